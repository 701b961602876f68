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

/// The CPU's local relaxation of `h` (`Fcg::relax_at_residuals`: `sweeps` red-black sweeps in
/// the windows of radius `RADIUS` around the cells whose normalised residual exceeds `threshold`,
/// none if they cover more than a quarter of the level). Returns its work units.
pub fn cpu_local_relaxation(hy: &Hierarchy, h: &mut [f32], threshold: f32, sweeps: usize) -> f64 {
    let mut r = vec![0.0; h.len()];
    let seeds = hy.large_residual_cells(h, &mut r, threshold);
    hy.relax_around_spans(h, &seeds, sweeps).0
}
