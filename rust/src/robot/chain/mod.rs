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
pub use urdf::MAX_JOINTS;

/// Code generic in a chain's joint count: [`with_joints`] calls `visit::<N>()` once, with N
/// the count it was given.
pub trait JointCount {
    type Output;
    fn visit<const N: usize>(self) -> Self::Output;
}

/// `v.visit::<n>()` for a chain of `n` joints (1 to [`MAX_JOINTS`]; `None` otherwise): the
/// one place a joint count becomes a type, for simulations (`sim::dispatch::visit_arm`) and
/// the Python layer's arm terms alike.
pub fn with_joints<V: JointCount>(n: usize, v: V) -> Option<V::Output> {
    Some(match n {
        1 => v.visit::<1>(),
        2 => v.visit::<2>(),
        3 => v.visit::<3>(),
        4 => v.visit::<4>(),
        5 => v.visit::<5>(),
        6 => v.visit::<6>(),
        7 => v.visit::<7>(),
        8 => v.visit::<8>(),
        _ => return None,
    })
}

/// The error for a joint count no simulation is compiled for.
pub(crate) fn unsupported_joints(n: usize) -> crate::error::Error {
    crate::error::Error::parameter(
        "robot.tip_link",
        format!("a chain of {n} joints"),
        &format!("a chain of 1 to {MAX_JOINTS} joints"),
    )
}
