//! The position control laws as pure functions over a scalar `T` (`f64` for one run, a lane
//! type for four): computed torque (eq. 7), model-free control (eq. 18 without the delay
//! estimate) and time-delayed control (eqs. 17, 18), each on the paper's square path (J⁻¹ of
//! a three-joint position task) and on the general task path of SPEC §11 (the damped
//! pseudo-inverse J⁺, orientation rows, a null-space posture term). They hold no state:
//! `control::controller` owns the memory and picks the path.

use nalgebra::{Matrix3, SMatrix, SVector, Vector3};

use crate::control::params::TdcLaw;
use crate::robot::Dynamics;
use crate::robot::Kinematics;
#[cfg(test)]
use crate::robot::{JointVector, TaskVector};
use crate::scalar::{finite, mat_t_vec, mat_vec, no_lane, zeros, Real};

/// The orientation part of a pose task: the error e_o = log(R0 Rᵀ) as a rotation vector
/// (the orientation is held at its start R0), the angular Jacobian and its J̇q̇. Over `f64`,
/// or four runs' terms in lanes.
#[derive(Debug, Clone, Copy)]
pub struct OrientationTask<const N: usize, T: Real = f64> {
    pub error: Vector3<T>,
    pub jacobian: SMatrix<T, 3, N>,
    pub jdot_qd: Vector3<T>,
}

/// The damped pseudo-inverse J⁺ = Jᵀ (J Jᵀ + λ² I)⁻¹ of a 6×N task Jacobian (SPEC §11),
/// with the lanes where it failed: a Cholesky pivot of J Jᵀ + λ² I that is not positive
/// (zero, negative or NaN), or a J⁺ that is not finite.
///
/// This is nalgebra's `cholesky()` and `solve`, operation for operation (J Jᵀ summed in
/// gemm's order, the factor column by column, forward then backward substitution, so the
/// `f64` bits of nalgebra's, tested), written out because nalgebra's loops are not inlined
/// into the AVX2 lane loop: left out of line, they ran as baseline two-wide code. Its
/// `cholesky()` also needs a `ComplexField` (it returns `None` at a bad pivot), which SIMD
/// lanes are not: the pivots (√pivot on L's diagonal) are checked here, lane by lane.
#[inline(always)]
pub(crate) fn damped_pseudo_inverse<T: Real, const N: usize>(
    j: &SMatrix<T, 6, N>,
    damping: T,
) -> (SMatrix<T, N, 6>, T::SimdBool) {
    // L's lower triangle, from A = J Jᵀ + λ² I (only A's lower triangle is read).
    let mut l = [[T::zero(); 6]; 6];
    let lambda2 = damping * damping;
    for r in 0..6 {
        for c in 0..=r {
            let mut sum = T::zero();
            for k in 0..N {
                sum += j[(r, k)] * j[(c, k)];
            }
            l[r][c] = if r == c { sum + lambda2 } else { sum };
        }
    }
    let mut failed = no_lane::<T>();
    for c in 0..6 {
        for k in 0..c {
            let f = l[c][k];
            for row in l.iter_mut().skip(c) {
                row[c] -= f * row[k];
            }
        }
        let pivot_root = l[c][c].simd_sqrt();
        // √pivot > 0 exactly when the pivot is positive (NaN and 0 fail).
        failed = failed | !pivot_root.simd_gt(T::zero());
        l[c][c] = pivot_root;
        for row in l.iter_mut().skip(c + 1) {
            row[c] /= pivot_root;
        }
    }
    // (J Jᵀ + λ² I)⁻¹ J column by column: J⁺ᵀ, as L Lᵀ x = J's column.
    let mut pinv = zeros::<T, N, 6>();
    for k in 0..N {
        let mut b: [T; 6] = std::array::from_fn(|i| j[(i, k)]);
        for i in 0..6 {
            let coeff = b[i] / l[i][i];
            b[i] = coeff;
            for r in i + 1..6 {
                b[r] -= coeff * l[r][i];
            }
        }
        for i in (0..6).rev() {
            let mut dot = T::zero();
            for r in i + 1..6 {
                dot += l[r][i] * b[r];
            }
            b[i] = (b[i] - dot) / l[i][i];
            failed = failed | !finite(b[i]);
            pinv[(k, i)] = b[i];
        }
    }
    (pinv, failed)
}

/// The terms of the general task (SPEC §11) at one state: the 6×N task Jacobian J (rows
/// 0–2 linear, 3–5 angular, zero for a position task, which the damped J⁺ then ignores),
/// the task command V and J̇q̇, J⁺, and the null-space posture term a_n.
#[derive(Debug, Clone, Copy)]
pub(crate) struct TaskTerms<T: Real, const N: usize> {
    jacobian: SMatrix<T, 6, N>,
    command: SVector<T, 6>,
    jdot_qd: SVector<T, 6>,
    pinv: SMatrix<T, N, 6>,
    null: SVector<T, N>,
}

/// What the general task reads besides the kinematics and V of eq. (39): the measured
/// joint state, a pose task's orientation with its (K_P, K_D), the posture q0 of a
/// redundant arm, K_A, the posture's (K_P, K_D) and J⁺'s damping λ.
#[derive(Debug, Clone, Copy)]
pub(crate) struct TaskInputs<'a, T: Real, const N: usize> {
    pub q: &'a SVector<T, N>,
    pub qd: &'a SVector<T, N>,
    pub orientation: Option<(&'a OrientationTask<N, T>, (T, T))>,
    pub posture: Option<&'a SVector<T, N>>,
    pub gains: (T, T, T),
    pub damping: T,
}

impl<T: Real, const N: usize> TaskTerms<T, N> {
    /// The task's J, V, J̇q̇, J⁺ and a_n = (I − J⁺J) K_A⁻¹ (K_P (q0 − q) − K_D q̇), with the
    /// lanes where J⁺ failed (`damped_pseudo_inverse`).
    #[inline(always)]
    pub(crate) fn new(
        k: &Kinematics<N, T>,
        v_position: &Vector3<T>,
        input: &TaskInputs<T, N>,
    ) -> (Self, T::SimdBool) {
        let (ka, kd, kp) = input.gains;
        let mut j = zeros::<T, 6, N>();
        let mut v = zeros::<T, 6, 1>();
        let mut jdot_qd = zeros::<T, 6, 1>();
        j.fixed_rows_mut::<3>(0).copy_from(&k.jacobian);
        v.fixed_rows_mut::<3>(0).copy_from(v_position);
        jdot_qd.fixed_rows_mut::<3>(0).copy_from(&k.jdot_qd);
        if let Some((o, (kp_o, kd_o))) = input.orientation {
            // eq. (39) for the orientation, held at R0: no feed-forward, Ẋ_d = 0.
            let omega = mat_vec(&o.jacobian, input.qd);
            let v_o = (o.error * kp_o - omega * kd_o) / ka;
            j.fixed_rows_mut::<3>(3).copy_from(&o.jacobian);
            v.fixed_rows_mut::<3>(3).copy_from(&v_o);
            jdot_qd.fixed_rows_mut::<3>(3).copy_from(&o.jdot_qd);
        }
        let (pinv, failed) = damped_pseudo_inverse(&j, input.damping);
        let null = match input.posture {
            Some(q0) => {
                // (I − J⁺J) w as w − J⁺ (J w): two products with vectors, no N×N matrix.
                let w = ((q0 - input.q) * kp - input.qd * kd) / ka;
                w - mat_vec(&pinv, &mat_vec(&j, &w))
            }
            None => zeros::<T, N, 1>(),
        };
        let terms = Self {
            jacobian: j,
            command: v,
            jdot_qd,
            pinv,
            null,
        };
        (terms, failed)
    }

    /// J⁺ (V − J̇q̇) + a_n: eqs. 7 and 17's joint acceleration.
    #[inline(always)]
    fn inverse(&self) -> SVector<T, N> {
        mat_vec(&self.pinv, &(self.command - self.jdot_qd)) + self.null
    }

    /// K_t Jᵀ V + a_n: eq. 18's.
    #[inline(always)]
    fn transpose(&self, torque_constant: T) -> SVector<T, N> {
        mat_t_vec(&self.jacobian, &self.command) * torque_constant + self.null
    }

    /// Eq. (7) over the task: τ = D̂ (J⁺ (V − J̇q̇) + a_n) + Ĉ + Ĝ + τ̂_f, plus the measured
    /// contact force's f J_xᵀ n when compensated (`linear`: the 3×N position Jacobian).
    #[inline(always)]
    pub(crate) fn computed_torque(
        &self,
        (d, friction): (Dynamics<N, T>, SVector<T, N>),
        linear: &SMatrix<T, 3, N>,
        compensation: Option<(&Vector3<T>, T)>,
    ) -> SVector<T, N> {
        let mut tau = mat_vec(&d.inertia, &self.inverse()) + d.coriolis + d.gravity + friction;
        if let Some((normal, force)) = compensation {
            tau += mat_t_vec(linear, normal) * force;
        }
        tau
    }

    /// Model-free control over the task: τ = D̄ (K_t Jᵀ V + a_n).
    #[inline(always)]
    pub(crate) fn model_free(&self, dbar: &SMatrix<T, N, N>, torque_constant: T) -> SVector<T, N> {
        mat_vec(dbar, &self.transpose(torque_constant))
    }

    /// TDC over the task, eq. (18) or eq. (17) times D̄, plus ĥ = τ_{k−1} − D̄ q̈_{k−1}
    /// (`started`: the lanes that have a q̇_{k−1}; q̈_{−1} = 0).
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    pub(crate) fn time_delay(
        &self,
        qd: &SVector<T, N>,
        dbar: &SMatrix<T, N, N>,
        (torque_constant, period): (T, T),
        law: TdcLaw,
        tau_prev: &SVector<T, N>,
        qd_prev: &SVector<T, N>,
        started: T::SimdBool,
    ) -> SVector<T, N> {
        let qdd_prev = last_acceleration(qd, qd_prev, period, started);
        let h_hat = tau_prev - mat_vec(dbar, &qdd_prev);
        let u = match law {
            TdcLaw::JacobianTranspose => mat_vec(dbar, &self.transpose(torque_constant)),
            TdcLaw::InverseJacobian => mat_vec(dbar, &self.inverse()),
        };
        u + h_hat
    }
}

/// q̈_{k−1} = (q̇_k − q̇_{k−1})/T in the `started` lanes, 0 in the others (q̈_{−1} = 0),
/// element by element: the same bits as nalgebra's vector ops, written out because the
/// closure holding them stayed out of line in the AVX-512 lane build.
#[inline(always)]
fn last_acceleration<T: Real, const N: usize>(
    qd: &SVector<T, N>,
    qd_prev: &SVector<T, N>,
    period: T,
    started: T::SimdBool,
) -> SVector<T, N> {
    let mut qdd = zeros::<T, N, 1>();
    if !T::none(started) {
        for i in 0..N {
            qdd[i] = ((qd[i] - qd_prev[i]) / period).select(started, T::zero());
        }
    }
    qdd
}

/// Why a control law could not produce a torque.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ControlFailure {
    SingularJacobian,
}

/// det J relative to its Hadamard bound (the product of the column norms) below which the
/// Jacobian counts as singular: J⁻¹ would amplify rounding beyond any use.
const SINGULAR_RATIO: f64 = 1e-9;

/// Damping λ of the pseudo-inverse J⁺ = Jᵀ (J Jᵀ + λ² I)⁻¹ (SPEC §11's default).
pub const PSEUDO_INVERSE_DAMPING: f64 = 1e-3;

/// Joint accelerations for a task acceleration (eqs. 7 and 17): J⁻¹ rhs for a square
/// Jacobian (three joints, position task, as the paper writes it); the damped
/// pseudo-inverse Jᵀ (J Jᵀ + λ² I)⁻¹ rhs of SPEC §11 for any other joint count. (The
/// controller calls `solve_square` and `damped_pseudo_inverse` directly; this keeps both
/// reachable for the tests.)
#[cfg(test)]
fn solve_jacobian<const N: usize>(
    j: &SMatrix<f64, 3, N>,
    rhs: &TaskVector,
) -> std::result::Result<JointVector<N>, ControlFailure> {
    if N != 3 {
        let damped = j * j.transpose() + Matrix3::identity() * PSEUDO_INVERSE_DAMPING.powi(2);
        return damped
            .try_inverse()
            .map(|inv| j.transpose() * (inv * rhs))
            .filter(|qdd| qdd.iter().all(|v| v.is_finite()))
            .ok_or(ControlFailure::SingularJacobian);
    }
    let (x, singular) = solve_square(j, rhs);
    if singular {
        return Err(ControlFailure::SingularJacobian);
    }
    Ok(x)
}

/// J⁻¹ rhs for the square 3×3 Jacobian of a three-joint position task (eqs. 7 and 17), with
/// the lanes where J counts as singular: |det J| at most `SINGULAR_RATIO` times its Hadamard
/// bound, NaN or exactly 0. The inverse is nalgebra's 3×3 cofactor formula written out
/// over any scalar (the same operations, so the same bits for `f64`; tested).
#[inline(always)]
pub(crate) fn solve_square<T: Real, const N: usize>(
    j: &SMatrix<T, 3, N>,
    rhs: &Vector3<T>,
) -> (SVector<T, N>, T::SimdBool) {
    let j: Matrix3<T> = j.fixed_view::<3, 3>(0, 0).into_owned();
    let bound = j.column(0).norm() * j.column(1).norm() * j.column(2).norm();
    let (m11, m12, m13) = (j[(0, 0)], j[(0, 1)], j[(0, 2)]);
    let (m21, m22, m23) = (j[(1, 0)], j[(1, 1)], j[(1, 2)]);
    let (m31, m32, m33) = (j[(2, 0)], j[(2, 1)], j[(2, 2)]);
    let minor_m12_m23 = m22 * m33 - m32 * m23;
    let minor_m11_m23 = m21 * m33 - m31 * m23;
    let minor_m11_m22 = m21 * m32 - m31 * m22;
    let signed = m11 * minor_m12_m23 - m12 * minor_m11_m23 + m13 * minor_m11_m22;
    let det = signed.simd_abs();
    let zero = T::zero();
    let singular =
        det.simd_ne(det) | det.simd_le(T::splat(SINGULAR_RATIO) * bound) | signed.simd_eq(zero);
    if T::all(singular) {
        return (zeros(), singular);
    }
    #[rustfmt::skip]
    let inv = Matrix3::new(
        minor_m12_m23 / signed, (m13 * m32 - m33 * m12) / signed, (m12 * m23 - m22 * m13) / signed,
        -minor_m11_m23 / signed, (m11 * m33 - m31 * m13) / signed, (m13 * m21 - m23 * m11) / signed,
        minor_m11_m22 / signed, (m12 * m31 - m32 * m11) / signed, (m11 * m22 - m21 * m12) / signed,
    );
    let x = mat_vec(&inv, rhs);
    (SVector::<T, N>::from_fn(|i, _| x[i]), singular)
}

/// Eq. (7) mapped to joint space with eq. (4): τ = D̂ J⁻¹ (V − J̇q̇) + Ĉ + Ĝ + τ̂_f, plus
/// f Jᵀ n when the measured contact force is compensated. `model` gives the controller
/// model's (D̂, Ĉ, Ĝ) and τ̂_f at the measured state. Returns τ and the singular lanes.
#[inline(always)]
pub(crate) fn computed_torque<T: Real, const N: usize>(
    k: &Kinematics<N, T>,
    v: &Vector3<T>,
    model: impl FnOnce() -> (Dynamics<N, T>, SVector<T, N>),
    compensation: Option<(&Vector3<T>, T)>,
) -> (SVector<T, N>, T::SimdBool) {
    let (qdd, singular) = solve_square(&k.jacobian, &(v - k.jdot_qd));
    if T::all(singular) {
        return (qdd, singular);
    }
    let (d, friction) = model();
    let mut tau = mat_vec(&d.inertia, &qdd) + d.coriolis + d.gravity + friction;
    if let Some((normal, force)) = compensation {
        // The plant feels Jᵀ(−f n); add it back.
        tau += mat_t_vec(&k.jacobian, normal) * force;
    }
    (tau, singular)
}

/// Model-free control, eq. (18) without the delay estimate: τ = D̄ K_t Jᵀ V (D̄ = α I).
#[inline(always)]
pub(crate) fn model_free<T: Real, const N: usize>(
    k: &Kinematics<N, T>,
    v: &Vector3<T>,
    inertia: T,
    torque_constant: T,
) -> SVector<T, N> {
    mat_t_vec(&k.jacobian, v) * (inertia * torque_constant)
}

/// Time-delayed control, eq. (18) or eq. (17) (D̄ = α I), with the memory τ_{k−1} and
/// q̇_{k−1} (`started`: the lanes that have a q̇_{k−1}). Returns τ_k and the singular lanes;
/// the caller stores τ_k and q̇_k as the next memory.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
pub(crate) fn time_delay<T: Real, const N: usize>(
    k: &Kinematics<N, T>,
    v: &Vector3<T>,
    qd: &SVector<T, N>,
    (inertia, torque_constant, period): (T, T, T),
    law: TdcLaw,
    tau_prev: &SVector<T, N>,
    qd_prev: &SVector<T, N>,
    started: T::SimdBool,
) -> (SVector<T, N>, T::SimdBool) {
    // eq. (14): ĥ ≈ τ_{k−1} − D̄ q̈_{k−1}, with q̈_{k−1} = (q̇_k − q̇_{k−1})/T, q̈_{−1} = 0.
    let qdd_prev = last_acceleration(qd, qd_prev, period, started);
    let h_hat = tau_prev - qdd_prev * inertia;
    let (u, singular) = match law {
        TdcLaw::JacobianTranspose => (
            mat_t_vec(&k.jacobian, v) * (inertia * torque_constant),
            no_lane::<T>(),
        ),
        TdcLaw::InverseJacobian => {
            let (qdd, singular) = solve_square(&k.jacobian, &(v - k.jdot_qd));
            (qdd * inertia, singular)
        }
    };
    (u + h_hat, singular)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::robot::three_link::{Kinematics, Vec3};
    use crate::robot::{ArmModel, Jacobian, JointMatrix, RobotModel, RobotParams, ThreeLinkArm};
    use crate::scalar::{lane_of, F64x4};
    use simba::simd::SimdValue;

    const X: TaskVector = TaskVector::new(1.0, 0.0, 0.0);

    fn at_q0() -> (ThreeLinkArm, Vec3, Kinematics) {
        let arm = ThreeLinkArm::new(&RobotParams::default());
        let q = arm.initial_position();
        let k = arm
            .model()
            .kinematics(&arm.model().configure(&q), &Vec3::zeros());
        (arm, q, k)
    }

    /// For a redundant arm (3×4 J) the damped pseudo-inverse reaches the task acceleration
    /// (to λ²) with the least-norm joint acceleration: it lies in J's row space.
    #[test]
    fn redundant_jacobian_uses_the_damped_pseudo_inverse() {
        #[rustfmt::skip]
        let j = Jacobian::<4>::new(
            0.3, -0.2, 0.5, 0.1,
            0.0, 0.7, 0.2, -0.4,
            0.6, 0.1, -0.3, 0.2,
        );
        let rhs = TaskVector::new(1.0, -2.0, 0.5);
        let qdd = solve_jacobian(&j, &rhs).unwrap();
        assert!((j * qdd - rhs).norm() < 1e-5, "{}", (j * qdd - rhs).norm());
        // Least norm: qdd = Jᵀ y for some y, so its part in J's null space is zero.
        let pinv = j.pseudo_inverse(1e-12).unwrap();
        let null_projector = nalgebra::Matrix4::identity() - pinv * j;
        assert!((null_projector * qdd).norm() < 1e-5);
        // A rank-deficient J still gives a finite answer (the damping's purpose).
        let flat = Jacobian::<4>::from_rows(&[
            j.row(0).into_owned(),
            j.row(0).into_owned(),
            j.row(2).into_owned(),
        ]);
        assert!(solve_jacobian(&flat, &rhs)
            .unwrap()
            .iter()
            .all(|v| v.is_finite()));
    }

    /// The square solve is nalgebra's determinant and 3×3 inverse, bit for bit.
    #[test]
    fn square_solve_is_nalgebras_inverse() {
        let (r, _, _) = at_q0();
        for i in 0..50 {
            let q = Vec3::new(
                0.1 * i as f64,
                0.3 + 0.02 * i as f64,
                -0.7 + 0.05 * i as f64,
            );
            let k = r
                .model()
                .kinematics(&r.model().configure(&q), &Vec3::zeros());
            let rhs = Vec3::new(1.0, -2.0 + i as f64, 0.5);
            let (x, singular) = solve_square(&k.jacobian, &rhs);
            if singular {
                continue;
            }
            let expected = k.jacobian.try_inverse().unwrap() * rhs;
            assert_eq!(x, expected, "q = {q:?}");
            assert!(k.jacobian.determinant().abs() > 0.0);
        }
    }

    /// The three laws over four lanes (their own kinematics, gains and memory) give four
    /// scalar laws' torques bit for bit, and the singular lane is reported in its lane.
    #[test]
    fn laws_in_lanes_equal_four_scalar_laws() {
        use crate::scalar::{lane, lane_of, mask_from, pack_vector};
        use simba::simd::SimdValue;
        let (r, _, _) = at_q0();
        let qs: [Vec3; 4] = [
            Vec3::new(0.0, 0.8, -0.8),
            Vec3::new(0.2, 0.5, -1.1),
            Vec3::new(0.0, 0.3, 0.0), // singular (q3 = 0)
            Vec3::new(-0.1, 0.9, -0.4),
        ];
        let qds: [Vec3; 4] = std::array::from_fn(|i| Vec3::new(0.01 * i as f64, -0.2, 0.3));
        let prev: [Vec3; 4] =
            std::array::from_fn(|i| Vec3::new(0.0, -0.21, 0.3 + 0.001 * i as f64));
        let kins: [Kinematics; 4] =
            std::array::from_fn(|i| r.model().kinematics(&r.model().configure(&qs[i]), &qds[i]));
        let vs: [Vec3; 4] = std::array::from_fn(|i| Vec3::new(1.0 + i as f64, -0.5, 0.25));
        let kin = crate::robot::Kinematics::<3, F64x4> {
            position: pack_vector(kins.each_ref().map(|k| &k.position)),
            jacobian: pack_vector(kins.each_ref().map(|k| &k.jacobian)),
            jdot_qd: pack_vector(kins.each_ref().map(|k| &k.jdot_qd)),
        };
        let v = pack_vector(vs.each_ref());
        let qd = pack_vector(qds.each_ref());
        let lanes4 = |f: fn(usize) -> f64| F64x4::from_lanes(f);
        // Model-free.
        let mf = model_free(
            &kin,
            &v,
            lanes4(|i| 0.1 + 0.01 * i as f64),
            lanes4(|i| 200.0 - i as f64),
        );
        for i in 0..4 {
            let e: Vec3 = model_free(&kins[i], &vs[i], 0.1 + 0.01 * i as f64, 200.0 - i as f64);
            assert_eq!(lane_of(&mf, i), e);
        }
        // TDC, both laws; lane 0 has no q̇_{k−1} yet.
        for law in [TdcLaw::JacobianTranspose, TdcLaw::InverseJacobian] {
            let started = mask_from::<F64x4>(|i| i != 0);
            let taus: [Vec3; 4] = std::array::from_fn(|i| Vec3::new(1.0, 50.0 + i as f64, 9.0));
            let (tau, singular) = time_delay(
                &kin,
                &v,
                &qd,
                (
                    lanes4(|i| 0.1 * (1 + i) as f64),
                    lanes4(|_| 200.0),
                    lanes4(|_| 1e-3),
                ),
                law,
                &pack_vector(taus.each_ref()),
                &pack_vector(prev.each_ref()),
                started,
            );
            for i in 0..4 {
                let (e, s): (Vec3, bool) = time_delay(
                    &kins[i],
                    &vs[i],
                    &qds[i],
                    (0.1 * (1 + i) as f64, 200.0, 1e-3),
                    law,
                    &taus[i],
                    &prev[i],
                    i != 0,
                );
                assert_eq!(singular.extract(i), s);
                if !s {
                    assert_eq!(lane_of(&tau, i), e, "{law:?} lane {i}");
                }
            }
            assert_eq!(singular.extract(2), law == TdcLaw::InverseJacobian);
        }
        // Computed torque with each lane's model terms (fixed here: no exp), compensated.
        let dyns: [crate::robot::Dynamics<3>; 4] =
            std::array::from_fn(|i| r.model().dynamics(&r.model().configure(&qs[i]), &qds[i]));
        let fr: [Vec3; 4] = std::array::from_fn(|i| Vec3::new(1.0, 2.0, 3.0 + i as f64));
        let n = pack_vector([&X; 4]);
        let force = lanes4(|i| 5.0 * i as f64);
        let (tau, singular) = computed_torque(
            &kin,
            &v,
            || {
                (
                    crate::robot::Dynamics {
                        inertia: pack_vector(dyns.each_ref().map(|d| &d.inertia)),
                        coriolis: pack_vector(dyns.each_ref().map(|d| &d.coriolis)),
                        gravity: pack_vector(dyns.each_ref().map(|d| &d.gravity)),
                    },
                    pack_vector(fr.each_ref()),
                )
            },
            Some((&n, force)),
        );
        for i in 0..4 {
            let (e, s): (Vec3, bool) = computed_torque(
                &kins[i],
                &vs[i],
                || (dyns[i], fr[i]),
                Some((&X, lane(force, i))),
            );
            assert_eq!(singular.extract(i), s);
            assert_eq!(s, i == 2);
            if !s {
                assert_eq!(lane_of(&tau, i), e);
            }
        }
    }

    /// A few deterministic numbers in [−1, 1) (a linear congruential generator).
    fn numbers(seed: u64) -> impl FnMut() -> f64 {
        let mut x = seed;
        move || {
            x = x
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (x >> 11) as f64 / (1u64 << 52) as f64 - 1.0
        }
    }

    /// The written-out J⁺ gives nalgebra's `cholesky()` and `solve` bits and fails exactly
    /// where `cholesky()` returns `None`, one run or four lanes.
    #[test]
    fn damped_pseudo_inverse_is_nalgebras_cholesky() {
        use crate::scalar::pack_vector;
        use nalgebra::Matrix6;
        let reference = |j: &SMatrix<f64, 6, 7>, lambda: f64| {
            let a = j * j.transpose() + Matrix6::identity() * (lambda * lambda);
            let pinv = a.cholesky()?.solve(j).transpose();
            pinv.iter().all(|v| v.is_finite()).then_some(pinv)
        };
        let mut next = numbers(7);
        let (mut ok, mut failed_cases) = (0, 0);
        for case in 0..64 {
            let cases: [(SMatrix<f64, 6, 7>, f64); 4] = std::array::from_fn(|l| {
                let mut j = SMatrix::<f64, 6, 7>::from_fn(|_, _| next());
                let lambda = [1e-3, 0.1, 0.0, 1e-3][l];
                if (case + l) % 3 == 0 {
                    // A position task: the angular rows are zero (λ = 0: a zero pivot).
                    j.fixed_rows_mut::<3>(3).fill(0.0);
                }
                if case % 11 == l {
                    j[(1, 2)] = f64::NAN;
                }
                (j, lambda)
            });
            let lanes = damped_pseudo_inverse(
                &pack_vector(cases.each_ref().map(|c| &c.0)),
                F64x4::from_lanes(|l| cases[l].1),
            );
            for (l, (j, lambda)) in cases.iter().enumerate() {
                let (pinv, failed) = damped_pseudo_inverse(j, *lambda);
                assert_eq!(lanes.1.extract(l), failed);
                match reference(j, *lambda) {
                    Some(expected) => {
                        assert!(!failed);
                        assert_eq!(pinv, expected);
                        assert_eq!(lane_of(&lanes.0, l), expected);
                        ok += 1;
                    }
                    None => {
                        assert!(failed, "case {case} lane {l}");
                        failed_cases += 1;
                    }
                }
            }
        }
        assert!(
            ok > 100 && failed_cases > 20,
            "{ok} solved, {failed_cases} failed"
        );
    }

    /// The general task law (SPEC §11) over four lanes (each with its own state, orientation,
    /// posture, gains, λ, D̄ and memory) gives four scalar calls' torques, and a lane whose
    /// J⁺ fails (zero angular rows with λ = 0) is reported in its lane only.
    #[test]
    fn task_law_in_lanes_equals_four_scalar_calls() {
        use crate::robot::chain::arm::rotation_vector;
        use crate::robot::chain::{UrdfArm, UrdfArmParams};
        use crate::scalar::{mask_from, pack_vector};
        let arm = UrdfArm::<7>::new(&UrdfArmParams {
            urdf: include_str!("../../../examples/data/panda.urdf").to_owned(),
            tip_link: "panda_hand_tcp".to_owned(),
            ..UrdfArmParams::default()
        })
        .unwrap();
        let mut next = numbers(11);
        let q0 = arm.initial_position();
        let qs: [SVector<f64, 7>; 4] =
            std::array::from_fn(|_| q0 + SVector::<f64, 7>::from_fn(|_, _| 0.4 * next()));
        let qds: [SVector<f64, 7>; 4] =
            std::array::from_fn(|_| SVector::<f64, 7>::from_fn(|_, _| next()));
        let prev: [SVector<f64, 7>; 4] = std::array::from_fn(|l| qds[l] * 0.99);
        let taus: [SVector<f64, 7>; 4] =
            std::array::from_fn(|_| SVector::<f64, 7>::from_fn(|_, _| 10.0 * next()));
        let r0 = nalgebra::Rotation3::from_scaled_axis(Vector3::new(0.1, -0.2, 0.3)).into_inner();
        let kins: [crate::robot::Kinematics<7>; 4] = std::array::from_fn(|l| {
            arm.model()
                .kinematics(&arm.model().configure(&qs[l]), &qds[l])
        });
        let orientations: [OrientationTask<7>; 4] = std::array::from_fn(|l| {
            let o = arm
                .model()
                .orientation(&arm.model().configure(&qs[l]), &qds[l])
                .unwrap();
            let jacobian = if l == 2 {
                Jacobian::zeros()
            } else {
                o.jacobian
            };
            OrientationTask {
                error: rotation_vector(&(r0 * o.rotation.transpose())),
                jacobian,
                jdot_qd: o.jdot_qd,
            }
        });
        let vs: [Vector3<f64>; 4] = std::array::from_fn(|_| Vector3::from_fn(|_, _| next()));
        let gains: [(f64, f64, f64); 4] = std::array::from_fn(|l| (5.0, 20.0 + l as f64, 100.0));
        let orientation_gains: [(f64, f64); 4] = std::array::from_fn(|l| (80.0 + l as f64, 15.0));
        let damping: [f64; 4] = [1e-3, 2e-3, 0.0, 1e-2];
        let dbars: [JointMatrix<7>; 4] = std::array::from_fn(|l| {
            let a = JointMatrix::<7>::from_fn(|_, _| 0.1 * next());
            a * a.transpose() + JointMatrix::<7>::identity() * (0.05 * (1 + l) as f64)
        });
        let dyns: [Dynamics<7>; 4] = std::array::from_fn(|l| {
            arm.model()
                .dynamics(&arm.model().configure(&qs[l]), &qds[l])
        });
        let frictions: [SVector<f64, 7>; 4] = std::array::from_fn(|l| taus[l] * 0.01);
        let normal = Vector3::new(1.0, 0.0, 0.0);
        let force = F64x4::from_lanes(|l| 3.0 * l as f64);
        let started = mask_from::<F64x4>(|l| l != 1);
        let four = |f: &dyn Fn(usize) -> f64| F64x4::from_lanes(f);

        let kin = crate::robot::Kinematics::<7, F64x4> {
            position: pack_vector(kins.each_ref().map(|k| &k.position)),
            jacobian: pack_vector(kins.each_ref().map(|k| &k.jacobian)),
            jdot_qd: pack_vector(kins.each_ref().map(|k| &k.jdot_qd)),
        };
        let orientation = OrientationTask::<7, F64x4> {
            error: pack_vector(orientations.each_ref().map(|o| &o.error)),
            jacobian: pack_vector(orientations.each_ref().map(|o| &o.jacobian)),
            jdot_qd: pack_vector(orientations.each_ref().map(|o| &o.jdot_qd)),
        };
        let (q, qd) = (pack_vector(qs.each_ref()), pack_vector(qds.each_ref()));
        let posture = pack_vector([&q0; 4]);
        let input = TaskInputs {
            q: &q,
            qd: &qd,
            orientation: Some((
                &orientation,
                (
                    four(&|l| orientation_gains[l].0),
                    four(&|l| orientation_gains[l].1),
                ),
            )),
            posture: Some(&posture),
            gains: (
                four(&|l| gains[l].0),
                four(&|l| gains[l].1),
                four(&|l| gains[l].2),
            ),
            damping: four(&|l| damping[l]),
        };
        let (terms, failed) = TaskTerms::new(&kin, &pack_vector(vs.each_ref()), &input);
        let dbar = pack_vector(dbars.each_ref());
        let kt = four(&|l| 150.0 + l as f64);
        let model_free = terms.model_free(&dbar, kt);
        let tdc = [TdcLaw::JacobianTranspose, TdcLaw::InverseJacobian].map(|law| {
            terms.time_delay(
                &qd,
                &dbar,
                (kt, four(&|_| 1e-3)),
                law,
                &pack_vector(taus.each_ref()),
                &pack_vector(prev.each_ref()),
                started,
            )
        });
        let computed = terms.computed_torque(
            (
                Dynamics {
                    inertia: pack_vector(dyns.each_ref().map(|d| &d.inertia)),
                    coriolis: pack_vector(dyns.each_ref().map(|d| &d.coriolis)),
                    gravity: pack_vector(dyns.each_ref().map(|d| &d.gravity)),
                },
                pack_vector(frictions.each_ref()),
            ),
            &kin.jacobian,
            Some((&pack_vector([&normal; 4]), force)),
        );
        let close = |a: &SVector<f64, 7>, b: &SVector<f64, 7>| {
            (a - b).abs().max() <= 1e-12 * b.abs().max().max(1e-300)
        };
        for l in 0..4 {
            let input = TaskInputs {
                q: &qs[l],
                qd: &qds[l],
                orientation: Some((&orientations[l], orientation_gains[l])),
                posture: Some(&q0),
                gains: gains[l],
                damping: damping[l],
            };
            let (e, f) = TaskTerms::new(&kins[l], &vs[l], &input);
            assert_eq!(failed.extract(l), f);
            assert_eq!(f, l == 2, "lane {l}");
            if f {
                continue;
            }
            let kt = 150.0 + l as f64;
            assert!(close(
                &lane_of(&model_free, l),
                &e.model_free(&dbars[l], kt)
            ));
            for (i, law) in [TdcLaw::JacobianTranspose, TdcLaw::InverseJacobian]
                .into_iter()
                .enumerate()
            {
                let expected = e.time_delay(
                    &qds[l],
                    &dbars[l],
                    (kt, 1e-3),
                    law,
                    &taus[l],
                    &prev[l],
                    l != 1,
                );
                assert!(close(&lane_of(&tdc[i], l), &expected), "{law:?} lane {l}");
            }
            let expected = e.computed_torque(
                (dyns[l], frictions[l]),
                &kins[l].jacobian,
                Some((&normal, 3.0 * l as f64)),
            );
            assert!(close(&lane_of(&computed, l), &expected), "CT lane {l}");
        }
    }

    /// The rotation vector inverts nalgebra's exponential map (`from_scaled_axis`) to
    /// 1e-15 relative, down to 1e-12 rad and up to 3 rad, with no rotation giving exactly
    /// zero; its lanes are the scalar's bits.
    #[test]
    fn rotation_vector_inverts_the_exponential_map() {
        use crate::robot::chain::arm::rotation_vector;
        use crate::scalar::pack_vector;
        let mut next = numbers(3);
        for case in 0..50 {
            let axes: [Vector3<f64>; 4] = std::array::from_fn(|l| {
                let scale = [1.0, 1e-3, 1e-9, 1.7][l] * if case % 5 == 0 { 1e-3 } else { 1.0 };
                if case % 7 == l {
                    Vector3::zeros()
                } else {
                    Vector3::from_fn(|_, _| scale * next())
                }
            });
            let rs = axes.map(|a| nalgebra::Rotation3::from_scaled_axis(a).into_inner());
            let lanes = rotation_vector(&pack_vector::<F64x4, 4, 3, 3>(rs.each_ref()));
            for (l, r) in rs.iter().enumerate() {
                let got = rotation_vector(r);
                let err = (got - axes[l]).norm();
                assert!(err <= 1e-15 * axes[l].norm().max(1e-300) + 1e-30, "{err:e}");
                assert_eq!(lane_of(&lanes, l), got);
            }
        }
    }

    /// Near the identity, rounding puts (tr R − 1)/2 above 1: acos (nalgebra's
    /// `scaled_axis`) gives NaN there; the log map stays finite and tiny.
    #[test]
    fn rotation_vector_near_the_identity_is_finite() {
        use crate::robot::chain::arm::rotation_vector;
        let mut r = Matrix3::<f64>::identity();
        r[(0, 0)] += 4.0 * f64::EPSILON;
        r[(1, 0)] = 3e-16;
        let scaled = nalgebra::Rotation3::from_matrix_unchecked(r).scaled_axis();
        assert!(
            scaled.iter().any(|v| v.is_nan()),
            "acos's failure is reproduced"
        );
        let v = rotation_vector(&r);
        assert!(v.iter().all(|x| x.is_finite()) && v.norm() < 1e-15, "{v}");
    }
}
