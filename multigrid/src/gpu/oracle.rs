//! Read access to CPU-backend internals that the GPU-vs-CPU tests compare against (the CPU keeps them
//! `pub(crate)`). Not part of the solver API.
#![doc(hidden)]

use crate::cpu::Hierarchy;

/// Galerkin stencils of CPU level `k >= 1`.
pub fn cpu_stencils(h: &Hierarchy, k: usize) -> &[[f32; 9]] {
    &h.coarse[k - 1].st
}

/// CPU level-0 diagonal (0 on hard cells) and right-hand side.
pub fn cpu_level0(h: &Hierarchy) -> (&[f32], &[f32]) {
    (&h.level0.diag, &h.level0.f)
}
