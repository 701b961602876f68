//! The procedural detail (`terrasketch-detail`) on the solvers' fields: its level-2 amplitude map
//! from the mip-2 heights, the diffused roughness and the hard elevation constraints.

use anyhow::Result;
use terrasketch_detail::{AmplitudeInputs, amplitude_map, hard_counts};
use terrasketch_multigrid::{ConstraintMaps, CpuSolver, Grid};
use terrasketch_sketch::Sketch;

use crate::backend::AnySolver;

/// The amplitude map (side `n / 4`) of `grid` from mip 2, the roughness (level 2) and the level-0
/// elevation weights.
pub fn amplitude_from(
    grid: &Grid,
    mip2: &[f32],
    roughness: &[f32],
    elev_weight: &[f32],
) -> Vec<f32> {
    let m = grid.n / 4;
    let counts = hard_counts(grid.n, elev_weight);
    let [dx, dy] = grid.cell_size_m();
    amplitude_map(&AmplitudeInputs {
        m,
        cell_m: [4.0 * dx as f32, 4.0 * dy as f32],
        mip2,
        roughness,
        hard_counts: &counts,
    })
}

/// The amplitude map of the CPU solver's current state (solves the roughness if it is stale; the
/// hard cells per block come from the solver's own constraint summary, kept current by each edit).
pub fn amplitude_cpu(solver: &mut CpuSolver) -> Vec<f32> {
    let rough = solver.roughness().to_vec();
    let grid = solver.grid();
    let m = grid.n / 4;
    let summary = solver.hard_summary_level2();
    let counts: Vec<u32> = if summary.len() == m * m {
        summary.iter().map(|c| c.1 as u32).collect()
    } else {
        hard_counts(grid.n, &solver.constraints().elev_weight)
    };
    let [dx, dy] = grid.cell_size_m();
    amplitude_map(&AmplitudeInputs {
        m,
        cell_m: [4.0 * dx as f32, 4.0 * dy as f32],
        mip2: solver.mip(2),
        roughness: &rough,
        hard_counts: &counts,
    })
}

/// The amplitude map of either backend after a solve of `sketch` (the GPU's roughness and mip 2 are
/// read back; its elevation weights are rasterised again on the CPU).
pub fn amplitude_any(solver: &mut AnySolver, sketch: &Sketch, grid: &Grid) -> Result<Vec<f32>> {
    match solver {
        AnySolver::Cpu(s) => Ok(amplitude_cpu(s)),
        AnySolver::Gpu(g) => {
            let rough = g.read_roughness()?;
            let mip2 = g.read_mip(2)?;
            let weights = ConstraintMaps::rasterize(sketch, grid).elev_weight;
            Ok(amplitude_from(grid, &mip2, &rough, &weights))
        }
    }
}
