//! The registry of surfaces the tip can touch (SPEC §14): one enum the plant, the stage
//! pipeline and the lanes hold, so a new surface is its own file (implementing
//! `contact::Surface`) plus one variant and its match arms here. Nothing in the plant, the
//! controller or the lanes names a concrete surface.

use crate::contact::{Contact, FreeSpace, Surface, TipMotion};
use crate::robot::TaskVector;
use crate::scalar::{Real, Wide};
use crate::world::environment::{ContactModel, Wall};

/// The environment of one run (`f64`) or of four runs of one kind in lanes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Environment<T: Real = f64> {
    /// Free space: no contact.
    Free,
    /// A plane (SPEC §10): `world::environment`.
    Plane(Wall<T>),
}

/// What runs must share for their environments to advance in one lane group: the kind and
/// the contact law's branch structure (every coefficient is a number a lane carries).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EnvironmentKey {
    Free,
    Plane(ContactModel),
}

impl<T: Real> Surface<T> for Environment<T> {
    #[inline(always)]
    fn contact(&self, tip: &impl TipMotion<T>) -> Contact<T> {
        match self {
            Environment::Free => FreeSpace.contact(tip),
            Environment::Plane(w) => w.contact(tip),
        }
    }
}

impl<T: Real> Environment<T> {
    pub fn lane_key(&self) -> EnvironmentKey {
        match self {
            Environment::Free => EnvironmentKey::Free,
            Environment::Plane(w) => EnvironmentKey::Plane(w.model),
        }
    }

    /// The plane, if this is one (the task frame and the metrics read its normal and
    /// position).
    pub fn plane(&self) -> Option<&Wall<T>> {
        match self {
            Environment::Plane(w) => Some(w),
            Environment::Free => None,
        }
    }
}

impl Environment {
    /// The contact normal the task frame controls force along, where the surface is
    /// planar (e_x in free space, the paper's default).
    pub fn normal(&self) -> TaskVector {
        self.plane().map_or_else(TaskVector::x, |w| w.normal)
    }
}

impl<W: Real> Environment<W> {
    /// Four environments of one [`EnvironmentKey`] in lanes; `None` if their keys differ.
    pub fn pack<const L: usize>(e: [&Environment; L]) -> Option<Self>
    where
        W: Wide<L>,
    {
        if !e.iter().all(|x| x.lane_key() == e[0].lane_key()) {
            return None;
        }
        Some(match e[0] {
            Environment::Free => Environment::Free,
            Environment::Plane(_) => Environment::Plane(Wall::pack(e.map(|x| match x {
                Environment::Plane(w) => w,
                Environment::Free => unreachable!("one key: every lane is a plane"),
            }))),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::contact::KnownTip;
    use crate::scalar::F64x4;
    use crate::world::environment::WallParams;
    use nalgebra::{SMatrix, SVector, Vector3};

    /// The registry gives each surface's own contact, packs only one key into lanes, and
    /// four packed planes give four scalar planes' contacts.
    #[test]
    fn registry_dispatches_and_packs_by_key() {
        let start = Vector3::new(0.5, 0.0, 0.8);
        let plane = |k: f64| {
            Environment::Plane(
                Wall::new(
                    &WallParams {
                        stiffness: k,
                        damping: 10.0,
                        ..WallParams::default()
                    },
                    &start,
                )
                .unwrap(),
            )
        };
        let (j, qd) = (
            SMatrix::<f64, 3, 1>::new(1.0, 0.0, 0.0),
            SVector::<f64, 1>::new(0.2),
        );
        let at = Vector3::new(0.501, 0.0, 0.8);
        let tip = KnownTip {
            position: &at,
            jacobian: &j,
            qd: &qd,
        };
        let c = plane(1e4).contact(&tip);
        assert!((c.normal_force - (1e4 * 0.001 + 10.0 * 0.2)).abs() < 1e-9);
        assert!((c.penetration - 0.001).abs() < 1e-12);
        let free = Environment::<f64>::Free.contact(&tip);
        assert_eq!(free.normal_force, 0.0);
        assert!(free.penetration.is_nan());
        assert!(Environment::<F64x4>::pack([
            &plane(1.0),
            &plane(2.0),
            &Environment::Free,
            &plane(3.0)
        ])
        .is_none());
        let four = [plane(1e4), plane(2e4), plane(3e4), plane(4e4)];
        let packed = Environment::pack(four.each_ref()).unwrap();
        let lanes = |x: f64| F64x4::from_lanes(|_| x);
        let (at4, j4, qd4) = (at.map(lanes), j.map(lanes), qd.map(lanes));
        let c4 = packed.contact(&KnownTip {
            position: &at4,
            jacobian: &j4,
            qd: &qd4,
        });
        for (l, e) in four.iter().enumerate() {
            assert_eq!(
                crate::scalar::lane(c4.normal_force, l),
                e.contact(&tip).normal_force
            );
        }
    }
}
