//! The procedural detail (`terrasketch-detail`) on the solvers' fields: its amplitude map (level
//! `AMPLITUDE_LEVEL`) from that mip of the heights, the diffused roughness (level 2) and the hard
//! elevation constraints.

use anyhow::Result;
use terrasketch_detail::amplitude::AMPLITUDE_LEVEL;
use terrasketch_detail::{AmplitudeInputs, HardCells, amplitude_map, amplitude_side, hard_counts};
use terrasketch_multigrid::{ConstraintMaps, CpuSolver, Grid};
use terrasketch_sketch::Sketch;

use crate::backend::AnySolver;

/// Cell size of the amplitude map of `grid`, metres.
fn map_cell_m(grid: &Grid) -> [f32; 2] {
    let [dx, dy] = grid.cell_size_m();
    let s = f64::from(1u32 << AMPLITUDE_LEVEL);
    [(s * dx) as f32, (s * dy) as f32]
}

/// The amplitude map ([`amplitude_side`]) of `grid` from the heights' mip `AMPLITUDE_LEVEL`, the
/// roughness (level 2, side n / 4) and the level-0 elevation weights.
pub fn amplitude_from(
    grid: &Grid,
    mip: &[f32],
    roughness: &[f32],
    elev_weight: &[f32],
) -> Vec<f32> {
    let counts = hard_counts(grid.n, elev_weight);
    amplitude_map(&AmplitudeInputs {
        m: amplitude_side(grid.n),
        cell_m: map_cell_m(grid),
        heights: mip,
        roughness,
        roughness_side: grid.n / 4,
        hard: HardCells::Counts(&counts),
    })
}

/// The amplitude map of the CPU solver's current state (solves the roughness if it is stale; the
/// hard cells per block come from the solver's own constraint summary, kept current by each edit).
pub fn amplitude_cpu(solver: &mut CpuSolver) -> Vec<f32> {
    let rough = solver.roughness().to_vec();
    let grid = solver.grid();
    let m = amplitude_side(grid.n);
    let summary = solver.hard_summary(AMPLITUDE_LEVEL);
    let counts;
    let hard = if summary.len() == m * m {
        HardCells::Summary(summary)
    } else {
        counts = hard_counts(grid.n, &solver.constraints().elev_weight);
        HardCells::Counts(&counts)
    };
    amplitude_map(&AmplitudeInputs {
        m,
        cell_m: map_cell_m(&grid),
        heights: solver.mip(AMPLITUDE_LEVEL as usize),
        roughness: &rough,
        roughness_side: grid.n / 4,
        hard,
    })
}

/// The amplitude map of either backend after a solve of `sketch` (the GPU's roughness and mip are
/// read back; its elevation weights are rasterised again on the CPU).
pub fn amplitude_any(solver: &mut AnySolver, sketch: &Sketch, grid: &Grid) -> Result<Vec<f32>> {
    match solver {
        AnySolver::Cpu(s) => Ok(amplitude_cpu(s)),
        AnySolver::Gpu(g) => {
            let rough = g.read_roughness()?;
            let mip = g.read_mip(AMPLITUDE_LEVEL as usize)?;
            let weights = ConstraintMaps::rasterize(sketch, grid).elev_weight;
            Ok(amplitude_from(grid, &mip, &rough, &weights))
        }
    }
}
