//! Composite-rigid-body algorithm (Featherstone Table 6.2): the joint-space inertia D(q).

use nalgebra::SMatrix;

use super::kinematics::Frames;
use super::model::SerialChain;
use super::spatial::{Real, SpatialInertia};
use crate::scalar::zeros;

impl<T: Real, const N: usize> SerialChain<T, N> {
    /// D(q): composite inertias I^c_i = I_i + Σ X_jᵀ I^c_j X_j from the tip down, then
    /// D_ij = S_jᵀ (X … X)ᵀ I^c_i S_i along the chain.
    #[inline(always)]
    pub fn crba(&self, f: &Frames<T, N>) -> SMatrix<T, N, N> {
        let mut composite: [SpatialInertia<T>; N] =
            std::array::from_fn(|i| SpatialInertia::rigid(&self.bodies[i].inertia));
        for i in (1..N).rev() {
            composite[i - 1] = composite[i - 1].add(&composite[i].to_parent(&f.up[i]));
        }
        let mut d = zeros::<T, N, N>();
        for i in 0..N {
            let mut force = composite[i].apply(&self.subspace(i));
            d[(i, i)] = self.subspace(i).dot(&force);
            let mut j = i;
            while j > 0 {
                force = f.up[j].force_to_parent(&force);
                j -= 1;
                let dij = self.subspace(j).dot(&force);
                d[(i, j)] = dij;
                d[(j, i)] = dij;
            }
        }
        d
    }
}
