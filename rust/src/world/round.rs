//! Round surfaces (SPEC §15): a sphere (distance to a centre point) and a cylinder
//! (distance to an axis line), touched from outside or from inside (a bowl, a bore).
//!
//! Both place their centre on the line from the tip's start X0 along the approach normal
//! n (for a cylinder: n's part across the axis), at X0 + (gap + R) n outside and
//! X0 − (R − gap) n inside, so the tip starts `gap` away. The penetration is written
//! relative to X0, δ = ∓(|d|² − R²)/(|d| + R) with |d|² − R² expanded around X0, so that a
//! large radius costs no accuracy: a sphere of R = 1e6 m reads the penetration of its
//! tangent plane to ~1e-16 m instead of R's rounding (1e-10 m).

use nalgebra::Vector3;

use crate::contact::{Contact, Surface, TipMotion};
use crate::error::{check, Error, Result};
use crate::jet::{self, Smooth, V3};
use crate::robot::TaskVector;
use crate::scalar::{Real, Wide};
use crate::world::contact_law::{surface_params, ContactLaw, ContactLawKey};
use crate::world::environment::{unit_normal, unit_vector};

/// Largest radius accepted [m]: beyond it a curved surface is a plane to the tip.
pub const MAX_RADIUS: f64 = 1e9;

surface_params! {
    /// A sphere of radius R (SPEC §15), its nearest point `gap` from the tip's start along n.
    pub struct SphereParams {
        /// Radius R [m], from 0 (exclusive) to 1e9.
        #[schemars(extend("x-ui" = {"min": 0.01, "max": 10.0, "scale": "log"}))]
        pub radius: f64 = 0.1,
        /// Approach normal n pointing into the surface at the point the tip starts beside
        /// (any length; normalised). Force is controlled along n, motion along
        /// t̂ = normalise(e_z − (e_z·n) n).
        pub normal: [f64; 3] = [1.0, 0.0, 0.0],
        /// ``False``: the tip touches the outside (a ball); ``True``: the inside (a bowl).
        pub inside: bool = false,
    }
}

surface_params! {
    /// A circular cylinder of radius R about `axis` (SPEC §15), its nearest point `gap` from
    /// the tip's start along n.
    pub struct CylinderParams {
        /// Radius R [m], from 0 (exclusive) to 1e9.
        #[schemars(extend("x-ui" = {"min": 0.01, "max": 10.0, "scale": "log"}))]
        pub radius: f64 = 0.1,
        /// Direction of the cylinder's axis (any length; normalised); not parallel to n.
        pub axis: [f64; 3] = [0.0, 0.0, 1.0],
        /// Approach normal n pointing into the surface at the point the tip starts beside
        /// (any length; normalised; its part along the axis is ignored). Force is controlled
        /// along n, motion along t̂ = normalise(e_z − (e_z·n) n).
        pub normal: [f64; 3] = [1.0, 0.0, 0.0],
        /// ``False``: the tip touches the outside (a shaft); ``True``: the inside (a bore).
        pub inside: bool = false,
    }
}

fn check_radius(radius: f64, gap: f64, inside: bool) -> Result<()> {
    check::positive_up_to("radius", radius, MAX_RADIUS, "m")?;
    if gap > MAX_RADIUS {
        return Err(Error::parameter(
            "gap",
            gap,
            &format!("from 0 to {MAX_RADIUS:e} m for a sphere or cylinder"),
        ));
    }
    if inside && gap >= radius {
        return Err(Error::parameter(
            "gap",
            gap,
            &format!("less than the radius ({radius}) inside a sphere or cylinder"),
        ));
    }
    Ok(())
}

impl SphereParams {
    pub fn validate(&self) -> Result<()> {
        self.validate_contact()?;
        unit_normal(&self.normal)?;
        check_radius(self.radius, self.gap, self.inside)
    }
}

impl CylinderParams {
    pub fn validate(&self) -> Result<()> {
        self.validate_contact()?;
        self.directions().map(|_| ())?;
        check_radius(self.radius, self.gap, self.inside)
    }

    /// (unit axis a, unit n⊥ = n's part across the axis, normalised).
    fn directions(&self) -> Result<(TaskVector, TaskVector)> {
        let axis = unit_vector("axis", &self.axis)?;
        let n = unit_normal(&self.normal)?;
        let across = n - axis * axis.dot(&n);
        if across.norm() < 1e-9 {
            return Err(Error::parameter(
                "axis",
                format!("{:?}", self.axis),
                "a direction not parallel to the normal",
            ));
        }
        Ok((axis, across / across.norm()))
    }
}

/// A sphere or a cylinder resolved for a start X0: over `f64`, or four in lanes of one
/// [`RoundKey`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Round<T: Real = f64> {
    pub law: ContactLaw<T>,
    /// X0, the tip's start.
    pub start: Vector3<T>,
    /// The unit direction from X0 to the centre's line, n (n⊥ for a cylinder).
    pub normal: Vector3<T>,
    /// The cylinder's unit axis; `None` for a sphere.
    pub axis: Option<Vector3<T>>,
    pub radius: T,
    /// s_c: the centre (line) is at X0 + s_c n.
    centre_offset: T,
    /// s_c² − R², written as gap·(gap ± 2R) so that it is exact for a large R.
    offset_sq_minus_radius_sq: T,
    pub inside: bool,
    pub gap: T,
    pub position_error: T,
}

/// What round surfaces in one lane group share.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RoundKey {
    pub law: ContactLawKey,
    pub cylinder: bool,
    pub inside: bool,
}

impl Round {
    /// The sphere of `p` for a tip starting at `start` (`p` must be valid).
    pub fn sphere(p: &SphereParams, start: &TaskVector) -> Result<Self> {
        Ok(Self::new(
            p.law(),
            *start,
            unit_normal(&p.normal)?,
            None,
            p.radius,
            p.inside,
            p.gap,
            p.position_error,
        ))
    }

    /// The cylinder of `p` for a tip starting at `start` (`p` must be valid).
    pub fn cylinder(p: &CylinderParams, start: &TaskVector) -> Result<Self> {
        let (axis, across) = p.directions()?;
        Ok(Self::new(
            p.law(),
            *start,
            across,
            Some(axis),
            p.radius,
            p.inside,
            p.gap,
            p.position_error,
        ))
    }

    #[allow(clippy::too_many_arguments)]
    fn new(
        law: ContactLaw,
        start: TaskVector,
        normal: TaskVector,
        axis: Option<TaskVector>,
        radius: f64,
        inside: bool,
        gap: f64,
        position_error: f64,
    ) -> Self {
        let (centre_offset, k0) = if inside {
            (-(radius - gap), gap * (gap - 2.0 * radius))
        } else {
            (gap + radius, gap * (gap + 2.0 * radius))
        };
        Self {
            law,
            start,
            normal,
            axis,
            radius,
            centre_offset,
            offset_sq_minus_radius_sq: k0,
            inside,
            gap,
            position_error,
        }
    }

    pub fn key(&self) -> RoundKey {
        RoundKey {
            law: self.law.key(),
            cylinder: self.axis.is_some(),
            inside: self.inside,
        }
    }

    /// The surface's point nearest X0 and its inward normal there: X0 + gap n, n.
    pub fn nearest_to_start(&self) -> (TaskVector, TaskVector) {
        (self.start + self.normal * self.gap, self.normal)
    }
}

impl<W: Real> Round<W> {
    /// L round surfaces of one key in lanes.
    pub fn pack<const L: usize>(r: [&Round; L]) -> Self
    where
        W: Wide<L>,
    {
        debug_assert!(r.iter().all(|x| x.key() == r[0].key()));
        let p = |f: fn(&Round) -> f64| W::from_lanes(|i| f(r[i]));
        let v =
            |f: fn(&Round) -> TaskVector| Vector3::from_fn(|j, _| W::from_lanes(|i| f(r[i])[j]));
        Self {
            law: ContactLaw::pack(r.map(|x| &x.law)),
            start: v(|x| x.start),
            normal: v(|x| x.normal),
            axis: r[0]
                .axis
                .map(|_| v(|x| x.axis.unwrap_or_else(TaskVector::zeros))),
            radius: p(|x| x.radius),
            centre_offset: p(|x| x.centre_offset),
            offset_sq_minus_radius_sq: p(|x| x.offset_sq_minus_radius_sq),
            inside: r[0].inside,
            gap: p(|x| x.gap),
            position_error: p(|x| x.position_error),
        }
    }
}

impl<T: Real> Round<T> {
    /// (δ, N) at tip position X: d = X − c (across the axis for a cylinder),
    /// δ = R − |d| outside, |d| − R inside, N = ∓d/|d| (toward the centre outside).
    #[inline(always)]
    pub fn penetration_normal(&self, position: &Vector3<T>) -> (T, Vector3<T>) {
        let mut e = position - self.start;
        if let Some(a) = &self.axis {
            e -= a * a.dot(&e);
        }
        let d = e - self.normal * self.centre_offset;
        // |d|² − R² = |e|² − 2 s_c n·e + (s_c² − R²): no difference of two large numbers.
        let two = T::splat(2.0);
        let excess = e.norm_squared() - two * self.centre_offset * self.normal.dot(&e)
            + self.offset_sq_minus_radius_sq;
        let distance = d.norm();
        let outward = excess / (distance + self.radius);
        let zero = T::zero();
        // At the centre itself the direction is undefined: take n.
        let at_centre = distance.simd_eq(zero);
        let unit = d / distance;
        let unit = if T::none(at_centre) {
            unit
        } else {
            unit.zip_map(&self.normal, |u, n| n.select(at_centre, u))
        };
        if self.inside {
            (outward, unit)
        } else {
            (-outward, -unit)
        }
    }
}

impl Round {
    /// Every number fixing the shape and place (`Environment::shape_numbers`).
    pub fn shape_numbers(&self, put: &mut impl FnMut(&[f64])) {
        let axis = self.axis.unwrap_or_else(|| TaskVector::from([f64::NAN; 3]));
        put(self.start.as_slice());
        put(self.normal.as_slice());
        put(axis.as_slice());
        put(&[
            self.radius,
            self.centre_offset,
            self.offset_sq_minus_radius_sq,
            f64::from(u8::from(self.inside)),
            self.gap,
        ]);
    }

    /// [`Round::penetration_normal`] over values or jets (the controller's belief, SPEC
    /// §15): (δ, N) at Y, the same closed form written on `jet::V3`.
    pub fn depth_normal<S: Smooth>(&self, y: &V3<S>) -> (S, V3<S>) {
        let c = S::constant;
        let mut e = jet::minus(y, &jet::constant(&self.start));
        if let Some(a) = &self.axis {
            let a = jet::constant(a);
            e = jet::minus(&e, &jet::scaled(&a, jet::dot(&a, &e)));
        }
        let n = jet::constant(&self.normal);
        let d = jet::minus(&e, &jet::scaled(&n, c(self.centre_offset)));
        let excess = jet::dot(&e, &e) - c(2.0 * self.centre_offset) * jet::dot(&n, &e)
            + c(self.offset_sq_minus_radius_sq);
        let distance = jet::dot(&d, &d).sqrt();
        let outward = excess / (distance + c(self.radius));
        let unit = if distance.value() == 0.0 {
            n
        } else {
            jet::scaled(&d, c(1.0) / distance)
        };
        if self.inside {
            (outward, unit)
        } else {
            (-outward, jet::scaled(&unit, c(-1.0)))
        }
    }
}

impl<T: Real> Surface<T> for Round<T> {
    #[inline(always)]
    fn contact(&self, tip: &impl TipMotion<T>) -> Contact<T> {
        let (penetration, normal) = self.penetration_normal(&tip.position());
        self.law.contact_at(penetration, normal, tip)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::world::environment::{Wall, WallParams};

    /// A small deterministic generator for random points (no test dependency needed).
    fn points(n: usize) -> impl Iterator<Item = TaskVector> {
        let mut s: u64 = 0x9e37_79b9_7f4a_7c15;
        let mut next = move || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
        };
        (0..n).map(move |_| TaskVector::new(next(), next(), next()) * 0.3)
    }

    fn start() -> TaskVector {
        TaskVector::new(0.7, 0.1, 0.9)
    }

    /// Penetration and normal against the closed forms, outside and inside, at random
    /// points: δ = R − |X − c| (outside), |X − c| − R (inside), N along the line to c.
    #[test]
    fn sphere_matches_the_closed_form() {
        for inside in [false, true] {
            let p = SphereParams {
                radius: 0.25,
                normal: [1.0, 0.0, -1.0],
                inside,
                gap: 0.01,
                ..SphereParams::default()
            };
            p.validate().unwrap();
            let s = Round::sphere(&p, &start()).unwrap();
            let n = TaskVector::new(1.0, 0.0, -1.0).normalize();
            let c = if inside {
                start() - n * (0.25 - 0.01)
            } else {
                start() + n * (0.01 + 0.25)
            };
            for x in points(200) {
                let x = start() + x;
                let (delta, normal) = s.penetration_normal(&x);
                let r = (x - c).norm();
                let (d, nn) = if inside {
                    (r - 0.25, (x - c) / r)
                } else {
                    (0.25 - r, (c - x) / r)
                };
                assert!((delta - d).abs() < 1e-15, "{inside} {delta} {d}");
                assert!((normal - nn).norm() < 1e-14);
            }
            for x in points(20) {
                let x = start() + x;
                let (d, n) = s.penetration_normal(&x);
                let (dj, nj) = s.depth_normal(&[x[0], x[1], x[2]]);
                assert!((d - dj).abs() < 1e-15 && (n - TaskVector::from(nj)).norm() < 1e-15);
            }
            // The tip starts `gap` away, and feels nothing there.
            assert!((s.penetration_normal(&start()).0 + 0.01).abs() < 1e-16);
        }
    }

    #[test]
    fn cylinder_matches_the_closed_form() {
        for inside in [false, true] {
            let p = CylinderParams {
                radius: 0.2,
                axis: [0.0, 1.0, 1.0],
                normal: [1.0, 0.0, 0.3],
                inside,
                ..CylinderParams::default()
            };
            p.validate().unwrap();
            let s = Round::cylinder(&p, &start()).unwrap();
            let a = TaskVector::new(0.0, 1.0, 1.0).normalize();
            let n = TaskVector::new(1.0, 0.0, 0.3);
            let n = (n - a * a.dot(&n)).normalize();
            let c = start() + n * if inside { -0.2 } else { 0.2 };
            for x in points(200) {
                let x = start() + x;
                let d = (x - c) - a * a.dot(&(x - c));
                let r = d.norm();
                let (delta, normal) = s.penetration_normal(&x);
                let (dd, nn) = if inside {
                    (r - 0.2, d / r)
                } else {
                    (0.2 - r, -d / r)
                };
                assert!((delta - dd).abs() < 1e-15);
                assert!((normal - nn).norm() < 1e-14);
                // Moving along the axis changes nothing.
                let moved = s.penetration_normal(&(x + a * 0.37)).0;
                assert!((moved - delta).abs() < 1e-15);
            }
        }
    }

    /// A sphere of radius 1e6 m is its tangent plane to the tip: the same penetration to
    /// 1e-15 m over ±0.3 mm… ±3 cm of sliding (the curvature's |e|²/2R ≤ 5e-10 m aside).
    #[test]
    fn a_huge_sphere_is_the_plane() {
        let s = Round::sphere(
            &SphereParams {
                radius: 1e6,
                ..SphereParams::default()
            },
            &start(),
        )
        .unwrap();
        let w = Wall::new(&WallParams::default(), &start()).unwrap();
        for x in points(100) {
            let x = start() + x * 0.1;
            let e = x - start();
            let tangential = e.norm_squared() - e[0] * e[0];
            let (delta, _) = s.penetration_normal(&x);
            let plane = w.penetration(&x) - tangential / 2e6;
            assert!((delta - plane).abs() < 1e-15, "{delta} {plane}");
        }
    }

    #[test]
    fn bad_round_surfaces_name_the_field() {
        let bad = |e: Result<()>| e.unwrap_err().to_string();
        assert!(bad(SphereParams {
            radius: 0.0,
            ..SphereParams::default()
        }
        .validate())
        .starts_with("radius = 0"));
        assert!(bad(SphereParams {
            radius: 0.1,
            gap: 0.2,
            inside: true,
            ..SphereParams::default()
        }
        .validate())
        .starts_with("gap = 0.2"));
        assert!(bad(CylinderParams {
            axis: [2.0, 0.0, 0.0],
            ..CylinderParams::default()
        }
        .validate())
        .starts_with("axis = [2.0, 0.0, 0.0]"));
        assert!(bad(CylinderParams {
            axis: [0.0, 0.0, f64::NAN],
            ..CylinderParams::default()
        }
        .validate())
        .starts_with("axis = "));
    }
}
