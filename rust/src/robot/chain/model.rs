//! A serial chain as plain data: one moving joint per body, from the base to the tip.
//!
//! [`ChainModel`] is what the URDF loader produces (names, limits, any joint count);
//! [`SerialChain`] is the same chain at a fixed joint count `N` over a scalar `T`, the form
//! the recursive algorithms (`kinematics`, `rnea`, `crba`, `aba`) run on without allocating.

use nalgebra::{Matrix3, Vector3};

use super::spatial::{Pose, Real, RigidInertia};
use crate::scalar::{put, put_vector, Wide};

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

    /// Whether `other` has this chain's structure (joint kinds), so both can share lanes.
    pub fn same_structure(&self, other: &Self) -> bool {
        self.bodies
            .iter()
            .zip(&other.bodies)
            .all(|(a, b)| a.kind == b.kind)
    }

    /// A point mass `m` [kg] added at the tip origin (a tool; negative takes one off):
    /// the last body's inertia gains m, m p and m [p]× [p]×ᵀ, p the tip in its frame.
    pub fn with_tip_mass(&self, m: f64) -> Self {
        let mut c = *self;
        if let Some(last) = c.bodies.last_mut() {
            let tool = RigidInertia::from_com(m, self.tip.pos, Matrix3::zeros());
            last.inertia.mass += tool.mass;
            last.inertia.h += tool.h;
            last.inertia.ibar += tool.ibar;
        }
        c
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

impl<W: Real, const N: usize> SerialChain<W, N> {
    /// Four chains of one structure (joint kinds) in four lanes; every number may differ.
    pub fn pack<const L: usize>(chains: [&SerialChain<f64, N>; L]) -> Self
    where
        W: Wide<L>,
    {
        debug_assert!(chains.iter().all(|c| c.same_structure(chains[0])));
        let v =
            |f: &dyn Fn(usize) -> Vector3<f64>| Vector3::from_fn(|r, _| W::from_lanes(|l| f(l)[r]));
        let m = |f: &dyn Fn(usize) -> Matrix3<f64>| {
            Matrix3::from_fn(|r, c| W::from_lanes(|l| f(l)[(r, c)]))
        };
        let pose = |f: &dyn Fn(usize) -> Pose<f64>| Pose {
            rot: m(&|l| f(l).rot),
            pos: v(&|l| f(l).pos),
        };
        Self {
            bodies: std::array::from_fn(|i| Body {
                kind: chains[0].bodies[i].kind,
                axis: v(&|l| chains[l].bodies[i].axis),
                tree: pose(&|l| chains[l].bodies[i].tree),
                inertia: RigidInertia {
                    mass: W::from_lanes(|l| chains[l].bodies[i].inertia.mass),
                    h: v(&|l| chains[l].bodies[i].inertia.h),
                    ibar: m(&|l| chains[l].bodies[i].inertia.ibar),
                },
            }),
            tip: pose(&|l| chains[l].tip),
            gravity: W::from_lanes(|l| chains[l].gravity),
        }
    }
}

impl<W: Real, const N: usize> SerialChain<W, N> {
    /// Lane `l` takes the chain `c` (of this structure).
    pub fn put_lane(&mut self, l: usize, c: &SerialChain<f64, N>) {
        debug_assert!(self
            .bodies
            .iter()
            .zip(&c.bodies)
            .all(|(a, b)| a.kind == b.kind));
        let pose = |p: &mut Pose<W>, v: &Pose<f64>| {
            put_vector(&mut p.rot, l, &v.rot);
            put_vector(&mut p.pos, l, &v.pos);
        };
        for (b, v) in self.bodies.iter_mut().zip(&c.bodies) {
            put_vector(&mut b.axis, l, &v.axis);
            pose(&mut b.tree, &v.tree);
            put(&mut b.inertia.mass, l, v.inertia.mass);
            put_vector(&mut b.inertia.h, l, &v.inertia.h);
            put_vector(&mut b.inertia.ibar, l, &v.inertia.ibar);
        }
        pose(&mut self.tip, &c.tip);
        put(&mut self.gravity, l, c.gravity);
    }
}
