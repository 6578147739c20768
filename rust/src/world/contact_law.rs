//! The contact law every surface shares (SPEC §10, §15): the normal force from the
//! penetration δ and its rate δ̇ (Kelvin–Voigt or Hunt–Crossley), and regularised Coulomb
//! friction along the surface. A surface computes δ, δ̇ and its inward normal N from the
//! tip's motion; this law turns them into the force on the tip, −f N + F_t.

use nalgebra::Vector3;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::contact::{Contact, TipMotion};
use crate::error::{check, Error, Result};
use crate::scalar::{Real, Wide};

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

/// Largest Hunt–Crossley exponent accepted.
pub const MAX_EXPONENT: f64 = 10.0;

/// The range of `stiction_velocity` [m/s]: below 1e-12 m/s its square underflows the
/// regularisation (0/0 at rest); above 1e6 m/s no tip slides fast enough to feel friction.
pub const STICTION_VELOCITY: (f64, f64) = (1e-12, 1e6);

/// A surface's parameter struct: the contact-law fields every surface has (SPEC §15), then
/// the surface's own. One declaration of the shared fields, their docs, defaults, slider
/// hints and checks, stamped into `WallParams`, `SphereParams`, `CylinderParams` and
/// `HeightFieldParams` (serde's `flatten` cannot be combined with refusing unknown keys).
macro_rules! surface_params {
    (
        $(#[$meta:meta])*
        pub struct $name:ident {
            $( $(#[$field_meta:meta])* pub $field:ident : $ty:ty = $default:expr, )*
        }
    ) => {
        $(#[$meta])*
        #[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize, schemars::JsonSchema)]
        #[serde(default, deny_unknown_fields)]
        pub struct $name {
            /// Environment stiffness k_e [N/m] (Hunt–Crossley: [N/m^p]); unknown to the controller.
            #[schemars(extend("x-ui" = {"min": 1000.0, "max": 10000000.0, "scale": "log"}))]
            pub stiffness: f64,
            /// Contact damping c [N·s/m].
            #[schemars(extend("x-ui" = {"min": 0.0, "max": 500.0, "scale": "linear"}))]
            pub damping: f64,
            /// Contact law: ``"kelvin_voigt"`` (spring and damper) or ``"hunt_crossley"``.
            pub model: $crate::world::contact_law::ContactModel,
            /// Hunt–Crossley exponent p, from 1 to 10 (ignored by Kelvin–Voigt).
            pub exponent: f64,
            /// Coulomb friction coefficient μ along the surface (0: frictionless), from 0 to 10.
            #[schemars(extend("x-ui" = {"min": 0.0, "max": 1.0, "scale": "linear", "unit": ""}))]
            pub friction: f64,
            /// Slip speed v_s [m/s] below which friction is regularised: F_t = −μ f v_t / √(|v_t|² + v_s²).
            pub stiction_velocity: f64,
            /// Error of the controller's estimate of the surface [m], along its normal: the
            /// controller believes the surface ``position_error`` further along n.
            #[schemars(extend("x-ui" = {"min": -0.02, "max": 0.02, "scale": "linear"}))]
            pub position_error: f64,
            /// Free space before contact [m]: the true surface starts ``gap`` further along n
            /// than where it would touch the tip at q0 (a Wall: than its ``position``). 0:
            /// touching at zero force.
            #[schemars(extend("x-ui" = {"min": 0.0, "max": 0.05, "scale": "linear"}))]
            pub gap: f64,
            $( $(#[$field_meta])* pub $field: $ty, )*
        }

        impl Default for $name {
            fn default() -> Self {
                Self {
                    stiffness: 30_000.0,
                    damping: 0.0,
                    model: $crate::world::contact_law::ContactModel::KelvinVoigt,
                    exponent: 1.0,
                    friction: 0.0,
                    stiction_velocity: 1e-3,
                    position_error: 0.0,
                    gap: 0.0,
                    $( $field: $default, )*
                }
            }
        }

        impl $name {
            /// The contact law these fields declare (they must be valid).
            pub fn law(&self) -> $crate::world::contact_law::ContactLaw {
                $crate::world::contact_law::ContactLaw {
                    stiffness: self.stiffness,
                    damping: self.damping,
                    model: self.model,
                    exponent: self.exponent,
                    friction: self.friction,
                    stiction_velocity: self.stiction_velocity,
                }
            }

            /// Checks the shared fields.
            fn validate_contact(&self) -> $crate::error::Result<()> {
                $crate::world::contact_law::validate(
                    &self.law(),
                    self.position_error,
                    self.gap,
                )
            }
        }
    };
}
pub(crate) use surface_params;

/// Checks the shared fields of a surface's parameters.
pub fn validate(law: &ContactLaw, position_error: f64, gap: f64) -> Result<()> {
    check::non_negative("stiffness", law.stiffness)?;
    check::non_negative("damping", law.damping)?;
    if !(law.exponent.is_finite() && (1.0..=MAX_EXPONENT).contains(&law.exponent)) {
        return Err(Error::parameter(
            "exponent",
            law.exponent,
            &format!("from 1 to {MAX_EXPONENT}"),
        ));
    }
    if !(law.friction.is_finite() && (0.0..=10.0).contains(&law.friction)) {
        return Err(Error::parameter("friction", law.friction, "from 0 to 10"));
    }
    let (low, high) = STICTION_VELOCITY;
    if !(law.stiction_velocity.is_finite() && (low..=high).contains(&law.stiction_velocity)) {
        return Err(Error::parameter(
            "stiction_velocity",
            law.stiction_velocity,
            &format!("from {low:e} to {high:e} m/s"),
        ));
    }
    check::finite("position_error", position_error)?;
    check::non_negative("gap", gap)
}

/// The contact law of one surface: over `f64`, or over lanes (four surfaces of one
/// [`ContactLawKey`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContactLaw<T: Real = f64> {
    pub stiffness: T,
    pub damping: T,
    pub model: ContactModel,
    pub exponent: T,
    /// Coulomb μ.
    pub friction: T,
    /// v_s [m/s].
    pub stiction_velocity: T,
}

/// What lanes must share for their contact laws to advance together: the law's branch
/// structure and whether friction is computed at all (a frictionless run never evaluates
/// it, so its bits are the same in lanes and alone).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ContactLawKey {
    pub model: ContactModel,
    pub friction: bool,
}

impl<W: Real> ContactLaw<W> {
    /// L laws of one key in lanes.
    pub fn pack<const L: usize>(laws: [&ContactLaw; L]) -> Self
    where
        W: Wide<L>,
    {
        debug_assert!(laws.iter().all(|l| l.key() == laws[0].key()));
        let p = |f: fn(&ContactLaw) -> f64| W::from_lanes(|i| f(laws[i]));
        Self {
            stiffness: p(|l| l.stiffness),
            damping: p(|l| l.damping),
            model: laws[0].model,
            exponent: p(|l| l.exponent),
            friction: p(|l| l.friction),
            stiction_velocity: p(|l| l.stiction_velocity),
        }
    }
}

impl ContactLaw {
    pub fn key(&self) -> ContactLawKey {
        ContactLawKey {
            model: self.model,
            friction: self.friction != 0.0,
        }
    }
}

impl<T: Real> ContactLaw<T> {
    /// Whether the force reads the penetration rate: only with damping (in lanes: in any
    /// lane).
    #[inline(always)]
    pub fn needs_rate(&self) -> bool {
        !T::all(self.damping.simd_eq(T::zero()))
    }

    /// Whether friction is computed (μ ≠ 0 in some lane; one key has it in all or none).
    #[inline(always)]
    pub fn has_friction(&self) -> bool {
        !T::all(self.friction.simd_eq(T::zero()))
    }

    /// Whether the tip's velocity is needed: for damping or friction.
    #[inline(always)]
    pub fn needs_velocity(&self) -> bool {
        self.needs_rate() || self.has_friction()
    }

    /// Normal force f [N] at penetration δ and rate δ̇: 0 while δ ≤ 0. Lanes out of
    /// contact (or undamped) take their branch by select.
    #[inline(always)]
    pub fn normal_force(&self, delta: T, rate: T) -> T {
        let zero = T::zero();
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
            // A surface pushes, never pulls.
            elastic.select(undamped, f.simd_max(zero))
        };
        if T::none(apart) {
            f
        } else {
            zero.select(apart, f)
        }
    }

    /// The contact of a curved surface whose penetration δ and inward normal N at the tip
    /// are known: f from δ and δ̇ = N·Ẋ, friction from Ẋ (read only when needed).
    #[inline(always)]
    pub fn contact_at(
        &self,
        penetration: T,
        normal: Vector3<T>,
        tip: &impl TipMotion<T>,
    ) -> Contact<T> {
        let velocity = if self.needs_velocity() {
            tip.velocity()
        } else {
            Vector3::zeros()
        };
        let normal_force = self.normal_force(penetration, normal.dot(&velocity));
        Contact {
            normal,
            normal_force,
            penetration,
            friction: self
                .has_friction()
                .then(|| self.friction_force(normal_force, &normal, &velocity)),
        }
    }

    /// Coulomb friction on the tip (SPEC §15): F_t = −μ f v_t / √(|v_t|² + v_s²), v_t the
    /// tip velocity's part in the tangent plane of the unit normal `normal`. Zero where
    /// f = 0, so a tip in free space feels none.
    #[inline(always)]
    pub fn friction_force(&self, f: T, normal: &Vector3<T>, velocity: &Vector3<T>) -> Vector3<T> {
        let v_t = tangential(normal, velocity);
        let scale = -(self.friction * f)
            / (v_t.norm_squared() + self.stiction_velocity * self.stiction_velocity).simd_sqrt();
        v_t * scale
    }
}

/// v's part in the plane normal to the unit vector `normal`: v − (N·v) N.
#[inline(always)]
pub fn tangential<T: Real>(normal: &Vector3<T>, v: &Vector3<T>) -> Vector3<T> {
    v - normal * normal.dot(v)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn law(friction: f64) -> ContactLaw {
        ContactLaw {
            stiffness: 1e4,
            damping: 0.0,
            model: ContactModel::KelvinVoigt,
            exponent: 1.0,
            friction,
            stiction_velocity: 1e-3,
        }
    }

    /// f_t = μ f |v_t| / √(|v_t|² + v_s²) against the sliding direction, nothing along N,
    /// and μ f in the limit |v_t| ≫ v_s.
    #[test]
    fn regularised_coulomb_friction() {
        let n = Vector3::new(1.0, 0.0, 0.0);
        let v = Vector3::new(0.3, 0.0, 0.004);
        let ft = law(0.5).friction_force(10.0, &n, &v);
        let expected = 0.5 * 10.0 * 0.004 / (0.004f64.powi(2) + 1e-6).sqrt();
        assert!((ft.norm() - expected).abs() < 1e-12 * expected);
        assert_eq!(ft[0], 0.0);
        assert!(ft[2] < 0.0);
        let fast = law(0.5).friction_force(10.0, &n, &Vector3::new(0.0, 0.0, 10.0));
        assert!((fast.norm() - 5.0).abs() < 1e-7);
        assert_eq!(law(0.5).friction_force(0.0, &n, &v).norm(), 0.0);
    }

    #[test]
    fn invalid_friction_names_the_field() {
        let bad = |l: ContactLaw| validate(&l, 0.0, 0.0).unwrap_err().to_string();
        assert!(bad(law(-0.1)).starts_with("friction = -0.1"));
        assert!(bad(ContactLaw {
            stiction_velocity: 0.0,
            ..law(0.1)
        })
        .starts_with("stiction_velocity = 0"));
        assert!(bad(ContactLaw {
            stiction_velocity: f64::NAN,
            ..law(0.1)
        })
        .starts_with("stiction_velocity = NaN"));
    }
}
