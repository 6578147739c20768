//! The lane loop's three builds (see [`LanePath`](super::LanePath)), one module each.
//!
//! Why modules: rustc places every instance of a generic function in the codegen unit of
//! the module that defines it. With the three builds in one module, all 27 of their
//! instances (9 arms × 3 builds, each the whole inlined loop) were optimised by one LLVM
//! thread, a quarter of an hour of a single core in the release build; one module per build
//! lets them run on separate cores.

use super::{lanes_loop, StagePath};
use crate::robot::RobotModel;
use crate::sim::simulation::Simulation;

/// Four lanes in baseline code: any CPU.
pub(super) mod portable {
    use super::*;
    use crate::scalar::F64x4;

    pub(in crate::sim::lanes) fn run<R: RobotModel<N>, const N: usize>(
        sims: &mut [Simulation<R, N>],
    ) -> StagePath {
        lanes_loop::<F64x4, 4, R, N>(sims)
    }
}

/// Four lanes in ymm registers, with AVX2 and FMA instructions.
#[cfg(target_arch = "x86_64")]
pub(super) mod avx2 {
    use super::*;
    use crate::scalar::F64x4Avx2;

    /// # Safety
    /// The CPU must have AVX2 and FMA.
    #[target_feature(enable = "avx2,fma")]
    pub(in crate::sim::lanes) unsafe fn run<R: RobotModel<N>, const N: usize>(
        sims: &mut [Simulation<R, N>],
    ) -> StagePath {
        lanes_loop::<F64x4Avx2, 4, R, N>(sims)
    }
}

/// Eight lanes in AVX-512 registers (F for the 512-bit arithmetic, DQ for the 64-bit
/// integer conversions and masks of `exp_lanes`' exponent bits, VL for the narrower ops).
#[cfg(target_arch = "x86_64")]
pub(super) mod avx512 {
    use super::*;
    use crate::scalar::F64x8Avx512;

    /// # Safety
    /// The CPU must have AVX-512 F, DQ and VL, AVX2 and FMA.
    #[target_feature(enable = "avx512f,avx512dq,avx512vl,avx2,fma")]
    pub(in crate::sim::lanes) unsafe fn run<R: RobotModel<N>, const N: usize>(
        sims: &mut [Simulation<R, N>],
    ) -> StagePath {
        lanes_loop::<F64x8Avx512, 8, R, N>(sims)
    }
}
