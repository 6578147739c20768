//! Articulated-body algorithm (Featherstone Table 7.1): forward dynamics q̈ = FD(q, q̇, τ,
//! f_ext) in O(N), with a spatial force on the last body (the environment's push on the tip).

use nalgebra::SVector;

use super::kinematics::Frames;
use super::model::{JointKind, SerialChain};
use super::spatial::{mul3tv, mul3v, Real, SVec, SpatialInertia};
use crate::scalar::zeros;

impl<T: Real, const N: usize> SerialChain<T, N> {
    /// q̈ for joint torques `tau` (friction already subtracted) with `tip_wrench` acting on
    /// body N (its frame) and gravity along −z.
    ///
    /// Inertias are kept as 3×3 blocks ([`SpatialInertia`]) and S_i = [s; 0] (revolute) or
    /// [0; s] (prismatic) is applied by picking blocks, so no 6×6 product is formed.
    #[inline(always)]
    pub fn aba(
        &self,
        f: &Frames<T, N>,
        qd: &SVector<T, N>,
        tau: &SVector<T, N>,
        tip_wrench: &SVec<T>,
    ) -> SVector<T, N> {
        let mut pa = [SVec::<T>::zero(); N];
        let mut c = [SVec::<T>::zero(); N];
        let mut u_vec = [SVec::<T>::zero(); N];
        let mut d_inv = [T::zero(); N];
        let mut u = [T::zero(); N];
        // Pass 1: velocities, velocity-product accelerations c_i = v_i ×ₘ S_i q̇_i and the
        // bias forces p_i = v_i ×* I_i v_i − f_ext.
        let mut v = SVec::<T>::zero();
        for i in 0..N {
            let vj = self.subspace(i).scale(qd[i]);
            v = f.up[i].motion_to_child(&v).add(&vj);
            c[i] = v.cross_motion(&vj);
            let inertia = &self.bodies[i].inertia;
            let mut p = v.cross_force(&inertia.apply(&v));
            if i == N - 1 {
                p = p.sub(tip_wrench);
            }
            pa[i] = p;
        }
        // Pass 2: articulated inertias from the tip down. U_i = I^A_i S_i, d_i = S_iᵀ U_i,
        // u_i = τ_i − S_iᵀ p^A_i; the parent gets Xᵀ (I^A − U Uᵀ/d) X and
        // Xᵀ (p^A + I^a c_i + U u_i/d_i). Only the child's contribution is carried down
        // (no array of inertias: in lanes each is 27 vectors, and copies went to memcpy).
        let mut carried: Option<SpatialInertia<T>> = None;
        for i in (0..N).rev() {
            let axis = self.bodies[i].axis;
            let rigid = SpatialInertia::rigid(&self.bodies[i].inertia);
            let ia = match &carried {
                Some(child) => rigid.add(child),
                None => rigid,
            };
            let (ui, di, bias) = match self.bodies[i].kind {
                JointKind::Revolute => {
                    let ui = SVec::new(mul3v(&ia.a, &axis), mul3tv(&ia.b, &axis));
                    (ui, axis.dot(&ui.ang), axis.dot(&pa[i].ang))
                }
                JointKind::Prismatic => {
                    let ui = SVec::new(mul3v(&ia.b, &axis), mul3v(&ia.c, &axis));
                    (ui, axis.dot(&ui.lin), axis.dot(&pa[i].lin))
                }
            };
            let inv = T::one() / di;
            u[i] = tau[i] - bias;
            u_vec[i] = ui;
            d_inv[i] = inv;
            if i > 0 {
                let ia_a = ia.minus_outer(&ui, inv);
                let pa_a = pa[i].add(&ia_a.apply(&c[i])).add(&ui.scale(u[i] * inv));
                let up = &f.up[i];
                carried = Some(ia_a.to_parent(up));
                pa[i - 1] = pa[i - 1].add(&up.force_to_parent(&pa_a));
            }
        }
        // Pass 3: accelerations from the base up, a_0 = −a_g.
        let mut a = self.base_acceleration(true);
        let mut qdd = zeros::<T, N, 1>();
        for i in 0..N {
            let a_prime = f.up[i].motion_to_child(&a).add(&c[i]);
            qdd[i] = (u[i] - a_prime.dot(&u_vec[i])) * d_inv[i];
            a = a_prime.add(&self.subspace(i).scale(qdd[i]));
        }
        qdd
    }
}

#[cfg(test)]
mod tests {
    use crate::robot::chain::kinematics::tests::{chain4, state};
    use crate::robot::chain::spatial::SVec;
    use nalgebra::{SVector, Vector3};

    /// ABA inverts RNEA (with a tip wrench), and CRBA is RNEA's derivative in q̈.
    #[test]
    fn aba_rnea_crba_are_consistent() {
        let c = chain4();
        let (q, qd) = state();
        let f = c.frames(&q);
        let tau = SVector::<f64, 4>::new(1.5, -2.0, 3.0, 0.7);
        let w = c.tip_wrench(&f, &Vector3::new(3.0, -1.0, 2.0));
        let qdd = c.aba(&f, &qd, &tau, &w);
        let back = c.rnea(&f, &qd, &qdd, true, &w);
        assert!((back - tau).norm() < 1e-11, "{back} {tau}");
        let d = c.crba(&f);
        assert!((d - d.transpose()).norm() < 1e-14);
        let (cq, g) = c.bias(&f, &qd);
        let by_parts = d * qdd + cq + g
            - c.jacobian(&f, &qd).0.transpose()
                * nalgebra::Vector6::new(3.0, -1.0, 2.0, 0.0, 0.0, 0.0);
        assert!((by_parts - tau).norm() < 1e-11, "{by_parts} {tau}");
        // A wrench through the Jacobian: Jᵀ F equals what RNEA sees from the tip wrench.
        let zero = SVector::<f64, 4>::zeros();
        let free = c.rnea(&f, &zero, &zero, false, &SVec::zero());
        assert!(free.norm() == 0.0);
    }
}

#[cfg(test)]
mod lanes {
    use crate::robot::chain::kinematics::tests::{chain4, state};
    use crate::robot::chain::model::{Body, SerialChain};
    use crate::robot::chain::spatial::{Pose, RigidInertia, SVec};
    use crate::scalar::{F64x4, Real};
    use nalgebra::{Matrix3, SVector, Vector3};
    use simba::simd::SimdValue;

    type W = F64x4;

    fn splat(v: f64) -> W {
        <W as SimdValue>::splat(v)
    }

    fn v3(v: &Vector3<f64>) -> Vector3<W> {
        v.map(splat)
    }

    fn m3(m: &Matrix3<f64>) -> Matrix3<W> {
        m.map(splat)
    }

    /// The same chain with every number in all four lanes.
    fn wide(c: &SerialChain<f64, 4>) -> SerialChain<W, 4> {
        SerialChain {
            bodies: std::array::from_fn(|i| {
                let b = &c.bodies[i];
                Body {
                    kind: b.kind,
                    axis: v3(&b.axis),
                    tree: Pose {
                        rot: m3(&b.tree.rot),
                        pos: v3(&b.tree.pos),
                    },
                    inertia: RigidInertia {
                        mass: splat(b.inertia.mass),
                        h: v3(&b.inertia.h),
                        ibar: m3(&b.inertia.ibar),
                    },
                }
            }),
            tip: Pose {
                rot: m3(&c.tip.rot),
                pos: v3(&c.tip.pos),
            },
            gravity: splat(c.gravity),
        }
    }

    /// The algorithms are one source for scalars and SIMD lanes: four different states in
    /// the four lanes of `F64x4` give each lane's scalar result.
    #[test]
    fn four_lanes_match_four_scalar_runs() {
        let c = chain4();
        let w = wide(&c);
        let (q, qd) = state();
        let shift = |k: usize| 0.3 * k as f64;
        let lane = |v: &SVector<f64, 4>| {
            SVector::<W, 4>::from_fn(|i, _| W::from_lanes(|k| v[i] + shift(k)))
        };
        let tau = SVector::<f64, 4>::new(1.5, -2.0, 3.0, 0.7);
        let (wq, wqd) = (lane(&q), lane(&qd));
        let wtau = SVector::<W, 4>::from_fn(|i, _| splat(tau[i]));
        let wf = w.frames(&wq);
        let force = Vector3::new(3.0, -1.0, 2.0);
        let wqdd = w.aba(&wf, &wqd, &wtau, &w.tip_wrench(&wf, &v3(&force)));
        let wd = w.crba(&wf);
        let (wj, _) = w.jacobian(&wf, &wqd);
        for k in 0..4 {
            let s = SVector::<f64, 4>::repeat(shift(k));
            let f = c.frames(&(q + s));
            let qdd = c.aba(&f, &(qd + s), &tau, &c.tip_wrench(&f, &force));
            let d = c.crba(&f);
            let (j, _) = c.jacobian(&f, &(qd + s));
            let pick = |x: W| x.extract(k);
            for i in 0..4 {
                assert!((pick(wqdd[i]) - qdd[i]).abs() < 1e-9 * (1.0 + qdd[i].abs()));
                for r in 0..4 {
                    assert!((pick(wd[(r, i)]) - d[(r, i)]).abs() < 1e-12);
                }
                for r in 0..6 {
                    assert!((pick(wj[(r, i)]) - j[(r, i)]).abs() < 1e-12);
                }
            }
        }
        let _ = SVec::<W>::zero();
    }
}
