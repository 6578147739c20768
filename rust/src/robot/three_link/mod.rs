//! The three-link arm of Table 1 (SPEC §1), in closed form.
//!
//! q1 is a yaw about +z at the origin; q2 and q3 are pitches (positive raises the link).
//! Link 1 lies on the yaw axis, so it adds nothing to D, C or G. The closed forms below come
//! from the arm's Lagrangian; the Python test suite checks them against Pinocchio.

use nalgebra::{Matrix3, Vector3};

use super::{ArmModel, RobotModel};
use crate::contact::{Contact, Surface, TipMotion};
use crate::error::{check, Error, Result};
use crate::scalar::{Real, Wide};

mod trig;
pub use trig::Trig;

pub type Vec3 = Vector3<f64>;
pub type Mat3 = Matrix3<f64>;
/// The arm's kinematics and dynamics: the generic structs at three joints.
pub type Kinematics = super::Kinematics<3>;
pub type Dynamics = super::Dynamics<3>;

/// How link mass is distributed.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize, schemars::JsonSchema,
)]
#[serde(rename_all = "snake_case")]
pub enum MassModel {
    /// Uniform thin rods: centre of mass at l/2, transverse inertia m l²/12, axial 0.
    Rod,
    /// A point mass at each link's distal end.
    Point,
}

/// Parameters of the three-link arm. Defaults are the paper's Table 1 (SPEC §1).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize, schemars::JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct RobotParams {
    /// Link lengths l1, l2, l3 [m].
    pub lengths: [f64; 3],
    /// Link masses [kg].
    pub masses: [f64; 3],
    /// ``"rod"``: uniform thin rods; ``"point"``: a point mass at each link's end.
    pub mass_model: MassModel,
    /// Viscous friction per joint [N·m·s/rad].
    pub viscous_friction: [f64; 3],
    /// Coulomb friction per joint [N·m].
    pub coulomb_friction: [f64; 3],
    /// ε [rad/s] of sgn(q̇) ≈ tanh(q̇/ε); ε ≤ 0 uses the exact sign.
    pub friction_smoothing: f64,
    /// Gravity along -z [m/s²].
    pub gravity: f64,
    /// Initial joint angles [rad].
    pub q0: [f64; 3],
}

impl Default for RobotParams {
    fn default() -> Self {
        Self {
            lengths: [0.66, 0.43, 0.43],
            masses: [30.0, 17.4, 4.8],
            mass_model: MassModel::Rod,
            viscous_friction: [3.0; 3],
            coulomb_friction: [5.0; 3],
            friction_smoothing: 0.01,
            gravity: 9.81,
            q0: [
                0.0,
                std::f64::consts::FRAC_PI_4,
                -std::f64::consts::FRAC_PI_4,
            ],
        }
    }
}

impl RobotParams {
    pub fn validate(&self) -> Result<()> {
        // An arm, not a planet: lengths beyond 1 km or masses beyond 1e9 kg overflow D's
        // products (a 1e300-m link ran as "stable" on NaN-free infinities).
        check::all("lengths", &self.lengths, |f, v| {
            check::positive_up_to(f, v, 1e3, "m")
        })?;
        check::all("masses", &self.masses, |f, v| {
            check::positive_up_to(f, v, 1e9, "kg")
        })?;
        check::all(
            "viscous_friction",
            &self.viscous_friction,
            check::non_negative,
        )?;
        check::all(
            "coulomb_friction",
            &self.coulomb_friction,
            check::non_negative,
        )?;
        check::finite("friction_smoothing", self.friction_smoothing)?;
        check::non_negative("gravity", self.gravity)?;
        check::all("q0", &self.q0, check::finite)?;
        let arm = ThreeLinkArm::new(self);
        let q0 = Vec3::from(self.q0);
        if arm.jacobian_conditioning(&q0) < SINGULARITY_TOLERANCE {
            return Err(Error::parameter(
                "q0",
                format!("{:?}", self.q0),
                "a configuration with a regular Jacobian (tip off the yaw axis and q3 not a multiple of π)",
            ));
        }
        Ok(())
    }

    /// The model a controller believes in: masses (and so inertias) scaled by `mass_scale`,
    /// friction by `friction_scale`; geometry is shared with the plant.
    pub fn with_model_error(&self, mass_scale: f64, friction_scale: f64) -> Self {
        let mut p = self.clone();
        p.masses.iter_mut().for_each(|m| *m *= mass_scale);
        super::scale_friction(
            &mut p.viscous_friction,
            &mut p.coulomb_friction,
            friction_scale,
        );
        p
    }
}

/// Below this `jacobian_conditioning` the Jacobian is treated as singular.
pub const SINGULARITY_TOLERANCE: f64 = 1e-6;

/// The arm's closed form (kinematics, eq. (1)'s D, C, G and friction) with its constants
/// folded once, over any scalar: `f64` for one arm, [`F64x4`] for four arms (whose
/// parameters may differ) advancing in lanes.
#[derive(Debug, Clone, PartialEq)]
pub struct ClosedForm<T: Real = f64> {
    l1: T,
    l2: T,
    l3: T,
    a3: T,
    g: T,
    fv: Vector3<T>,
    fc: Vector3<T>,
    /// ε, 1/ε and −2/ε, so the hot path multiplies instead of dividing.
    eps: T,
    inv_eps: T,
    neg_two_inv_eps: T,
    k: InertiaConstants<T>,
}

/// Parameter-only products of D, C and G, folded once instead of once per RK4 stage.
#[derive(Debug, Clone, PartialEq)]
struct InertiaConstants<T: Real> {
    /// m2 a2² + i2: D11's c2² coefficient.
    k2: T,
    m3_l2: T,
    m3_a3: T,
    i3: T,
    /// m3 l2 a3: D23's c3 coefficient (and −h/s3).
    m3_l2_a3: T,
    /// D22 = d22_0 + d22_c3 c3.
    d22_0: T,
    d22_c3: T,
    /// D33 = m3 a3² + i3, also D23's constant part.
    d33: T,
    g_m2_a2: T,
    g_m3_a3: T,
}

impl ClosedForm {
    /// The closed form of `p` with a tool of mass `tool` [kg] at the tip.
    fn new(p: &RobotParams, tool: f64) -> Self {
        let [l1, l2, l3] = p.lengths;
        let [_, m2, m3] = p.masses;
        let (a2, a3, i2, i3) = match p.mass_model {
            MassModel::Rod => (l2 / 2.0, l3 / 2.0, m2 * l2 * l2 / 12.0, m3 * l3 * l3 / 12.0),
            MassModel::Point => (l2, l3, 0.0, 0.0),
        };
        // A tool is a point mass on link 3's line at l3: link 3 and the tool are one body
        // on that line, of mass m3 + m_t, first moment m3 a3 + m_t l3 and second moment
        // m3 a3² + i3 + m_t l3² about joint 3, which is all the closed form reads.
        let (m3, a3, i3) = if tool > 0.0 {
            let mass = m3 + tool;
            let com = (m3 * a3 + tool * l3) / mass;
            let second = m3 * a3 * a3 + i3 + tool * l3 * l3;
            (mass, com, second - mass * com * com)
        } else {
            (m3, a3, i3)
        };
        let g = p.gravity;
        let k2 = m2 * a2 * a2 + i2;
        let d33 = m3 * a3 * a3 + i3;
        Self {
            l1,
            l2,
            l3,
            a3,
            g,
            fv: Vec3::from(p.viscous_friction),
            fc: Vec3::from(p.coulomb_friction),
            eps: p.friction_smoothing,
            inv_eps: 1.0 / p.friction_smoothing,
            neg_two_inv_eps: -2.0 / p.friction_smoothing,
            k: InertiaConstants {
                k2,
                m3_l2: m3 * l2,
                m3_a3: m3 * a3,
                i3,
                m3_l2_a3: m3 * l2 * a3,
                d22_0: k2 + m3 * l2 * l2 + d33,
                d22_c3: 2.0 * m3 * l2 * a3,
                d33,
                g_m2_a2: g * m2 * a2,
                g_m3_a3: g * m3 * a3,
            },
        }
    }
}

impl<W: Real> ClosedForm<W> {
    /// Four arms' closed forms in four lanes.
    pub fn pack<const L: usize>(arms: [&ClosedForm; L]) -> Self
    where
        W: Wide<L>,
    {
        let p = |f: fn(&ClosedForm) -> f64| W::from_lanes(|i| f(arms[i]));
        let v =
            |f: fn(&ClosedForm) -> &Vec3| Vector3::from_fn(|j, _| W::from_lanes(|i| f(arms[i])[j]));
        Self {
            l1: p(|a| a.l1),
            l2: p(|a| a.l2),
            l3: p(|a| a.l3),
            a3: p(|a| a.a3),
            g: p(|a| a.g),
            fv: v(|a| &a.fv),
            fc: v(|a| &a.fc),
            eps: p(|a| a.eps),
            inv_eps: p(|a| a.inv_eps),
            neg_two_inv_eps: p(|a| a.neg_two_inv_eps),
            k: InertiaConstants {
                k2: p(|a| a.k.k2),
                m3_l2: p(|a| a.k.m3_l2),
                m3_a3: p(|a| a.k.m3_a3),
                i3: p(|a| a.k.i3),
                m3_l2_a3: p(|a| a.k.m3_l2_a3),
                d22_0: p(|a| a.k.d22_0),
                d22_c3: p(|a| a.k.d22_c3),
                d33: p(|a| a.k.d33),
                g_m2_a2: p(|a| a.k.g_m2_a2),
                g_m3_a3: p(|a| a.k.g_m3_a3),
            },
        }
    }
}

impl<W: Real> ClosedForm<W> {
    /// Lane `l` takes the arm `a` (a new run's, or its controller's model).
    pub fn put_lane(&mut self, l: usize, a: &ClosedForm) {
        let one = |x: &mut W, v: f64| x.replace(l, v);
        one(&mut self.l1, a.l1);
        one(&mut self.l2, a.l2);
        one(&mut self.l3, a.l3);
        one(&mut self.a3, a.a3);
        one(&mut self.g, a.g);
        for j in 0..3 {
            one(&mut self.fv[j], a.fv[j]);
            one(&mut self.fc[j], a.fc[j]);
        }
        one(&mut self.eps, a.eps);
        one(&mut self.inv_eps, a.inv_eps);
        one(&mut self.neg_two_inv_eps, a.neg_two_inv_eps);
        let (k, c) = (&mut self.k, &a.k);
        one(&mut k.k2, c.k2);
        one(&mut k.m3_l2, c.m3_l2);
        one(&mut k.m3_a3, c.m3_a3);
        one(&mut k.i3, c.i3);
        one(&mut k.m3_l2_a3, c.m3_l2_a3);
        one(&mut k.d22_0, c.d22_0);
        one(&mut k.d22_c3, c.d22_c3);
        one(&mut k.d33, c.d33);
        one(&mut k.g_m2_a2, c.g_m2_a2);
        one(&mut k.g_m3_a3, c.g_m3_a3);
    }
}

/// The three-link tip's motion at one state, from the closed form's trigonometry: with
/// r = l2 c2 + l3 c23 (distance from the yaw axis) and h = l2 s2 + l3 s23 (height above the
/// shoulder), and the normal's horizontal part in the arm's yaw frame a = (c1, s1)·(n0, n1),
/// b = (−s1, c1)·(n0, n1): n·X = r a + n2 (l1 + h), and Jᵀ n follows from J's entries (see
/// `kinematics`). For the paper's n = e_x, n·X = x and Jᵀ n is J's first row.
pub struct ClosedTip<'a, T: Real> {
    form: &'a ClosedForm<T>,
    trig: Trig<T>,
    qd: &'a Vector3<T>,
}

impl<T: Real> ClosedTip<'_, T> {
    #[inline(always)]
    fn radius_height(&self) -> (T, T) {
        let (f, t) = (self.form, &self.trig);
        (f.l2 * t.c2 + f.l3 * t.c23, f.l2 * t.s2 + f.l3 * t.s23)
    }

    /// (a, b) of the normal's horizontal part in the yaw frame.
    #[inline(always)]
    fn yaw_frame(&self, n: &Vector3<T>) -> (T, T) {
        let t = &self.trig;
        (t.c1 * n[0] + t.s1 * n[1], t.c1 * n[1] - t.s1 * n[0])
    }

    /// Jᵀ n.
    #[inline(always)]
    pub fn jacobian_transpose(&self, n: &Vector3<T>) -> Vector3<T> {
        let (r, h) = self.radius_height();
        let (a, b) = self.yaw_frame(n);
        let t = &self.trig;
        Vector3::new(
            r * b,
            r * n[2] - h * a,
            self.form.l3 * (t.c23 * n[2] - t.s23 * a),
        )
    }
}

impl<T: Real> TipMotion<T> for ClosedTip<'_, T> {
    #[inline(always)]
    fn along(&self, n: &Vector3<T>, rate: bool) -> (T, T) {
        let (r, h) = self.radius_height();
        let (a, _) = self.yaw_frame(n);
        let along = r * a + n[2] * (self.form.l1 + h);
        let rate = if rate {
            self.jacobian_transpose(n).dot(self.qd)
        } else {
            T::zero()
        };
        (along, rate)
    }

    #[inline(always)]
    fn position(&self) -> Vector3<T> {
        let (r, h) = self.radius_height();
        let t = &self.trig;
        Vector3::new(r * t.c1, r * t.s1, self.form.l1 + h)
    }

    /// Ẋ = J q̇ from the closed form's rates: X = (r c1, r s1, l1 + h), so
    /// Ẋ = (ṙ c1 − r s1 q̇1, ṙ s1 + r c1 q̇1, ḣ) with ṙ = −h q̇2 − l3 s23 q̇3 and
    /// ḣ = r q̇2 + l3 c23 q̇3 (10 products; J's zeros never multiplied).
    #[inline(always)]
    fn velocity(&self) -> Vector3<T> {
        let (r, h) = self.radius_height();
        let (t, l3, qd) = (&self.trig, self.form.l3, self.qd);
        let r_dot = -(h * qd[1]) - l3 * t.s23 * qd[2];
        let h_dot = r * qd[1] + l3 * t.c23 * qd[2];
        let yaw = r * qd[0];
        Vector3::new(r_dot * t.c1 - yaw * t.s1, r_dot * t.s1 + yaw * t.c1, h_dot)
    }
}

impl<T: Real> ClosedForm<T> {
    /// |det J| / (l2 l3 (l2 + l3)) = |r sin q3| / (l2 + l3): zero exactly at the singular
    /// configurations (det J = −r l2 l3 sin q3, r the tip's distance from the yaw axis).
    pub fn jacobian_conditioning(&self, t: &Trig<T>) -> T {
        let r = self.l2 * t.c2 + self.l3 * t.c23;
        (r * t.s3).simd_abs() / (self.l2 + self.l3)
    }

    /// sgn(v) as friction uses it: tanh(v/ε), or the exact sign where ε ≤ 0.
    #[inline(always)]
    fn sign(&self, v: T) -> T {
        friction_sign(v, v * self.inv_eps, self.eps)
    }

    /// Coulomb friction of joint `j`: f_c tanh(q̇/ε) as f_c (1 − e)/(1 + e) with
    /// e = e^(−2|q̇|/ε) and the sign of q̇ (as `smooth_sign`, with f_c multiplied in before the
    /// division to shorten the chain), or f_c sgn q̇ for ε ≤ 0.
    #[inline(always)]
    fn coulomb(&self, j: usize, v: T) -> T {
        let zero = T::zero();
        let sharp = self.eps.simd_le(zero);
        if T::all(sharp) {
            return self.fc[j] * self.sign(v);
        }
        // A joint at rest (the yaw joint in every planar task) skips the call.
        let rest = v.simd_eq(zero);
        if T::all(rest) {
            return zero;
        }
        // |v|·(−2/ε) is −2|v/ε| exactly: scaling by 2 commutes with rounding.
        let e = (v.simd_abs() * self.neg_two_inv_eps).exp_fast();
        let one = T::one();
        let smooth = ((self.fc[j] * (one - e)) / (one + e)).simd_copysign(v);
        let smooth = if T::none(rest) {
            smooth
        } else {
            zero.select(rest, smooth)
        };
        if T::none(sharp) {
            smooth
        } else {
            (self.fc[j] * self.sign(v)).select(sharp, smooth)
        }
    }
}

/// The closed form as the arm interface, over any scalar: one arm in `f64`, four in lanes.
impl<T: Real> ArmModel<T, 3> for ClosedForm<T> {
    type Config = Trig<T>;

    #[inline(always)]
    fn configure(&self, q: &Vector3<T>) -> Trig<T> {
        Trig::new(q)
    }

    /// Angle addition from the stage's start (`Trig::shifted`).
    #[inline(always)]
    fn configure_shifted(
        &self,
        at_q: &Trig<T>,
        delta: &Vector3<T>,
        shifted: &Vector3<T>,
        out: &mut Trig<T>,
    ) {
        *out = at_q.shifted(delta, shifted);
    }

    #[inline]
    fn tip_position(&self, t: &Trig<T>) -> Vector3<T> {
        let r = self.l2 * t.c2 + self.l3 * t.c23;
        Vector3::new(
            t.c1 * r,
            t.s1 * r,
            self.l1 + self.l2 * t.s2 + self.l3 * t.s23,
        )
    }

    /// Link 3's frame: x along the link, y = (−sin q1, cos q1, 0) along the pitch axes
    /// (positive pitch turns about −y), z = x × y.
    #[inline]
    fn tip_rotation(&self, t: &Trig<T>) -> Matrix3<T> {
        let zero = T::zero();
        Matrix3::new(
            t.c1 * t.c23,
            -t.s1,
            -t.c1 * t.s23,
            t.s1 * t.c23,
            t.c1,
            -t.s1 * t.s23,
            t.s23,
            zero,
            t.c23,
        )
    }

    #[inline]
    fn kinematics(&self, t: &Trig<T>, qd: &Vector3<T>) -> super::Kinematics<3, T> {
        let (l2, l3) = (self.l2, self.l3);
        let two = T::splat(2.0);
        let r = l2 * t.c2 + l3 * t.c23; // distance from the yaw axis
        let h = l2 * t.s2 + l3 * t.s23; // height above the shoulder
        let position = Vector3::new(t.c1 * r, t.s1 * r, self.l1 + h);
        let jacobian = Matrix3::new(
            -t.s1 * r,
            -t.c1 * h,
            -t.c1 * l3 * t.s23,
            t.c1 * r,
            -t.s1 * h,
            -t.s1 * l3 * t.s23,
            T::zero(),
            r,
            l3 * t.c23,
        );
        let (w1, w2) = (qd[0], qd[1]);
        let w23 = qd[1] + qd[2];
        let r_dot = -h * w2 - l3 * t.s23 * qd[2];
        // Parts of r̈ and z̈ that do not contain q̈.
        let r_ddot = -(l2 * t.c2 * w2 * w2 + l3 * t.c23 * w23 * w23);
        let z_ddot = -(l2 * t.s2 * w2 * w2 + l3 * t.s23 * w23 * w23);
        let jdot_qd = Vector3::new(
            -t.c1 * w1 * w1 * r - two * t.s1 * w1 * r_dot + t.c1 * r_ddot,
            -t.s1 * w1 * w1 * r + two * t.c1 * w1 * r_dot + t.s1 * r_ddot,
            z_ddot,
        );
        super::Kinematics {
            position,
            jacobian,
            jdot_qd,
        }
    }

    #[inline(always)]
    fn dynamics(&self, t: &Trig<T>, qd: &Vector3<T>) -> super::Dynamics<3, T> {
        let k = &self.k;
        let (zero, two) = (T::zero(), T::splat(2.0));
        // m3 times the distance of link 3's centre of mass from the yaw axis.
        let m3r3 = k.m3_l2 * t.c2 + k.m3_a3 * t.c23;
        let r3 = self.l2 * t.c2 + self.a3 * t.c23;
        let i3cs = k.i3 * t.c23 * t.s23;
        let d11 = k.k2 * t.c2 * t.c2 + m3r3 * r3 + k.i3 * t.c23 * t.c23;
        let d22 = k.d22_0 + k.d22_c3 * t.c3;
        let d23 = k.d33 + k.m3_l2_a3 * t.c3;
        // The yaw inertia is decoupled from the pitch block: D12 = D13 = 0.
        let inertia = Matrix3::new(d11, zero, zero, zero, d22, d23, zero, d23, k.d33);

        // C by Christoffel symbols from ∂D11/∂q2 = −2 p2, ∂D11/∂q3 = −2 p3,
        // ∂D22/∂q3 = 2h and ∂D23/∂q3 = h.
        let p2 = k.k2 * t.c2 * t.s2 + m3r3 * (self.l2 * t.s2 + self.a3 * t.s23) + i3cs;
        let p3 = m3r3 * self.a3 * t.s23 + i3cs;
        let h = -k.m3_l2_a3 * t.s3;
        let (w1, w2, w3) = (qd[0], qd[1], qd[2]);
        let w11 = w1 * w1;
        let coriolis = Vector3::new(
            -two * (p2 * w2 + p3 * w3) * w1,
            h * w3 * (two * w2 + w3) + p2 * w11,
            -h * w2 * w2 + p3 * w11,
        );
        let gravity = Vector3::new(zero, k.g_m2_a2 * t.c2 + self.g * m3r3, k.g_m3_a3 * t.c23);
        super::Dynamics {
            inertia,
            coriolis,
            gravity,
        }
    }

    /// Viscous plus Coulomb friction at q̇. Always inlined: it runs at every RK4 stage, and
    /// left out of line from the lanes' AVX2 loop (as LTO once chose) it ran as baseline
    /// two-wide code.
    #[inline(always)]
    fn friction(&self, qd: &Vector3<T>) -> Vector3<T> {
        Vector3::new(
            self.fv[0] * qd[0] + self.fc[0] * self.sign(qd[0]),
            self.fv[1] * qd[1] + self.fc[1] * self.sign(qd[1]),
            self.fv[2] * qd[2] + self.fc[2] * self.sign(qd[2]),
        )
    }

    /// Joint accelerations with the surface's contact evaluated at the same state: eq. (1)
    /// with τ_ext = Jᵀ F, F = −f n. The tip's motion along n and Jᵀn come from the closed
    /// form ([`ClosedTip`]). Returns (q̈, the contact).
    #[inline(always)]
    fn accelerate(
        &self,
        t: &Trig<T>,
        qd: &Vector3<T>,
        tau: &Vector3<T>,
        surface: &impl Surface<T>,
    ) -> (Vector3<T>, Contact<T>) {
        let t = *t;
        let tip = ClosedTip {
            form: self,
            trig: t,
            qd,
        };
        let contact = surface.contact(&tip);
        // The surface pushes the tip along −n (and friction along the surface: then one
        // Jᵀ of F = −f n + F_t; a frictionless run keeps (Jᵀn)·(−f), the paper's bits).
        let contact_torque = match &contact.friction {
            None => tip.jacobian_transpose(&contact.normal) * -contact.normal_force,
            Some(_) => tip.jacobian_transpose(&contact.force()),
        };
        let d = self.dynamics(&t, qd);
        // q̈ = D⁻¹ (rest − τ_c), with τ_c the Coulomb friction and rest everything else. The
        // longest dependency chain of an RK4 stage runs q̇ → exp → τ_c → q̈ → next stage's q̇,
        // so τ_c enters last, through the inverse of D (which depends on q only and is
        // ready early): three dependent operations after τ_c instead of five.
        let rest = tau + contact_torque - d.coriolis - d.gravity - self.fv.component_mul(qd);
        let (a, b, c) = (d.inertia[(1, 1)], d.inertia[(1, 2)], d.inertia[(2, 2)]);
        let inv_d11 = T::one() / d.inertia[(0, 0)];
        let inv_det = T::one() / (a * c - b * b);
        let (k22, k23, k33) = (c * inv_det, -b * inv_det, a * inv_det);
        let tau_c = Vector3::new(
            self.coulomb(0, qd[0]),
            self.coulomb(1, qd[1]),
            self.coulomb(2, qd[2]),
        );
        let qdd = Vector3::new(
            rest[0] * inv_d11 - tau_c[0] * inv_d11,
            (k22 * rest[1] + k23 * rest[2]) - (k22 * tau_c[1] + k23 * tau_c[2]),
            (k23 * rest[1] + k33 * rest[2]) - (k23 * tau_c[1] + k33 * tau_c[2]),
        );
        (qdd, contact)
    }

    /// Eq. (1) with a given tip force, solved with D's block structure.
    fn forward_dynamics(
        &self,
        t: &Trig<T>,
        qd: &Vector3<T>,
        tau: &Vector3<T>,
        tip_force: &Vector3<T>,
    ) -> Vector3<T> {
        let (k, d) = (self.kinematics(t, qd), self.dynamics(t, qd));
        let rhs =
            tau + k.jacobian.transpose() * tip_force - d.coriolis - d.gravity - self.friction(qd);
        solve_block_inertia(&d.inertia, &rhs)
    }
}

/// sgn(v) as Coulomb friction uses it: tanh(v/ε) (`scaled` = v/ε) where ε > 0, else the
/// exact sign (0 at 0), lane by lane.
#[inline(always)]
pub(crate) fn friction_sign<T: Real>(v: T, scaled: T, eps: T) -> T {
    let (zero, one) = (T::zero(), T::one());
    let exact = one.select(v.simd_gt(zero), (-one).select(v.simd_lt(zero), zero));
    let sharp = eps.simd_le(zero);
    if T::all(sharp) {
        return exact;
    }
    let smooth = smooth_sign(scaled);
    if T::none(sharp) {
        smooth
    } else {
        exact.select(sharp, smooth)
    }
}

/// tanh(x) as ±(1 − e^(−2|x|)) / (1 + e^(−2|x|)): one `exp`, never overflows, within
/// 2.3e-16 of `f64::tanh` (tested) and about twice as fast. It runs 3 times per RK4 stage.
#[inline(always)]
pub(crate) fn smooth_sign<T: Real>(x: T) -> T {
    let zero = T::zero();
    // A joint at rest (the yaw joint in every planar task) skips the call.
    let rest = x.simd_eq(zero);
    if T::all(rest) {
        return x;
    }
    let one = T::one();
    let e = (T::splat(-2.0) * x.simd_abs()).exp_fast();
    let y = ((one - e) / (one + e)).simd_copysign(x);
    if T::none(rest) {
        y
    } else {
        x.select(rest, y)
    }
}

/// Solves D q̈ = rhs for this arm's block-diagonal D (yaw scalar ⊕ 2×2 pitch block).
/// A singular D (arm straight up: no yaw inertia) gives non-finite q̈, which the
/// simulation reports as divergence.
#[inline]
fn solve_block_inertia<T: Real>(d: &Matrix3<T>, rhs: &Vector3<T>) -> Vector3<T> {
    let (a, b, c) = (d[(1, 1)], d[(1, 2)], d[(2, 2)]);
    let inv_det = T::one() / (a * c - b * b);
    Vector3::new(
        rhs[0] / d[(0, 0)],
        (c * rhs[1] - b * rhs[2]) * inv_det,
        (a * rhs[2] - b * rhs[1]) * inv_det,
    )
}

/// The arm of Table 1: its parameters and its closed form in `f64`.
#[derive(Debug, Clone, PartialEq)]
pub struct ThreeLinkArm {
    /// The parameters it was built from (model-error copies start from them).
    params: RobotParams,
    /// A tool's mass at the tip [kg] (SPEC §15).
    tool: f64,
    form: ClosedForm,
}

impl ThreeLinkArm {
    pub fn new(p: &RobotParams) -> Self {
        Self::with_tool_mass(p, 0.0)
    }

    fn with_tool_mass(p: &RobotParams, tool: f64) -> Self {
        Self {
            params: p.clone(),
            tool,
            form: ClosedForm::new(p, tool),
        }
    }

    /// The closed form, for the SIMD lanes that pack four arms' (`ClosedForm::pack`).
    pub fn closed_form(&self) -> &ClosedForm {
        &self.form
    }

    /// |det J| / (l2 l3 (l2 + l3)): zero exactly at the singular configurations.
    pub fn jacobian_conditioning(&self, q: &Vec3) -> f64 {
        self.form.jacobian_conditioning(&Trig::new(q))
    }
}

impl RobotModel<3> for ThreeLinkArm {
    type Model = ClosedForm;
    type Lanes<W: Real> = ClosedForm<W>;

    #[inline(always)]
    fn model(&self) -> &ClosedForm {
        &self.form
    }

    fn same_structure(&self, _: &Self) -> bool {
        true
    }

    fn pack<W: Wide<L>, const L: usize>(models: [&ClosedForm; L]) -> ClosedForm<W> {
        ClosedForm::pack(models)
    }

    fn put_lane<W: Real>(lanes: &mut ClosedForm<W>, l: usize, model: &ClosedForm) {
        lanes.put_lane(l, model);
    }

    fn with_model_error(&self, mass_scale: f64, friction_scale: f64) -> Self {
        let p = self.params.with_model_error(mass_scale, friction_scale);
        ThreeLinkArm::with_tool_mass(&p, self.tool)
    }

    fn with_tool(&self, mass: f64) -> Self {
        ThreeLinkArm::with_tool_mass(&self.params, mass)
    }

    fn gravity(&self) -> f64 {
        self.params.gravity
    }

    fn initial_position(&self) -> Vec3 {
        Vec3::from(self.params.q0)
    }
}

/// Conveniences that evaluate the trigonometry themselves (tests, the Python layer).
impl ThreeLinkArm {
    pub fn params(&self) -> &RobotParams {
        &self.params
    }

    /// Kinematics and dynamics together, sharing one trigonometric evaluation.
    pub fn evaluate(&self, q: &Vec3, qd: &Vec3) -> (Kinematics, Dynamics) {
        let t = Trig::new(q);
        (self.form.kinematics(&t, qd), self.form.dynamics(&t, qd))
    }

    /// Tip position at q.
    pub fn forward_kinematics(&self, q: &Vec3) -> Vec3 {
        self.form.tip_position(&Trig::new(q))
    }

    /// q̈ of eq. (1) at (q, q̇) with a Cartesian tip force.
    pub fn forward_dynamics_at(&self, q: &Vec3, qd: &Vec3, tau: &Vec3, tip_force: &Vec3) -> Vec3 {
        self.form
            .forward_dynamics(&Trig::new(q), qd, tau, tip_force)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn arm() -> (RobotParams, ThreeLinkArm) {
        let p = RobotParams::default();
        let a = ThreeLinkArm::new(&p);
        (p, a)
    }

    fn q0() -> Vec3 {
        Vec3::from(RobotParams::default().q0)
    }

    #[test]
    fn spec_check_values_at_q0() {
        let (_, arm) = arm();
        let k = arm.model().kinematics(&Trig::new(&q0()), &Vec3::zeros());
        assert!(
            (k.position - Vec3::new(0.734056, 0.0, 0.964056))
                .abs()
                .max()
                < 5e-7
        );
        let d = arm.model().dynamics(&Trig::new(&q0()), &Vec3::zeros());
        let expected = Mat3::new(1.903, 0.0, 0.0, 0.0, 2.883, 0.610, 0.0, 0.610, 0.296);
        assert!((d.inertia - expected).abs().max() < 5e-4, "{}", d.inertia);
        assert!((d.gravity - Vec3::new(0.0, 50.39, 10.12)).abs().max() < 5e-3);
    }

    #[test]
    fn jacobian_matches_finite_differences_and_jdot() {
        let (_, arm) = arm();
        let q = Vec3::new(0.3, 0.7, -1.1);
        let qd = Vec3::new(0.4, -0.9, 1.3);
        let k = arm.model().kinematics(&Trig::new(&q), &qd);
        let h = 1e-6;
        for j in 0..3 {
            let mut dq = Vec3::zeros();
            dq[j] = h;
            let col =
                (arm.forward_kinematics(&(q + dq)) - arm.forward_kinematics(&(q - dq))) / (2.0 * h);
            assert!((col - k.jacobian.column(j)).abs().max() < 1e-8);
        }
        // J̇q̇ = d/dt (J q̇) along q(t) = q + q̇ t with q̇ constant.
        let jqd = |t: f64| {
            arm.model()
                .kinematics(&Trig::new(&(q + qd * t)), &qd)
                .jacobian
                * qd
        };
        let fd = (jqd(h) - jqd(-h)) / (2.0 * h);
        assert!((fd - k.jdot_qd).abs().max() < 1e-7);
    }

    #[test]
    fn jacobian_determinant_closed_form() {
        let (p, arm) = arm();
        let q = Vec3::new(0.2, 0.5, -0.8);
        let k = arm.model().kinematics(&Trig::new(&q), &Vec3::zeros());
        let r = p.lengths[1] * q[1].cos() + p.lengths[2] * (q[1] + q[2]).cos();
        let det = -r * p.lengths[1] * p.lengths[2] * q[2].sin();
        assert!((k.jacobian.determinant() - det).abs() < 1e-12);
    }

    /// Energy balance: with no friction and no torque, d/dt(T + V) = 0 along the flow,
    /// which checks C against D (q̇ᵀ(Ḋ/2 q̇ − C) = 0) and G against the potential.
    #[test]
    fn coriolis_and_gravity_conserve_energy() {
        for model in [MassModel::Rod, MassModel::Point] {
            let p = RobotParams {
                mass_model: model,
                viscous_friction: [0.0; 3],
                coulomb_friction: [0.0; 3],
                ..RobotParams::default()
            };
            let arm = ThreeLinkArm::new(&p);
            let q = Vec3::new(0.3, 0.6, -0.9);
            let qd = Vec3::new(1.1, -0.7, 0.5);
            let qdd = arm.forward_dynamics_at(&q, &qd, &Vec3::zeros(), &Vec3::zeros());
            let energy = |q: &Vec3, qd: &Vec3| {
                let d = arm.model().dynamics(&Trig::new(q), qd);
                let (a2, a3) = match model {
                    MassModel::Rod => (p.lengths[1] / 2.0, p.lengths[2] / 2.0),
                    MassModel::Point => (p.lengths[1], p.lengths[2]),
                };
                let z2 = a2 * q[1].sin();
                let z3 = p.lengths[1] * q[1].sin() + a3 * (q[1] + q[2]).sin();
                0.5 * qd.dot(&(d.inertia * qd)) + p.gravity * (p.masses[1] * z2 + p.masses[2] * z3)
            };
            let h = 1e-6;
            let de = (energy(&(q + qd * h), &(qd + qdd * h))
                - energy(&(q - qd * h), &(qd - qdd * h)))
                / (2.0 * h);
            assert!(de.abs() < 1e-6, "{model:?}: dE/dt = {de}");
        }
    }

    #[test]
    fn accelerate_matches_forward_dynamics_with_contact() {
        let (_, arm) = arm();
        let q = Vec3::new(0.1, 0.7, -0.6);
        let qd = Vec3::new(0.2, 0.3, -0.4);
        let tau = Vec3::new(1.0, 40.0, 9.0);
        let n = Vec3::new(0.6, 0.48, 0.64);
        // A spring and damper along n that reads n·Ẋ only when `rate`.
        struct Linear(Vec3, bool);
        impl Surface<f64> for Linear {
            fn contact(&self, tip: &impl TipMotion<f64>) -> Contact<f64> {
                let (s, rate) = tip.along(&self.0, self.1);
                Contact {
                    friction: None,
                    normal: self.0,
                    normal_force: 1000.0 * s + 20.0 * rate,
                    penetration: s,
                }
            }
        }
        let (qdd, c) = arm
            .model()
            .accelerate(&Trig::new(&q), &qd, &tau, &Linear(n, true));
        let k = arm.model().kinematics(&Trig::new(&q), &qd);
        let expected = 1000.0 * n.dot(&k.position) + 20.0 * n.dot(&(k.jacobian * qd));
        let f = c.normal_force;
        assert!((f - expected).abs() < 1e-12, "{f} vs {expected}");
        assert_eq!(c.force(), n * -f);
        let reference = arm.forward_dynamics_at(&q, &qd, &tau, &(n * -f));
        assert!((qdd - reference).abs().max() < 1e-12);
        // Without the rate the contact sees ṡ = 0.
        let (_, c0) = arm
            .model()
            .accelerate(&Trig::new(&q), &qd, &tau, &Linear(n, false));
        assert!((c0.normal_force - 1000.0 * n.dot(&k.position)).abs() < 1e-12);
    }

    /// The tip's velocity from the closed form's rates is J q̇, and a contact with
    /// friction applies Jᵀ(−f n + F_t) in one product.
    #[test]
    fn tip_velocity_is_j_qdot_and_friction_goes_through_jt() {
        let (_, arm) = arm();
        let n = Vec3::new(0.0, 0.6, 0.8);
        // Friction opposite the tip's velocity, F_t = −3 Ẋ (its tangential part aside).
        struct Sliding(Vec3);
        impl Surface<f64> for Sliding {
            fn contact(&self, tip: &impl TipMotion<f64>) -> Contact<f64> {
                Contact {
                    friction: Some(tip.velocity() * -3.0),
                    normal: self.0,
                    normal_force: 5.0 + tip.position()[2],
                    penetration: 0.0,
                }
            }
        }
        for (q, qd) in [
            (Vec3::new(0.1, 0.7, -0.6), Vec3::new(0.2, 0.3, -0.4)),
            (Vec3::new(-2.0, -0.3, 1.9), Vec3::new(-1.5, 2.0, 0.7)),
        ] {
            let tau = Vec3::new(1.0, 40.0, 9.0);
            let k = arm.model().kinematics(&Trig::new(&q), &qd);
            let (qdd, c) = arm
                .model()
                .accelerate(&Trig::new(&q), &qd, &tau, &Sliding(n));
            let v = k.jacobian * qd;
            assert!(
                (c.friction.map(|f| f / -3.0).unwrap_or_default() - v)
                    .abs()
                    .max()
                    < 1e-14
            );
            let force = n * -(5.0 + k.position[2]) - v * 3.0;
            let reference = arm.forward_dynamics_at(&q, &qd, &tau, &force);
            assert!(
                (qdd - reference).abs().max() < 1e-11,
                "{qdd} vs {reference}"
            );
        }
    }

    /// Angle addition agrees with a fresh evaluation to rounding, over the whole range
    /// where it is used (|δ| ≤ 1/128), and hands over to a fresh evaluation beyond it.
    #[test]
    fn shifted_trig_is_trig_of_the_sum() {
        let q = Vec3::new(0.3, std::f64::consts::FRAC_PI_4, -2.9);
        let base = Trig::new(&q);
        let worst = |a: &Trig, b: &Trig| {
            [
                a.s1 - b.s1,
                a.c1 - b.c1,
                a.s2 - b.s2,
                a.c2 - b.c2,
                a.s3 - b.s3,
                a.c3 - b.c3,
                a.s23 - b.s23,
                a.c23 - b.c23,
            ]
            .iter()
            .fold(0.0f64, |m, d| m.max(d.abs()))
        };
        for i in -100..=100 {
            let d = i as f64 / 12800.0; // up to ±1/128
            let delta = Vec3::new(d, -0.7 * d, 0.3 * d);
            let shifted = base.shifted(&delta, &(q + delta));
            let fresh = Trig::new(&(q + delta));
            assert!(worst(&shifted, &fresh) < 4.5e-16, "δ = {d}");
        }
        // Beyond 1/128 it is a fresh evaluation, bit for bit.
        let delta = Vec3::new(0.0, 0.008, 0.0);
        assert_eq!(base.shifted(&delta, &(q + delta)), Trig::new(&(q + delta)));
    }

    #[test]
    fn smooth_sign_is_tanh() {
        let worst = (0..=600_000)
            .map(|i| -30.0 + i as f64 * 1e-4)
            .map(|x| (smooth_sign(x) - x.tanh()).abs())
            .fold(0.0, f64::max);
        assert!(worst <= 2.3e-16, "{worst}");
        assert_eq!(smooth_sign(0.0), 0.0);
        assert_eq!(smooth_sign(1e3), 1.0);
        assert_eq!(smooth_sign(-1e3), -1.0);
    }

    #[test]
    fn friction_smoothed_and_exact() {
        let (mut p, arm) = arm();
        let f = arm.model().friction(&Vec3::new(0.01, 0.0, -1.0));
        assert!((f[0] - (0.03 + 5.0 * 1f64.tanh())).abs() < 1e-12);
        assert_eq!(f[1], 0.0);
        assert!((f[2] - (-3.0 - 5.0 * 100f64.tanh())).abs() < 1e-12);
        p.friction_smoothing = 0.0;
        let exact = ThreeLinkArm::new(&p)
            .model()
            .friction(&Vec3::new(0.01, 0.0, -1.0));
        assert_eq!(exact, Vec3::new(5.03, 0.0, -8.0));
    }

    #[test]
    fn absurd_sizes_are_parameter_errors() {
        for (lengths, masses, field) in [
            ([0.3, 1e300, 0.4], [1.0, 1.0, 1.0], "lengths[1] = 1e300"),
            ([0.3, 0.4, 0.4], [1.0, 1.0, 1e100], "masses[2] = 1e100"),
            ([0.3, 0.4, -1.0], [1.0, 1.0, 1.0], "lengths[2] = -1"),
        ] {
            let p = RobotParams {
                lengths,
                masses,
                ..RobotParams::default()
            };
            let e = p.validate().unwrap_err().to_string();
            assert!(e.starts_with(field), "{e}");
        }
    }

    #[test]
    fn singular_start_is_a_parameter_error() {
        let p = RobotParams {
            q0: [0.0, 0.5, 0.0],
            ..RobotParams::default()
        };
        let err = p.validate().unwrap_err();
        assert!(err.to_string().starts_with("q0 ="), "{err}");
        let p = RobotParams {
            masses: [30.0, -1.0, 4.8],
            ..RobotParams::default()
        };
        assert!(p
            .validate()
            .unwrap_err()
            .to_string()
            .starts_with("masses[1]"));
    }

    #[test]
    fn model_error_scales_inertia_and_friction() {
        let (p, arm) = arm();
        let wrong = arm.with_model_error(1.2, 0.5);
        assert_eq!(wrong, ThreeLinkArm::new(&p.with_model_error(1.2, 0.5)));
        let (d, dw) = (
            arm.model().dynamics(&Trig::new(&q0()), &Vec3::zeros()),
            wrong.model().dynamics(&Trig::new(&q0()), &Vec3::zeros()),
        );
        assert!((dw.inertia - d.inertia * 1.2).abs().max() < 1e-12);
        let qd = Vec3::new(1.0, -1.0, 0.5);
        assert!(
            (wrong.model().friction(&qd) - arm.model().friction(&qd) * 0.5)
                .abs()
                .max()
                < 1e-12
        );
    }
}
