//! The registry of surfaces the tip can touch (SPEC §14, §15): their parameters as one
//! tagged enum ([`SurfaceParams`], the scenario's `wall`) and, resolved for a start, one
//! enum the plant, the stage pipeline and the lanes hold ([`Environment`]). A new surface is
//! its own file (implementing `contact::Surface`) plus one variant and its match arms here.
//! Nothing in the plant, the controller or the lanes names a concrete surface.

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::contact::{Contact, FreeSpace, Surface, TipMotion};
use crate::error::Result;
use crate::jet::{self, Smooth, V3};
use crate::robot::TaskVector;
use crate::scalar::{Real, Wide};
use crate::world::contact_law::ContactLawKey;
use crate::world::environment::{Wall, WallParams};
use crate::world::height_field::{HeightField, HeightFieldParams};
use crate::world::round::{CylinderParams, Round, RoundKey, SphereParams};

/// A surface's parameters, by kind (SPEC §15): tagged `plane`, `sphere`, `cylinder` and
/// `height_field`, as the Python blocks send them (a TOML table without a kind is a plane:
/// the Python side reads it so).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum SurfaceParams {
    Plane(WallParams),
    Sphere(SphereParams),
    Cylinder(CylinderParams),
    HeightField(HeightFieldParams),
}

/// The kinds a tagged surface may name.
pub const SURFACE_KINDS: [&str; 4] = ["plane", "sphere", "cylinder", "height_field"];

impl From<WallParams> for SurfaceParams {
    fn from(p: WallParams) -> Self {
        SurfaceParams::Plane(p)
    }
}

impl Default for SurfaceParams {
    fn default() -> Self {
        SurfaceParams::Plane(WallParams::default())
    }
}

impl SurfaceParams {
    pub fn validate(&self) -> Result<()> {
        match self {
            SurfaceParams::Plane(p) => p.validate(),
            SurfaceParams::Sphere(p) => p.validate(),
            SurfaceParams::Cylinder(p) => p.validate(),
            SurfaceParams::HeightField(p) => p.validate(),
        }
    }

    /// The plane's parameters, if this is one.
    pub fn plane(&self) -> Option<&WallParams> {
        match self {
            SurfaceParams::Plane(p) => Some(p),
            _ => None,
        }
    }

    /// The plane's parameters, if this is one (mutable: a guarded approach's sweeps move
    /// its gap).
    pub fn plane_mut(&mut self) -> Option<&mut WallParams> {
        match self {
            SurfaceParams::Plane(p) => Some(p),
            _ => None,
        }
    }

    /// The surface's kind tag.
    pub fn kind(&self) -> &'static str {
        match self {
            SurfaceParams::Plane(_) => "plane",
            SurfaceParams::Sphere(_) => "sphere",
            SurfaceParams::Cylinder(_) => "cylinder",
            SurfaceParams::HeightField(_) => "height_field",
        }
    }

    /// The controller's error along the normal [m].
    pub fn position_error(&self) -> f64 {
        match self {
            SurfaceParams::Plane(p) => p.position_error,
            SurfaceParams::Sphere(p) => p.position_error,
            SurfaceParams::Cylinder(p) => p.position_error,
            SurfaceParams::HeightField(p) => p.position_error,
        }
    }

    /// The surface as the controller believes it, for a tip starting at `start`: moved by
    /// its `position_error` along its normal at the point nearest the start (SPEC §15; `p`
    /// must be valid).
    pub fn believed(&self, start: &TaskVector) -> Result<Environment> {
        let normal = Environment::new(self, start)?.normal();
        Environment::new(self, &(start + normal * self.position_error()))
    }

    /// The gap before contact [m] (SPEC §16).
    pub fn gap(&self) -> f64 {
        match self {
            SurfaceParams::Plane(p) => p.gap,
            SurfaceParams::Sphere(p) => p.gap,
            SurfaceParams::Cylinder(p) => p.gap,
            SurfaceParams::HeightField(p) => p.gap,
        }
    }
}

/// The environment of one run (`f64`) or of four runs of one kind in lanes.
#[derive(Debug, Clone, PartialEq)]
pub enum Environment<T: Real = f64> {
    /// Free space: no contact.
    Free,
    /// A plane (SPEC §10): `world::environment`.
    Plane(Wall<T>),
    /// A sphere or a cylinder (SPEC §15): `world::round`.
    Round(Round<T>),
    /// A height field (SPEC §15): `world::height_field`.
    HeightField(HeightField<T>),
}

/// What runs must share for their environments to advance in one lane group: the kind and
/// the contact law's branch structure (every coefficient is a number a lane carries).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EnvironmentKey {
    Free,
    Plane(ContactLawKey),
    Round(RoundKey),
    HeightField(ContactLawKey),
}

impl<T: Real> Surface<T> for Environment<T> {
    #[inline(always)]
    fn contact(&self, tip: &impl TipMotion<T>) -> Contact<T> {
        match self {
            Environment::Free => FreeSpace.contact(tip),
            Environment::Plane(w) => w.contact(tip),
            Environment::Round(r) => r.contact(tip),
            Environment::HeightField(h) => h.contact(tip),
        }
    }
}

/// Work done against the environment's surface as its own type ([`Environment::visit`]).
pub trait SurfaceVisitor<T: Real> {
    type Output;
    fn visit<S: Surface<T>>(self, surface: &S) -> Self::Output;
}

impl<T: Real> Environment<T> {
    /// `visitor` run on this environment, matched once: a plane as [`Wall`] itself, so the
    /// visit (an RK4 period) is monomorphised with the plane's contact code alone; any
    /// other environment as the `Environment`, matched where it is used. A loop holding
    /// every surface's code behind a match at each stage cost fig. 19's lanes 16 % on an
    /// Intel core (docs/performance-history.md §19); a loop per surface would repeat the arms'
    /// inlined dynamics four times over for curved surfaces that cost more anyway.
    #[inline(always)]
    pub fn visit<V: SurfaceVisitor<T>>(&self, visitor: V) -> V::Output {
        match self {
            Environment::Plane(w) => visitor.visit(w),
            other => visitor.visit(other),
        }
    }

    /// The plane, if this is one.
    pub fn plane(&self) -> Option<&Wall<T>> {
        match self {
            Environment::Plane(w) => Some(w),
            _ => None,
        }
    }
}

impl Environment {
    /// The surface of `p` (valid) for a tip starting at `start`.
    pub fn new(p: &SurfaceParams, start: &TaskVector) -> Result<Self> {
        Ok(match p {
            SurfaceParams::Plane(w) => Environment::Plane(Wall::new(w, start)?),
            SurfaceParams::Sphere(s) => Environment::Round(Round::sphere(s, start)?),
            SurfaceParams::Cylinder(c) => Environment::Round(Round::cylinder(c, start)?),
            SurfaceParams::HeightField(h) => Environment::HeightField(HeightField::new(h, start)?),
        })
    }

    pub fn lane_key(&self) -> EnvironmentKey {
        match self {
            Environment::Free => EnvironmentKey::Free,
            Environment::Plane(w) => EnvironmentKey::Plane(w.law.key()),
            Environment::Round(r) => EnvironmentKey::Round(r.key()),
            Environment::HeightField(h) => EnvironmentKey::HeightField(h.key()),
        }
    }

    /// The plane the controller's task frame is built on (SPEC §10, §15): a plane itself;
    /// for a curved surface its tangent plane at the point nearest the start. Returns the
    /// unit normal and the plane's position along it (the surface's own, without
    /// `position_error`), and the position error; `None` in free space.
    pub fn tangent_plane(&self) -> Option<(TaskVector, f64, f64)> {
        let (point, normal, error) = match self {
            Environment::Free => return None,
            Environment::Plane(w) => return Some((w.normal, w.position, w.position_error)),
            Environment::Round(r) => {
                let (p, n) = r.nearest_to_start();
                (p, n, r.position_error)
            }
            Environment::HeightField(h) => {
                let (p, n) = h.nearest_to_start();
                (p, n, h.position_error)
            }
        };
        Some((normal, normal.dot(&point), error))
    }

    /// The contact normal the task frame controls force along, where the surface is
    /// planar (e_x in free space, the paper's default).
    pub fn normal(&self) -> TaskVector {
        self.tangent_plane().map_or_else(TaskVector::x, |p| p.0)
    }
}

impl Environment {
    /// (δ, N) at Y over values or jets: the penetration (positive inside) and the inward
    /// normal, as the contact computes them (free space: NaN and e_x).
    pub fn depth_normal<S: Smooth>(&self, y: &V3<S>) -> (S, V3<S>) {
        match self {
            Environment::Free => (S::constant(f64::NAN), jet::constant(&TaskVector::x())),
            Environment::Plane(w) => {
                let n = jet::constant(&w.normal);
                (jet::dot(&n, y) - S::constant(w.position), n)
            }
            Environment::Round(r) => r.depth_normal(y),
            Environment::HeightField(h) => h.depth_normal(y),
        }
    }

    /// The surface's point nearest Y and its inward normal there, over values or jets: for
    /// a plane, a sphere and a cylinder Y − δ N (δ their exact distance); for a height field
    /// the foot of the perpendicular, by iteration.
    pub fn foot<S: Smooth>(&self, y: &V3<S>) -> (V3<S>, V3<S>) {
        match self {
            Environment::HeightField(h) => h.foot(y),
            _ => {
                let (depth, normal) = self.depth_normal(y);
                (jet::minus(y, &jet::scaled(&normal, depth)), normal)
            }
        }
    }

    /// Feeds `put` every number that fixes the surface's shape and place (its contact law
    /// and position error aside): two environments feeding the same bits give the same
    /// [`Environment::foot`], bit for bit, from the same Y.
    pub fn shape_numbers(&self, put: &mut impl FnMut(&[f64])) {
        match self {
            Environment::Free => put(&[0.0]),
            Environment::Plane(w) => {
                put(&[1.0, w.position]);
                put(w.normal.as_slice());
            }
            Environment::Round(r) => {
                put(&[2.0]);
                r.shape_numbers(put);
            }
            Environment::HeightField(h) => {
                put(&[3.0]);
                h.shape_numbers(put);
            }
        }
    }

    /// Whether the surface is a plane (or free space): the task frame's fixed directions
    /// are then exact everywhere.
    pub fn is_planar(&self) -> bool {
        matches!(self, Environment::Free | Environment::Plane(_))
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
        // One key: every lane is of the first lane's kind.
        Some(match e[0] {
            Environment::Free => Environment::Free,
            Environment::Plane(_) => Environment::Plane(Wall::pack(e.map(|x| match x {
                Environment::Plane(w) => w,
                _ => unreachable!("one key: every lane is a plane"),
            }))),
            Environment::Round(_) => Environment::Round(Round::pack(e.map(|x| match x {
                Environment::Round(r) => r,
                _ => unreachable!("one key: every lane is a round surface"),
            }))),
            Environment::HeightField(_) => {
                Environment::HeightField(HeightField::pack(e.map(|x| match x {
                    Environment::HeightField(h) => h,
                    _ => unreachable!("one key: every lane is a height field"),
                })))
            }
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
