//! The whole GPU solver against the CPU one: edge differences computed on the GPU from the diffused
//! gradient field, cold and warm solves of real sketches, the incremental `begin` / `iterate` path,
//! texel probes and the traffic counters. Run on lavapipe with `WGPU_BACKEND=vulkan`.

mod gpu_common;

use terrasketch_multigrid::gpu_solver::GpuSolver;
use terrasketch_multigrid::{
    Budget, ConstraintMaps, CpuSolver, Grid, SolverParams, fields, gpu::GpuContext,
};
use terrasketch_sketch::{Sketch, example_sketch};

fn max_abs_diff(a: &[f32], b: &[f32]) -> f32 {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f32::max)
}

fn max_abs(a: &[f32]) -> f32 {
    a.iter().map(|x| x.abs()).fold(0.0, f32::max)
}

/// CPU heights of `sketch` on `grid`, refined to round-off.
fn cpu_heights(grid: Grid, sketch: &Sketch) -> Vec<f32> {
    let mut s = CpuSolver::new(grid, SolverParams::default()).unwrap();
    s.set_sketch(sketch);
    s.solve();
    s.set_params(SolverParams {
        tolerance: 1e-7,
        max_vcycles: 60,
        ..SolverParams::default()
    });
    s.step(Budget::Unlimited);
    s.heights().to_vec()
}

fn moved(sketch: &Sketch, dx_m: f64) -> Sketch {
    let mut s = sketch.clone();
    for p in &mut s.strokes[0].points {
        p[0] += dx_m;
    }
    s
}

fn check_edges(ctx: &GpuContext, n: usize) {
    let sketch = example_sketch();
    let grid = Grid::new(n, sketch.extent_m).unwrap();
    let mut gpu = GpuSolver::new(ctx, grid, SolverParams::default()).unwrap();
    gpu.solve_sketch(&sketch).unwrap();
    // The CPU edge differences from the very gradient field the GPU diffused.
    let (gx, gy) = gpu.read_gradient().unwrap();
    let maps = ConstraintMaps::rasterize(&sketch, &grid);
    let (mut de, mut dn) = (vec![0.0f32; n * n], vec![0.0f32; n * n]);
    fields::edge_differences(&grid, &maps, (&gx, &gy), 0..n, (&mut de, &mut dn));
    let (ge, gn) = gpu.read_edge_differences().unwrap();
    let scale = max_abs(&de).max(max_abs(&dn));
    assert!(
        scale > 1.0,
        "the example sketch has gradient bands ({scale})"
    );
    let (e, no) = (max_abs_diff(&de, &ge), max_abs_diff(&dn, &gn));
    assert!(
        e <= 1e-5 * scale && no <= 1e-5 * scale,
        "{n}^2: edge differences differ by {e} (east), {no} (north); largest {scale} m"
    );
    // Both zero outside the bands and on the last column / row.
    for j in 0..n {
        assert_eq!(ge[j * n + n - 1], 0.0);
        assert_eq!(gn[(n - 1) * n + j], 0.0);
    }
}

#[test]
fn edge_differences_match_cpu_128_and_256() {
    let ctx = gpu_common::device();
    check_edges(&ctx, 128);
    check_edges(&ctx, 256);
}

#[test]
fn cold_warm_and_incremental_solves_match_cpu() {
    let ctx = gpu_common::device();
    let n = 128;
    let sketch = example_sketch();
    let grid = Grid::new(n, sketch.extent_m).unwrap();
    let mut gpu = GpuSolver::new(&ctx, grid, SolverParams::default()).unwrap();

    // Cold, refined to round-off on both sides.
    let r = gpu.solve_sketch(&sketch).unwrap();
    assert!(r.converged, "{r:?}");
    gpu.refine_to(1e-7, 60).unwrap();
    let cpu = cpu_heights(grid, &sketch);
    let relief = r.height_max_m - r.height_min_m;
    assert!(relief > 100.0, "relief {relief}");
    let d = max_abs_diff(&gpu.read_heights().unwrap(), &cpu);
    assert!(
        d <= 2e-3 * relief,
        "cold: GPU and CPU differ by {d} m over {relief} m"
    );

    // Warm update after moving a stroke: the same heights as a cold CPU solve of the new sketch.
    let edited = moved(&sketch, 0.03 * sketch.extent_m[0]);
    let w = gpu.update_sketch_warm(&edited).unwrap();
    assert!(w.converged, "{w:?}");
    gpu.refine_to(1e-7, 60).unwrap();
    let cpu_edited = cpu_heights(grid, &edited);
    let d = max_abs_diff(&gpu.read_heights().unwrap(), &cpu_edited);
    assert!(d <= 2e-3 * relief, "warm: GPU and CPU differ by {d} m");
    // The edit changed the terrain (the test can fail).
    assert!(max_abs_diff(&cpu, &cpu_edited) > 10.0);

    // Incremental path (the editor's): begin warm on the original sketch, iterate to the tolerance;
    // FCG's residual decreases and the result matches the CPU.
    let b = gpu.begin(&sketch, false).unwrap();
    assert!(b.residual > SolverParams::default().tolerance, "{b:?}");
    let mut iters = 0;
    let mut last = gpu.residual();
    while gpu.residual() > 1e-6 && iters < 60 {
        if gpu.iterate().unwrap().is_none() {
            break;
        }
        iters += 1;
        assert!(gpu.residual().is_finite());
        last = last.min(gpu.residual());
    }
    assert!(last <= 1e-5, "residual after {iters} iterations: {last}");
    gpu.publish().unwrap();
    let d = max_abs_diff(&gpu.read_heights().unwrap(), &cpu);
    assert!(
        d <= 2e-3 * relief,
        "incremental: GPU and CPU differ by {d} m"
    );
    // The constraint maps kept for the overlay are the CPU rasterisation.
    assert_eq!(
        gpu.constraint_maps().unwrap(),
        &ConstraintMaps::rasterize(&sketch, &grid)
    );

    // Texel probes: equal to the mip read back in full, 4 bytes each by the traffic counter.
    let mip1 = gpu.read_mip(1).unwrap();
    let side = n / 2;
    let texels = [[0u32, 0u32], [5, 9], [63, 63], [31, 2]];
    let before = ctx.traffic();
    let got = gpu.read_texels(1, &texels).unwrap();
    let after = ctx.traffic();
    assert_eq!(after.1 - before.1, 16, "bytes down for 4 texels");
    for (t, h) in texels.iter().zip(&got) {
        assert_eq!(*h, mip1[t[1] as usize * side + t[0] as usize]);
    }
    assert!(gpu.read_texels(1, &[[64, 0]]).is_err(), "outside the mip");
    assert!(gpu.read_texels(9, &[[0, 0]]).is_err(), "no such mip");

    // A warm begin uploads the problem but reads back only FCG's stop tests.
    let before = ctx.traffic();
    gpu.begin(&edited, false).unwrap();
    for _ in 0..3 {
        gpu.iterate().unwrap();
    }
    let after = ctx.traffic();
    let down = after.1 - before.1;
    assert!(down <= 8 * 64, "a warm start read back {down} bytes");
    assert!(
        after.0 - before.0 >= (n * n * 12) as u64,
        "uploads are counted"
    );
}

#[test]
fn empty_sketch_is_flat_at_the_base() {
    let ctx = gpu_common::device();
    let sketch = Sketch::empty([2000.0, 2000.0], 150.0);
    let grid = Grid::new(64, sketch.extent_m).unwrap();
    let mut gpu = GpuSolver::new(&ctx, grid, SolverParams::default()).unwrap();
    let r = gpu.solve_sketch(&sketch).unwrap();
    assert!(r.converged);
    assert!(gpu.read_heights().unwrap().iter().all(|h| *h == 150.0));
    assert_eq!(r.height_min_m, 150.0);
    assert_eq!(r.height_max_m, 150.0);
}
