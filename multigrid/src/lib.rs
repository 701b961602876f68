//! # terrasketch-multigrid
//!
//! Turns rasterised stroke constraints into a heightmap by solving diffusion (Poisson) systems with a
//! real multigrid: full multigrid (FMG) with V-cycles on Galerkin coarse operators, stopping on a
//! residual tolerance. The exact discrete algorithm is in `ALGORITHM.md`; the CPU backend (`cpu`) is
//! the reference, the GPU backend (`gpu`) runs the same algorithm in WGSL compute shaders.
//!
//! ## How it works
//! 1. `constraints` rasterises a [`terrasketch_sketch::Sketch`] into level-0 constraint maps.
//! 2. The gradient field and roughness are diffused from the stroke bands (one operator, three fields).
//! 3. Heights are solved from the elevation constraints plus edge differences from that field.
//! 4. Each level of the solve is one mip level of the heightmap; a small min/max pyramid feeds the
//!    quadtree.

pub mod backend;
pub mod constraints;
pub mod cpu;
pub mod cycle;
pub mod fields;
pub mod gpu;
pub mod gpu_solver;
pub mod grid;
pub mod problem;
pub mod pyramid;
pub mod solver;

use thiserror::Error;

pub use backend::{Solver, Taken};
pub use constraints::ConstraintMaps;
pub use grid::Grid;
pub use problem::FieldProblem;
pub use solver::{Budget, CpuSolver, PhaseMs, Progress, SolveReport};

/// Tuning of one solve.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SolverParams {
    /// Gauss-Seidel sweeps before the coarse-grid correction.
    pub pre_sweeps: u32,
    /// Gauss-Seidel sweeps after the coarse-grid correction.
    pub post_sweeps: u32,
    /// Stop when `max |r| / ((2 ax + 2 ay) relief)` is at most this.
    pub tolerance: f32,
    /// Upper bound on level-0 V-cycles of one solve.
    pub max_vcycles: u32,
    /// Coarse-grid visits per level: 1 = V-cycle, 2 = W-cycle.
    pub gamma: u32,
    /// Levels from which `gamma` applies (coarser levels are cheap; 0 = everywhere).
    pub gamma_from_level: u32,
    /// Level from which the visits are single again: level `k + 1` is visited `gamma` times from
    /// level `k` for `gamma_from_level <= k < gamma_until_level`, once otherwise (a W-cycle
    /// between those levels, V-cycles below).
    pub gamma_until_level: u32,
    /// FCG's stop-test relaxation (ALGORITHM.md): a residual within twice the tolerance in a few
    /// cells is relaxed there instead of by another iteration. Off for offline solves that want
    /// every iteration's global smoothing (the refinement's target and merges).
    pub stop_relaxation: bool,
}

impl Default for SolverParams {
    fn default() -> Self {
        SolverParams {
            pre_sweeps: 1,
            post_sweeps: 1,
            tolerance: 3e-4,
            max_vcycles: 40,
            gamma: 2,
            gamma_from_level: 1,
            gamma_until_level: 3,
            stop_relaxation: true,
        }
    }
}

/// Errors of the solver crate.
#[derive(Debug, Error)]
pub enum SolverError {
    /// The heightmap side is not a power of two in the supported range.
    #[error(
        "size {size} is not supported: the heightmap side must be a power of two from {min} to {max}",
        min = grid::MIN_SIDE,
        max = grid::MAX_SIDE
    )]
    BadSize {
        /// The refused size.
        size: usize,
    },
    /// The extent is not positive and finite.
    #[error("extent {extent_m:?} m is not valid: both sides must be positive and finite")]
    BadExtent {
        /// The refused extent.
        extent_m: [f64; 2],
    },
}
