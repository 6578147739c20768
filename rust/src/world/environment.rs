//! The environment stage: a unilateral wall of any orientation with Kelvin–Voigt or
//! Hunt–Crossley contact (SPEC §10; the paper's wall of SPEC §2 is the default).

use crate::contact::{Contact, Surface, TipMotion};
use crate::error::{check, Error, Result};
use crate::robot::TaskVector;
use crate::scalar::{Real, Wide};
use nalgebra::Vector3;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// How the contact force grows with penetration δ and its rate δ̇.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum ContactModel {
    /// f = max(0, k δ + c δ̇): a spring and a damper in parallel.
    KelvinVoigt,
    /// f = max(0, k δ^p + c δ^p δ̇): damping that vanishes with the penetration, so the
    /// force is continuous at first contact.
    HuntCrossley,
}

/// Wall parameters. The controller never sees them; it is told
/// x̂_e = `position` + `position_error` along the normal.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct WallParams {
    /// Environment stiffness k_e [N/m] (Hunt–Crossley: [N/m^p]); unknown to the controller.
    #[schemars(extend("x-ui" = {"min": 1000.0, "max": 10000000.0, "scale": "log"}))]
    pub stiffness: f64,
    /// Contact damping c [N·s/m].
    #[schemars(extend("x-ui" = {"min": 0.0, "max": 500.0, "scale": "linear"}))]
    pub damping: f64,
    /// Contact law: ``"kelvin_voigt"`` (spring and damper) or ``"hunt_crossley"``.
    pub model: ContactModel,
    /// Hunt–Crossley exponent p, from 1 to 10 (ignored by Kelvin–Voigt).
    pub exponent: f64,
    /// Normal n pointing into the wall (any length; normalised). Force is controlled along n,
    /// motion along t̂ = normalise(e_z − (e_z·n) n).
    pub normal: [f64; 3],
    /// Wall position x_e along n [m]; ``None`` puts the plane through the tip at q0
    /// (touching, zero force).
    pub position: Option<f64>,
    /// Error of the controller's estimate x̂_e = x_e + position_error [m], along n.
    #[schemars(extend("x-ui" = {"min": -0.02, "max": 0.02, "scale": "linear"}))]
    pub position_error: f64,
    /// Free space before contact [m]: the true surface starts ``gap`` beyond ``position``
    /// (or the tip at q0) along n. 0: touching at zero force.
    #[schemars(extend("x-ui" = {"min": 0.0, "max": 0.05, "scale": "linear"}))]
    pub gap: f64,
}

impl Default for WallParams {
    fn default() -> Self {
        Self {
            stiffness: 30_000.0,
            damping: 0.0,
            model: ContactModel::KelvinVoigt,
            exponent: 1.0,
            normal: [1.0, 0.0, 0.0],
            position: None,
            position_error: 0.0,
            gap: 0.0,
        }
    }
}

/// Largest Hunt–Crossley exponent accepted.
pub const MAX_EXPONENT: f64 = 10.0;

impl WallParams {
    pub fn validate(&self) -> Result<()> {
        check::non_negative("stiffness", self.stiffness)?;
        check::non_negative("damping", self.damping)?;
        if !(self.exponent.is_finite() && (1.0..=MAX_EXPONENT).contains(&self.exponent)) {
            return Err(Error::parameter(
                "exponent",
                self.exponent,
                &format!("from 1 to {MAX_EXPONENT}"),
            ));
        }
        unit_normal(&self.normal)?;
        if let Some(x) = self.position {
            check::finite("position", x)?;
        }
        check::finite("position_error", self.position_error)?;
        check::non_negative("gap", self.gap)
    }
}

/// `v / |v|`, computed without overflow; an error for a zero or non-finite vector.
pub fn unit_normal(v: &[f64; 3]) -> Result<TaskVector> {
    let v = TaskVector::from(*v);
    let scale = v.amax();
    if !(v.iter().all(|x| x.is_finite()) && scale > 0.0) {
        return Err(Error::parameter(
            "normal",
            format!("{:?}", [v[0], v[1], v[2]]),
            "a finite, non-zero vector",
        ));
    }
    let scaled = v / scale;
    Ok(scaled / scaled.norm())
}

/// A wall with its normal and position resolved: over `f64`, or over lanes (four walls,
/// one model, `Wall::pack`) for runs advancing together.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Wall<T: Real = f64> {
    pub stiffness: T,
    pub damping: T,
    pub model: ContactModel,
    pub exponent: T,
    /// Unit normal n.
    pub normal: Vector3<T>,
    /// x_e along n.
    pub position: T,
    pub position_error: T,
}

impl<W: Real> Wall<W> {
    /// Four walls of one contact model in four lanes.
    pub fn pack<const L: usize>(walls: [&Wall; L]) -> Self
    where
        W: Wide<L>,
    {
        debug_assert!(walls.iter().all(|w| w.model == walls[0].model));
        let p = |f: fn(&Wall) -> f64| W::from_lanes(|i| f(walls[i]));
        Self {
            stiffness: p(|w| w.stiffness),
            damping: p(|w| w.damping),
            model: walls[0].model,
            exponent: p(|w| w.exponent),
            normal: Vector3::from_fn(|j, _| W::from_lanes(|i| walls[i].normal[j])),
            position: p(|w| w.position),
            position_error: p(|w| w.position_error),
        }
    }
}

impl Wall {
    /// Resolves the wall for an arm whose tip starts at `start`. `p` must be valid.
    pub fn new(p: &WallParams, start: &TaskVector) -> Result<Self> {
        let normal = unit_normal(&p.normal)?;
        Ok(Self {
            stiffness: p.stiffness,
            damping: p.damping,
            model: p.model,
            exponent: p.exponent,
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
/// a damped wall, n·Ẋ.
impl<T: Real> Surface<T> for Wall<T> {
    #[inline(always)]
    fn contact(&self, tip: &impl TipMotion<T>) -> Contact<T> {
        let (along, rate) = tip.along(&self.normal, self.needs_rate());
        Contact {
            normal: self.normal,
            normal_force: self.force_along(along, rate),
            penetration: along - self.position,
        }
    }
}

impl<T: Real> Wall<T> {
    /// Whether the force reads the tip's rate along n: only with damping (in lanes: in any
    /// lane).
    #[inline(always)]
    pub fn needs_rate(&self) -> bool {
        !T::all(self.damping.simd_eq(T::zero()))
    }

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
    /// Lanes out of contact (or undamped) take their branch by select.
    #[inline(always)]
    pub fn force_along(&self, along: T, rate: T) -> T {
        let zero = T::zero();
        let delta = along - self.position;
        let apart = delta.simd_le(zero);
        if T::all(apart) {
            return zero;
        }
        let spring = match self.model {
            ContactModel::KelvinVoigt => delta,
            ContactModel::HuntCrossley => delta.simd_powf(self.exponent),
        };
        let undamped = self.damping.simd_eq(zero);
        // The paper's wall: no velocity term at all (and no 0·δ̇ to round).
        let elastic = self.stiffness * spring;
        let f = if T::all(undamped) {
            elastic
        } else {
            let f = match self.model {
                ContactModel::KelvinVoigt => self.stiffness * delta + self.damping * rate,
                ContactModel::HuntCrossley => spring * (self.stiffness + self.damping * rate),
            };
            // A wall pushes, never pulls.
            elastic.select(undamped, f.simd_max(zero))
        };
        if T::none(apart) {
            f
        } else {
            zero.select(apart, f)
        }
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
