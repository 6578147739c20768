//! Forward kinematics, the tip Jacobian and J̇q̇ of a [`SerialChain`].
//!
//! Joint i moves body i relative to body i−1: the joint frame `tree` (at q = 0) followed by a
//! rotation about (revolute) or a translation along (prismatic) the unit axis s_i. Its motion
//! subspace in body coordinates is S_i = [s_i; 0] or [0; s_i] (Featherstone Table 4.1).

use nalgebra::{SMatrix, SVector, Vector3};

use super::model::{JointKind, SerialChain};
use super::spatial::{mul3tv, mul3v, turn, Pose, Real, SVec};
use crate::scalar::{cross, zeros};

/// The frames of one configuration: each body in its parent (`up`) and in the base
/// (`world`), and the tip in the base.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Frames<T: Real, const N: usize> {
    pub up: [Pose<T>; N],
    pub world: [Pose<T>; N],
    pub tip: Pose<T>,
}

impl<T: Real, const N: usize> SerialChain<T, N> {
    /// The motion subspace S_i in body coordinates.
    #[inline(always)]
    pub fn subspace(&self, i: usize) -> SVec<T> {
        let b = &self.bodies[i];
        match b.kind {
            JointKind::Revolute => SVec::new(b.axis, zeros()),
            JointKind::Prismatic => SVec::new(zeros(), b.axis),
        }
    }

    /// The frames at `q` (one sin/cos per revolute joint).
    #[inline(always)]
    pub fn frames(&self, q: &SVector<T, N>) -> Frames<T, N> {
        let mut f = Frames {
            up: [Pose::identity(); N],
            world: [Pose::identity(); N],
            tip: Pose::identity(),
        };
        self.frames_into(q, &mut f);
        f
    }

    /// [`Self::frames`] written into `f`. RK4 fills its buffers in place: a returned `Frames`
    /// was copied (5.8 KB per call in lanes, measured), and so were arrays built first and
    /// moved in.
    #[inline(always)]
    pub fn frames_into(&self, q: &SVector<T, N>, f: &mut Frames<T, N>) {
        let mut parent = Pose::identity();
        for i in 0..N {
            let b = &self.bodies[i];
            f.up[i] = match b.kind {
                JointKind::Revolute => Pose {
                    rot: turn(&b.tree.rot, &b.axis, q[i].sin_cos_fast()),
                    pos: b.tree.pos,
                },
                JointKind::Prismatic => Pose {
                    rot: b.tree.rot,
                    pos: b.tree.pos + mul3v(&b.tree.rot, &(b.axis * q[i])),
                },
            };
            parent = parent.compose(&f.up[i]);
            f.world[i] = parent;
        }
        f.tip = parent.compose(&self.tip);
    }

    /// The tip Jacobian (6×N, rows 0–2 linear, 3–5 angular, world-aligned at the tip origin)
    /// and J̇q̇, the classical acceleration [a; α] of the tip origin at q̈ = 0.
    ///
    /// Column i: revolute, [a_i × (p_tip − p_i); a_i]; prismatic, [a_i; 0], with a_i the
    /// joint axis in the world. Its rate follows from ȧ_i = ω_{i−1} × a_i and
    /// d/dt (p_tip − p_i) = v_tip − v_i (velocities by a forward recursion).
    #[inline(always)]
    pub fn jacobian(
        &self,
        f: &Frames<T, N>,
        qd: &SVector<T, N>,
    ) -> (SMatrix<T, 6, N>, SVector<T, 6>) {
        let p_tip = f.tip.pos;
        let mut j = zeros::<T, 6, N>();
        let mut jdot_qd = zeros::<T, 6, 1>();
        // Forward recursion of ω and the velocity of each body origin, in the world.
        let mut omega = zeros::<T, 3, 1>();
        let mut v_origin = zeros::<T, 3, 1>();
        let mut p_prev = zeros::<T, 3, 1>();
        let mut axes = [zeros::<T, 3, 1>(); N];
        let mut axis_rates = [zeros::<T, 3, 1>(); N];
        let mut origins_v = [zeros::<T, 3, 1>(); N];
        for i in 0..N {
            let b = &self.bodies[i];
            let p = f.world[i].pos;
            let a = mul3v(&f.world[i].rot, &b.axis);
            v_origin += cross(&omega, &(p - p_prev));
            axis_rates[i] = cross(&omega, &a);
            match b.kind {
                JointKind::Revolute => omega += a * qd[i],
                JointKind::Prismatic => v_origin += a * qd[i],
            }
            axes[i] = a;
            origins_v[i] = v_origin;
            p_prev = p;
        }
        let v_tip = v_origin + cross(&omega, &(p_tip - p_prev));
        for i in 0..N {
            let (a, adot) = (axes[i], axis_rates[i]);
            let (lin, ang, lin_rate, ang_rate) = match self.bodies[i].kind {
                JointKind::Revolute => {
                    let r = p_tip - f.world[i].pos;
                    (
                        cross(&a, &r),
                        a,
                        cross(&adot, &r) + cross(&a, &(v_tip - origins_v[i])),
                        adot,
                    )
                }
                JointKind::Prismatic => (a, zeros::<T, 3, 1>(), adot, zeros::<T, 3, 1>()),
            };
            for r in 0..3 {
                j[(r, i)] = lin[r];
                j[(r + 3, i)] = ang[r];
                jdot_qd[r] += lin_rate[r] * qd[i];
                jdot_qd[r + 3] += ang_rate[r] * qd[i];
            }
        }
        (j, jdot_qd)
    }

    /// The tip's linear velocity in the world (J_v q̇ without forming J).
    #[inline(always)]
    pub fn tip_velocity(&self, f: &Frames<T, N>, qd: &SVector<T, N>) -> Vector3<T> {
        let mut omega = zeros::<T, 3, 1>();
        let mut v = zeros::<T, 3, 1>();
        let mut p_prev = zeros::<T, 3, 1>();
        for i in 0..N {
            let b = &self.bodies[i];
            let p = f.world[i].pos;
            let a = mul3v(&f.world[i].rot, &b.axis);
            v += cross(&omega, &(p - p_prev));
            match b.kind {
                JointKind::Revolute => omega += a * qd[i],
                JointKind::Prismatic => v += a * qd[i],
            }
            p_prev = p;
        }
        v + cross(&omega, &(f.tip.pos - p_prev))
    }

    /// A world force `force` at the tip origin as a spatial force on body N, in its frame.
    #[inline(always)]
    pub fn tip_wrench(&self, f: &Frames<T, N>, force: &Vector3<T>) -> SVec<T> {
        let lin = mul3tv(&f.world[N - 1].rot, force);
        SVec::new(cross(&self.tip.pos, &lin), lin)
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::robot::chain::model::Body;
    use crate::robot::chain::spatial::{axis_angle, RigidInertia};
    use nalgebra::Matrix3;

    /// A small random-looking chain with tilted, mixed joints (deterministic numbers).
    pub fn chain4() -> SerialChain<f64, 4> {
        let mut seed = 12345u64;
        let mut r = move || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((seed >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
        };
        let bodies = std::array::from_fn(|i| {
            let axis = Vector3::new(r(), r(), r()).normalize();
            let rot = axis_angle(&Vector3::new(r(), r(), r()).normalize(), r().sin_cos());
            let a = Matrix3::new(r(), r(), r(), r(), r(), r(), r(), r(), r());
            let i_com = a * a.transpose() + Matrix3::identity() * 0.05;
            Body {
                kind: if i == 2 {
                    JointKind::Prismatic
                } else {
                    JointKind::Revolute
                },
                axis,
                tree: Pose {
                    rot,
                    pos: Vector3::new(r(), r(), r()) * 0.4,
                },
                inertia: RigidInertia::from_com(
                    1.0 + r().abs(),
                    Vector3::new(r(), r(), r()) * 0.2,
                    i_com,
                ),
            }
        });
        SerialChain {
            bodies,
            tip: Pose {
                rot: axis_angle(&Vector3::new(0.2, 0.9, -0.1).normalize(), 0.3f64.sin_cos()),
                pos: Vector3::new(0.1, -0.05, 0.3),
            },
            gravity: 9.81,
        }
    }

    pub fn state() -> (SVector<f64, 4>, SVector<f64, 4>) {
        (
            SVector::<f64, 4>::new(0.3, -0.7, 0.15, 1.1),
            SVector::<f64, 4>::new(0.5, -1.2, 0.3, 0.8),
        )
    }

    /// J is the derivative of the tip position and J̇q̇ that of J q̇, by central differences.
    #[test]
    fn jacobian_and_its_rate_are_derivatives() {
        let c = chain4();
        let (q, qd) = state();
        let (j, jdq) = c.jacobian(&c.frames(&q), &qd);
        let h = 1e-6;
        let fp = c.frames(&(q + qd * h));
        let fm = c.frames(&(q - qd * h));
        let v = (fp.tip.pos - fm.tip.pos) / (2.0 * h);
        let jv = j * qd;
        assert!((v - jv.fixed_rows::<3>(0)).norm() < 1e-8, "{v} {jv}");
        // Angular: R_dot R^T = [ω]×.
        let rdot = (fp.tip.rot - fm.tip.rot) / (2.0 * h);
        let w = rdot * c.frames(&q).tip.rot.transpose();
        let omega = Vector3::new(w[(2, 1)], w[(0, 2)], w[(1, 0)]);
        assert!((omega - jv.fixed_rows::<3>(3)).norm() < 1e-8);
        let (jp, _) = c.jacobian(&fp, &qd);
        let (jm, _) = c.jacobian(&fm, &qd);
        let rate = (jp * qd - jm * qd) / (2.0 * h);
        assert!((rate - jdq).norm() < 1e-7, "{rate} {jdq}");
        assert!((c.tip_velocity(&c.frames(&q), &qd) - jv.fixed_rows::<3>(0)).norm() < 1e-14);
    }
}
