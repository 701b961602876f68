//! What a warm update costs on the GPU, counted: the local relaxation's tile passes run over the
//! box of their windows only, and a drag update of `GpuSolver` stays below fixed dispatch and byte
//! bounds. Run on lavapipe with `WGPU_BACKEND=vulkan`.

mod gpu_common;

use gpu_common::{device, max_diff, problem};
use terrasketch_multigrid::gpu::GpuFieldSolver;
use terrasketch_multigrid::gpu_solver::GpuSolver;
use terrasketch_multigrid::{CpuSolver, Grid, SolverParams};

/// An edit of a short stretch of one row (32 cells of a 128^2 problem): the relaxation's 10 sweeps
/// run as 2 tile passes over the windows' box (not 20 colour passes), which move less than a fifth
/// of the bytes the same passes move over the whole level (about `28 n^2` bytes each: `h` and `z`
/// read and written, `f`, `diag`, the mask), and the windowed relaxation still changes `h` there
/// and leaves it unchanged far away.
#[test]
fn local_relaxation_moves_only_its_box() {
    let ctx = device();
    let n = 128;
    let p = problem(n, 1.0, 1.0);
    let relief = p.relief();
    let mut gpu = GpuFieldSolver::new(&ctx, n, p.ax, p.ay).unwrap();
    gpu.upload_problem(&p).unwrap();
    gpu.fmg().unwrap();
    gpu.fcg(60, 1e-6).unwrap();
    let mut edited = p.clone();
    for i in n / 4..n / 4 + 32 {
        edited.value[(n / 5) * n + i] = 800.0;
    }
    // The same start without sweeps, then with them: the difference is the tile passes' bytes.
    let mut moved = [0u64; 2];
    let mut dispatches = [0u64; 2];
    let h0 = gpu.read_solution().unwrap();
    for (k, sweeps) in [0usize, 10].into_iter().enumerate() {
        gpu.warm_start(&edited).unwrap();
        let before = ctx.counters();
        gpu.fcg_start_relaxed(0.1, sweeps).unwrap();
        let c = ctx.counters().since(&before);
        moved[k] = c.bytes_moved_estimate;
        dispatches[k] = c.dispatches;
    }
    let h = gpu.read_solution().unwrap();
    let tile_passes = moved[1] - moved[0];
    let whole_level = 2 * 28 * (n * n) as u64;
    eprintln!(
        "relaxation tile passes: {tile_passes} B (whole level: {whole_level} B), \
         dispatches {dispatches:?}"
    );
    assert_eq!(dispatches[1] - dispatches[0], 2, "two tile passes");
    assert!(
        tile_passes > 0 && tile_passes * 5 < whole_level,
        "the tile passes moved {tile_passes} B, whole-level passes {whole_level} B"
    );
    assert!(max_diff(&h, &h0) / relief > 1e-2, "the relaxation moved h");
    // Far from the edit (the last rows) nothing moved.
    let far = (n - 8) * n;
    assert_eq!(max_diff(&h[far..], &h0[far..]), 0.0);
}

/// The benchmark drag's second update at 256^2 (`bench drag`'s second frame): at most 165
/// dispatches (197 with a pass per colour of the local relaxation, 287 with one per colour of each
/// coarse sweep too) and at most 900 estimated bytes per texel (1,058 and 1,223 with them), and
/// the heights agree with a cold CPU solve of the moved sketch within 1e-3 of the relief.
#[test]
fn a_drag_update_stays_below_its_dispatch_and_byte_bounds() {
    let ctx = device();
    let n = 256;
    let mut sketch = terrasketch_sketch::benchmark_sketch();
    let grid = Grid::new(n, sketch.extent_m).unwrap();
    let mut gpu = GpuSolver::new(&ctx, grid, SolverParams::default()).unwrap();
    gpu.solve_sketch(&sketch).unwrap();
    let mut counts = Vec::new();
    for _ in 0..2 {
        for p in &mut sketch.strokes[0].points {
            p[0] += 6.0;
            p[1] += 4.0;
        }
        let before = ctx.counters();
        let r = gpu.update_sketch_warm(&sketch).unwrap();
        assert!(r.converged, "{r:?}");
        counts.push(ctx.counters().since(&before));
    }
    let c = counts[1];
    let per_texel = c.bytes_moved_estimate as f64 / (n * n) as f64;
    eprintln!("{n}^2 drag update: {c:?}, {per_texel:.0} B per texel");
    assert!(c.dispatches <= 165, "{} dispatches", c.dispatches);
    assert!(per_texel <= 900.0, "{per_texel:.0} B per texel");
    // One round trip: the queued runs' reports (the reliefs are computed on the GPU).
    assert!(c.blocking_waits <= 1, "{} waits", c.blocking_waits);
    let mut cpu = CpuSolver::new(grid, SolverParams::default()).unwrap();
    cpu.set_sketch(&sketch);
    cpu.solve();
    let relief = cpu.relief_m();
    let d = max_diff(&gpu.read_heights().unwrap(), cpu.heights()) / relief;
    assert!(d <= 1e-3, "warm GPU vs cold CPU: {d:.2e} of the relief");
}
