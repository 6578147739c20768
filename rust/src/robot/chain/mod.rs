//! General serial arms (SPEC §11): a chain loaded from a URDF, with dynamics by the
//! recursive algorithms of Featherstone's *Rigid Body Dynamics Algorithms*.
//!
//! - `spatial`: motion/force vectors, Plücker transforms, rigid-body inertia;
//! - `model`: the chain as data ([`ChainModel`], [`SerialChain`]);
//! - `urdf`: URDF → [`ChainModel`];
//! - `kinematics`: frames, tip Jacobian, J̇q̇; `rnea`: inverse dynamics, C q̇ + G;
//!   `crba`: D(q); `aba`: forward dynamics with a tip wrench;
//! - `arm`: [`UrdfArm`], the chain as a [`crate::robot::RobotModel`].

pub mod aba;
pub mod arm;
pub mod crba;
pub mod kinematics;
pub mod model;
pub mod rnea;
pub mod spatial;
pub mod urdf;

pub use arm::{Chain, TaskKind, UrdfArm, UrdfArmParams};
pub use kinematics::Frames;
pub use model::{ChainModel, JointKind, JointSpec, SerialChain};
