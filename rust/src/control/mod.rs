//! The controller side of the loop: references, the outer force loop (admittance filters),
//! the task directions and the inner position control laws.

pub mod controller;
pub mod filter;
pub mod reference;
pub mod task;
