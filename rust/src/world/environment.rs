//! The environment stage: a unilateral wall of any orientation with Kelvin–Voigt or
//! Hunt–Crossley contact (SPEC §10; the paper's wall of SPEC §2 is the default).

use crate::contact::{Contact, Surface, TipMotion};
use crate::error::{check, Error, Result};
use crate::robot::TaskVector;
use crate::scalar::{Real, Wide};
use crate::world::contact_law::{surface_params, ContactLaw};
pub use crate::world::contact_law::{ContactModel, MAX_EXPONENT};
use nalgebra::Vector3;

surface_params! {
    /// Wall parameters: the plane {X : n·X = x_e}. The controller never sees them; it is
    /// told x̂_e = `position` + `position_error` along the normal.
    pub struct WallParams {
        /// Normal n pointing into the wall (any length; normalised). Force is controlled along n,
        /// motion along t̂ = normalise(e_z − (e_z·n) n).
        pub normal: [f64; 3] = [1.0, 0.0, 0.0],
        /// Wall position x_e along n [m]; ``None`` puts the plane through the tip at q0
        /// (touching, zero force).
        pub position: Option<f64> = None,
    }
}

impl WallParams {
    pub fn validate(&self) -> Result<()> {
        self.validate_contact()?;
        unit_normal(&self.normal)?;
        if let Some(x) = self.position {
            check::finite("position", x)?;
        }
        Ok(())
    }
}

/// `v / |v|`, computed without overflow; an error for a zero or non-finite vector.
pub fn unit_normal(v: &[f64; 3]) -> Result<TaskVector> {
    unit_vector("normal", v)
}

/// Field `field`'s `v / |v|` (see [`unit_normal`]).
pub fn unit_vector(field: &str, v: &[f64; 3]) -> Result<TaskVector> {
    let v = TaskVector::from(*v);
    let scale = v.amax();
    if !(v.iter().all(|x| x.is_finite()) && scale > 0.0) {
        return Err(Error::parameter(
            field,
            format!("{:?}", [v[0], v[1], v[2]]),
            "a finite, non-zero vector",
        ));
    }
    let scaled = v / scale;
    Ok(scaled / scaled.norm())
}

/// A wall with its normal and position resolved: over `f64`, or over lanes (four walls,
/// one contact-law key, `Wall::pack`) for runs advancing together.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Wall<T: Real = f64> {
    pub law: ContactLaw<T>,
    /// Unit normal n.
    pub normal: Vector3<T>,
    /// x_e along n.
    pub position: T,
    pub position_error: T,
}

impl<W: Real> Wall<W> {
    /// L walls of one contact-law key in lanes.
    pub fn pack<const L: usize>(walls: [&Wall; L]) -> Self
    where
        W: Wide<L>,
    {
        Self {
            law: ContactLaw::pack(walls.map(|w| &w.law)),
            normal: Vector3::from_fn(|j, _| W::from_lanes(|i| walls[i].normal[j])),
            position: W::from_lanes(|i| walls[i].position),
            position_error: W::from_lanes(|i| walls[i].position_error),
        }
    }
}

impl Wall {
    /// Resolves the wall for an arm whose tip starts at `start`. `p` must be valid.
    pub fn new(p: &WallParams, start: &TaskVector) -> Result<Self> {
        let normal = unit_normal(&p.normal)?;
        Ok(Self {
            law: p.law(),
            normal,
            // SPEC §15: the surface starts `gap` beyond X0 (or `position`) along n.
            position: p.position.unwrap_or_else(|| normal.dot(start)) + p.gap,
            position_error: p.position_error,
        })
    }

    /// x̂_e: where the controller believes the wall is, along n.
    #[inline]
    pub fn estimated_position(&self) -> f64 {
        self.position + self.position_error
    }
}

/// The plane {X : n·X = x_e} as a surface: the force along n from the tip's n·X and, for
/// a damped wall, n·Ẋ; friction from the tip's velocity in the plane.
impl<T: Real> Surface<T> for Wall<T> {
    #[inline(always)]
    fn contact(&self, tip: &impl TipMotion<T>) -> Contact<T> {
        let (along, rate) = tip.along(&self.normal, self.law.needs_rate());
        let normal_force = self.force_along(along, rate);
        Contact {
            normal: self.normal,
            normal_force,
            penetration: along - self.position,
            friction: self.law.has_friction().then(|| {
                self.law
                    .friction_force(normal_force, &self.normal, &tip.velocity())
            }),
        }
    }
}

impl<T: Real> Wall<T> {
    /// Penetration δ = n·X − x_e (positive inside the wall).
    #[inline(always)]
    pub fn penetration(&self, position: &Vector3<T>) -> T {
        self.normal.dot(position) - self.position
    }

    /// Contact force along n [N] at tip position X and velocity Ẋ: 0 while δ ≤ 0.
    #[inline(always)]
    pub fn force(&self, position: &Vector3<T>, velocity: &Vector3<T>) -> T {
        self.force_along(self.normal.dot(position), self.normal.dot(velocity))
    }

    /// Contact force along n [N] from the tip's displacement s = n·X and rate ṡ = n·Ẋ.
    #[inline(always)]
    pub fn force_along(&self, along: T, rate: T) -> T {
        self.law.normal_force(along - self.position, rate)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at_x(x: f64) -> TaskVector {
        TaskVector::new(x, 0.3, 0.9)
    }

    #[test]
    fn unilateral_spring_normal_to_x() {
        let w = Wall::new(&WallParams::default(), &at_x(0.5)).unwrap();
        let still = TaskVector::zeros();
        assert_eq!(w.force(&at_x(0.4), &still), 0.0);
        assert_eq!(w.force(&at_x(0.5), &still), 0.0);
        assert!((w.force(&at_x(0.5001), &still) - 3.0).abs() < 1e-9);
        let w = Wall::new(
            &WallParams {
                position: Some(0.7),
                position_error: 0.01,
                ..WallParams::default()
            },
            &at_x(0.5),
        )
        .unwrap();
        assert_eq!(w.position, 0.7);
        assert!((w.estimated_position() - 0.71).abs() < 1e-15);
    }

    #[test]
    fn tilted_plane_through_the_start() {
        let p = WallParams {
            normal: [2.0, 0.0, 2.0],
            ..WallParams::default()
        };
        let start = TaskVector::new(0.7, 0.0, 0.9);
        let w = Wall::new(&p, &start).unwrap();
        let s = std::f64::consts::FRAC_1_SQRT_2;
        assert!((w.normal - TaskVector::new(s, 0.0, s)).norm() < 1e-15);
        assert!((w.position - 1.6 * s).abs() < 1e-15);
        // 1 mm along n into the wall; a move within the plane changes nothing.
        let inside = start + w.normal * 1e-3;
        assert!((w.force(&inside, &TaskVector::zeros()) - 30.0).abs() < 1e-9);
        let along = inside + TaskVector::new(s, 0.0, -s) * 0.2;
        assert!((w.force(&along, &TaskVector::zeros()) - 30.0).abs() < 1e-9);
    }

    #[test]
    fn kelvin_voigt_and_hunt_crossley() {
        let start = at_x(0.0);
        let kv = Wall::new(
            &WallParams {
                stiffness: 1e4,
                damping: 50.0,
                ..WallParams::default()
            },
            &start,
        )
        .unwrap();
        let inside = at_x(2e-3);
        // k δ + c δ̇ = 20 + 50·0.1; moving out fast, the damper cannot pull: 0.
        assert!((kv.force(&inside, &TaskVector::new(0.1, 0.0, 0.0)) - 25.0).abs() < 1e-12);
        assert_eq!(kv.force(&inside, &TaskVector::new(-1.0, 0.0, 0.0)), 0.0);
        let hc = Wall::new(
            &WallParams {
                stiffness: 1e6,
                damping: 50.0,
                model: ContactModel::HuntCrossley,
                exponent: 1.5,
                ..WallParams::default()
            },
            &start,
        )
        .unwrap();
        let d: f64 = 2e-3;
        let expected = 1e6 * d.powf(1.5) + 50.0 * d.powf(1.5) * 0.1;
        assert!((hc.force(&inside, &TaskVector::new(0.1, 0.0, 0.0)) - expected).abs() < 1e-12);
    }

    #[test]
    fn invalid_walls_name_the_field() {
        let bad = |p: WallParams| p.validate().unwrap_err().to_string();
        assert!(bad(WallParams {
            stiffness: -1.0,
            ..WallParams::default()
        })
        .starts_with("stiffness = -1"));
        assert!(bad(WallParams {
            normal: [0.0; 3],
            ..WallParams::default()
        })
        .starts_with("normal = [0.0, 0.0, 0.0]"));
        assert!(bad(WallParams {
            exponent: 0.5,
            ..WallParams::default()
        })
        .starts_with("exponent = 0.5"));
        // A huge but finite normal is normalised without overflow.
        let n = unit_normal(&[1e300, 0.0, 1e300]).unwrap();
        assert!((n.norm() - 1.0).abs() < 1e-15);
    }
}
