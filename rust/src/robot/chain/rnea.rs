//! Recursive Newton–Euler (Featherstone Table 5.1): inverse dynamics τ = ID(q, q̇, q̈, f_ext),
//! and from it the bias terms C q̇ and G of eq. (1).

use nalgebra::{SVector, Vector3};

use super::kinematics::Frames;
use super::model::SerialChain;
use super::spatial::{Real, SVec};
use crate::scalar::zeros;

impl<T: Real, const N: usize> SerialChain<T, N> {
    /// The base's spatial acceleration standing in for gravity: a_0 = −a_g = [0; 0, 0, g].
    #[inline(always)]
    pub(crate) fn base_acceleration(&self, gravity: bool) -> SVec<T> {
        let g = if gravity { self.gravity } else { T::zero() };
        SVec::new(zeros(), Vector3::new(T::zero(), T::zero(), g))
    }

    /// τ = D q̈ + C q̇ + G − Jᵀ(tip wrench): the torques that give `qdd` at (q, q̇) while the
    /// environment applies `tip_wrench` (a spatial force on body N in its frame).
    #[inline(always)]
    pub fn rnea(
        &self,
        f: &Frames<T, N>,
        qd: &SVector<T, N>,
        qdd: &SVector<T, N>,
        gravity: bool,
        tip_wrench: &SVec<T>,
    ) -> SVector<T, N> {
        let mut forces = [SVec::<T>::zero(); N];
        let mut v = SVec::<T>::zero();
        let mut a = self.base_acceleration(gravity);
        // Forward pass: v_i = X_i v_{i−1} + S_i q̇_i, a_i = X_i a_{i−1} + S_i q̈_i + v_i ×ₘ S_i q̇_i,
        // f_i = I_i a_i + v_i ×* I_i v_i.
        for i in 0..N {
            let s = self.subspace(i);
            let vj = s.scale(qd[i]);
            v = f.up[i].motion_to_child(&v).add(&vj);
            a = f.up[i]
                .motion_to_child(&a)
                .add(&s.scale(qdd[i]))
                .add(&v.cross_motion(&vj));
            let inertia = &self.bodies[i].inertia;
            forces[i] = inertia.apply(&a).add(&v.cross_force(&inertia.apply(&v)));
        }
        forces[N - 1] = forces[N - 1].sub(tip_wrench);
        // Backward pass: τ_i = S_iᵀ f_i, f_{i−1} += X_iᵀ f_i.
        let mut tau = zeros::<T, N, 1>();
        for i in (0..N).rev() {
            tau[i] = self.subspace(i).dot(&forces[i]);
            if i > 0 {
                let up = f.up[i].force_to_parent(&forces[i]);
                forces[i - 1] = forces[i - 1].add(&up);
            }
        }
        tau
    }

    /// C(q, q̇) q̇ and G(q).
    #[inline(always)]
    pub fn bias(&self, f: &Frames<T, N>, qd: &SVector<T, N>) -> (SVector<T, N>, SVector<T, N>) {
        let zero = zeros::<T, N, 1>();
        let g = self.rnea(f, &zero, &zero, true, &SVec::zero());
        let c = self.rnea(f, qd, &zero, false, &SVec::zero());
        (c, g)
    }
}
