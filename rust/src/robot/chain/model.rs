//! A serial chain as plain data: one moving joint per body, from the base to the tip.
//!
//! [`ChainModel`] is what the URDF loader produces (names, limits, any joint count);
//! [`SerialChain`] is the same chain at a fixed joint count `N` over a scalar `T`, the form
//! the recursive algorithms (`kinematics`, `rnea`, `crba`, `aba`) run on without allocating.

use nalgebra::Vector3;

use super::spatial::{Pose, Real, RigidInertia};

/// The joint kinds the algorithms support (fixed joints are merged away by the loader).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum JointKind {
    /// Rotation about the axis (URDF `revolute` and `continuous`).
    Revolute,
    /// Translation along the axis.
    Prismatic,
}

/// One moving joint and the rigid body it carries.
#[derive(Debug, Clone, PartialEq)]
pub struct JointSpec {
    /// The URDF joint's name.
    pub name: String,
    pub kind: JointKind,
    /// Unit axis in the joint (= body) frame.
    pub axis: Vector3<f64>,
    /// The joint frame at q = 0 in the previous body's frame (the base's for the first).
    pub tree: Pose<f64>,
    /// The body's inertia (its link and every link fixed to it) about the joint frame.
    pub inertia: RigidInertia<f64>,
    /// Position limits [rad or m]; ±∞ for a continuous joint or when not given.
    pub lower: f64,
    pub upper: f64,
    /// Effort limit [N·m or N]; ∞ when not given (or given as 0).
    pub effort: f64,
}

/// A serial chain from a base link to a tip link.
#[derive(Debug, Clone, PartialEq)]
pub struct ChainModel {
    pub base_link: String,
    pub tip_link: String,
    pub joints: Vec<JointSpec>,
    /// The tip link's frame in the last body's frame.
    pub tip: Pose<f64>,
}

impl ChainModel {
    pub fn dof(&self) -> usize {
        self.joints.len()
    }
}

/// One body of a [`SerialChain`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Body<T: Real> {
    pub kind: JointKind,
    pub axis: Vector3<T>,
    pub tree: Pose<T>,
    pub inertia: RigidInertia<T>,
}

/// A chain of `N` bodies over the scalar `T`; gravity acts along −z of the base frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SerialChain<T: Real, const N: usize> {
    pub bodies: [Body<T>; N],
    /// The tip frame in body N's frame.
    pub tip: Pose<T>,
    /// Gravity along −z [m/s²].
    pub gravity: T,
}

impl<const N: usize> SerialChain<f64, N> {
    /// The chain of `model`, which must have `N` joints.
    pub fn from_model(model: &ChainModel, gravity: f64) -> Self {
        assert_eq!(model.dof(), N, "joint count");
        Self {
            bodies: std::array::from_fn(|i| {
                let j = &model.joints[i];
                Body {
                    kind: j.kind,
                    axis: j.axis,
                    tree: j.tree,
                    inertia: j.inertia,
                }
            }),
            tip: model.tip,
            gravity,
        }
    }

    /// Every inertia scaled by `s` (a controller's mass model error).
    pub fn with_mass_scale(&self, s: f64) -> Self {
        let mut c = *self;
        c.bodies
            .iter_mut()
            .for_each(|b| b.inertia = b.inertia.scaled(s));
        c
    }
}
