//! The controller side of the loop: references, the guarded approach, the outer force loop
//! (admittance filters),
//! the task directions and the inner position loop: its parameters (`params`), its laws as
//! pure functions (`laws`) and its state machine (`controller`).

pub mod approach;
pub mod belief;
pub mod controller;
pub mod filter;
pub mod laws;
pub mod params;
pub mod reference;
pub mod task;
pub mod wrench_admittance;
