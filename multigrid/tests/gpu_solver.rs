//! The whole GPU solver against the CPU one: the height operator assembled on the GPU with edge
//! differences computed inside the assembly from the diffused gradient field, cold and warm solves of real sketches, the incremental `begin` / `iterate` path,
//! texel probes and the traffic counters. Run on lavapipe with `WGPU_BACKEND=vulkan`.

mod gpu_common;

use terrasketch_multigrid::cpu::Hierarchy;
use terrasketch_multigrid::gpu::oracle;
use terrasketch_multigrid::gpu_solver::GpuSolver;
use terrasketch_multigrid::{
    Budget, ConstraintMaps, CpuSolver, FieldProblem, Grid, SolverParams, fields, gpu::GpuContext,
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

/// The CPU's level-0 assembly `(diag, f)` of the height problem of `maps` with edge differences
/// `(de, dn)`.
fn cpu_height_operator(
    grid: &Grid,
    maps: &ConstraintMaps,
    (de, dn): (Vec<f32>, Vec<f32>),
) -> (Vec<f32>, Vec<f32>) {
    let n = grid.n;
    let [ax, ay] = grid.axis_weights();
    let p = FieldProblem {
        n,
        ax,
        ay,
        weight: maps.elev_weight.clone(),
        value: maps.elev_value.clone(),
        d_east: de,
        d_north: dn,
    };
    let mut h = Hierarchy::new(n, ax, ay);
    h.assemble(&p);
    let (diag, f) = oracle::cpu_level0(&h);
    (diag.to_vec(), f.to_vec())
}

/// Cells where `f` differs from `reference` by more than the tolerance of [`check_edges`]: `1e-5` of
/// the largest edge term `flux_scale` plus 1e-6 of the cell's `sigma E` (`f0`, the right-hand side
/// without edge differences), for the rounding of that term.
fn f_mismatches(f: &[f32], reference: &[f32], f0: &[f32], flux_scale: f32) -> Vec<usize> {
    (0..f.len())
        .filter(|&i| (f[i] - reference[i]).abs() > 1e-5 * flux_scale + 1e-6 * f0[i].abs())
        .collect()
}

/// The edge differences, which the GPU computes inside the height assembly from the gradient field it
/// diffused, checked through what they feed: the assembled level-0 diagonal and right-hand side against
/// the CPU's assembly with the CPU's edge differences of that very gradient field. A wrong edge
/// difference on any edge with a free end changes `f` there by `a * error`.
fn check_edges(ctx: &GpuContext, n: usize) {
    let sketch = example_sketch();
    let grid = Grid::new(n, sketch.extent_m).unwrap();
    let mut gpu = GpuSolver::new(ctx, grid, SolverParams::default()).unwrap();
    gpu.solve_sketch(&sketch).unwrap();
    let (gd, gf) = gpu.read_height_operator(&sketch).unwrap();
    let (gx, gy) = gpu.read_gradient().unwrap();
    let maps = ConstraintMaps::rasterize(&sketch, &grid);
    let (mut de, mut dn) = (vec![0.0f32; n * n], vec![0.0f32; n * n]);
    fields::edge_differences(&grid, &maps, (&gx, &gy), 0..n, (&mut de, &mut dn));
    let scale = max_abs(&de).max(max_abs(&dn));
    assert!(
        scale > 1.0,
        "the example sketch has gradient bands ({scale})"
    );
    let (diag, f) = cpu_height_operator(&grid, &maps, (de.clone(), dn.clone()));
    let (_, f0) = cpu_height_operator(&grid, &maps, (vec![0.0; n * n], vec![0.0; n * n]));
    let flux: Vec<f32> = f0.iter().zip(&f).map(|(a, b)| a - b).collect();
    let flux_scale = max_abs(&flux);
    assert!(flux_scale > 1.0, "the edge terms matter ({flux_scale})");
    assert!(
        gd.iter()
            .zip(&diag)
            .all(|(g, c)| (*g == 0.0) == (*c == 0.0)),
        "{n}^2: hard cells differ"
    );
    let dmax = diag.iter().fold(0.0f32, |m, v| m.max(*v));
    assert!(
        max_abs_diff(&gd, &diag) <= 1e-6 * dmax,
        "{n}^2: diag differs"
    );
    let bad = f_mismatches(&gf, &f, &f0, flux_scale);
    assert!(
        bad.is_empty(),
        "{n}^2: f differs at {} cells (first {:?}: gpu {} cpu {}); largest edge term {flux_scale}",
        bad.len(),
        bad.first(),
        bad.first().map_or(0.0, |&i| gf[i]),
        bad.first().map_or(0.0, |&i| f[i])
    );
    // The check catches a wrong edge difference: one east edge of a free cell with a non-zero
    // difference, off by 1e-4 of the largest difference, makes the CPU's own `f` fail it.
    let i = (0..n * n)
        .find(|&i| i % n + 1 < n && de[i] != 0.0 && diag[i] != 0.0 && diag[i + 1] != 0.0)
        .expect("an edge with a difference between free cells");
    let mut wrong = de.clone();
    wrong[i] += 1e-4 * scale;
    let (_, fw) = cpu_height_operator(&grid, &maps, (wrong, dn));
    assert!(
        !f_mismatches(&fw, &f, &f0, flux_scale).is_empty(),
        "{n}^2: an edge difference off by {} goes unnoticed",
        1e-4 * scale
    );
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

    // Cold, at the tolerance (within the 1e-3 error budget of the converged CPU heights: this
    // catches a cold path that solves a wrong problem, which `refine_to`'s re-assembly would
    // mend), then refined to round-off on both sides.
    let counted = ctx.counters();
    let r = gpu.solve_sketch(&sketch).unwrap();
    assert!(r.converged, "{r:?}");
    // FCG stops on the GPU and the reliefs are computed there: the reports (with the map's
    // min/max) are the only round trip, unless the first solve's guess of its iterations fell
    // short (one more).
    let waits = ctx.counters().since(&counted).blocking_waits;
    assert!(waits <= 2, "a cold solve waited {waits} times");
    let cpu = cpu_heights(grid, &sketch);
    let relief = r.height_max_m - r.height_min_m;
    assert!(relief > 100.0, "relief {relief}");
    let d = max_abs_diff(&gpu.read_heights().unwrap(), &cpu);
    assert!(
        d <= 2e-3 * relief,
        "cold at the tolerance: GPU and CPU differ by {d} m over {relief} m"
    );
    gpu.refine_to(&sketch, 1e-7, 60).unwrap();
    let d = max_abs_diff(&gpu.read_heights().unwrap(), &cpu);
    assert!(
        d <= 2e-3 * relief,
        "cold: GPU and CPU differ by {d} m over {relief} m"
    );

    // Warm update after moving a stroke: the same heights as a cold CPU solve of the new sketch.
    let edited = moved(&sketch, 0.03 * sketch.extent_m[0]);
    let counted = ctx.counters();
    let w = gpu.update_sketch_warm(&edited).unwrap();
    assert!(w.converged, "{w:?}");
    // A jump this large needs FCG in the field solves, which a warm take guesses it does not (a
    // drag's small edits never do): one retake, one more round trip, and maybe one for the heights.
    let waits = ctx.counters().since(&counted).blocking_waits;
    assert!(waits <= 3, "a warm update waited {waits} times");
    gpu.refine_to(&edited, 1e-7, 60).unwrap();
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

    // Publishing after every iteration, as the editor does each frame, changes no bit: the mips'
    // constraint pyramid lives in the heights' `weight`, which nothing reads after the assembly.
    let mut after = |publish_each: bool| {
        gpu.begin(&sketch, true).unwrap();
        for _ in 0..4 {
            if publish_each {
                gpu.publish().unwrap();
            }
            gpu.iterate().unwrap();
        }
        gpu.publish().unwrap();
        (gpu.read_heights().unwrap(), gpu.read_mip(1).unwrap())
    };
    let quiet = after(false);
    assert_eq!(after(true), quiet);
    assert_eq!(after(false), quiet, "cold begins repeat bit for bit");

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
    // A texel read-back is one submit and one blocking wait, and dispatches nothing.
    let before = ctx.counters();
    gpu.read_texels(1, &texels).unwrap();
    let c = ctx.counters().since(&before);
    assert_eq!(
        (c.dispatches, c.submits, c.blocking_waits),
        (0, 1, 1),
        "{c:?}"
    );
    assert_eq!(c.bytes_read_back, 16);
    assert!(gpu.read_texels(1, &[[64, 0]]).is_err(), "outside the mip");
    assert!(gpu.read_texels(9, &[[0, 0]]).is_err(), "no such mip");

    // A warm begin uploads only the stroke geometry and reads back only the queued runs' reports
    // (`REPORTS`) and FCG's 20-byte stop tests (`rmax`, `status` and the stop-test relaxation's
    // counts).
    let before = ctx.traffic();
    let counted = ctx.counters();
    gpu.begin(&edited, false).unwrap();
    for _ in 0..3 {
        gpu.iterate().unwrap();
    }
    // The take is one round trip (every queued run's report); each `iterate` is one more.
    let c = ctx.counters().since(&counted);
    assert!(c.dispatches > 3 * 10, "{c:?}");
    assert_eq!(c.blocking_waits, 1 + 3, "{c:?}");
    assert_eq!(c.bytes_read_back, ctx.traffic().1 - before.1);
    // The breakdown per kernel adds up to the totals, the gated passes' bytes (counted from the
    // reports) included.
    let by_pass = c.by_pass.nonzero();
    assert_eq!(by_pass.iter().map(|p| p.1).sum::<u64>(), c.dispatches);
    assert_eq!(
        by_pass.iter().map(|p| p.2).sum::<u64>(),
        c.bytes_moved_estimate
    );
    let gate = terrasketch_multigrid::gpu::shaders::Kernel::FcgGate;
    assert!(c.by_pass.of(gate).0 > 0, "{:?}", c.by_pass);
    let after = ctx.traffic();
    let down = after.1 - before.1;
    const REPORTS: u64 = 4 * terrasketch_multigrid::gpu::QUEUED_REPORT_BYTES + 8;
    assert_eq!(
        down,
        REPORTS + 3 * 20,
        "a warm start read back {down} bytes"
    );
    let up = after.0 - before.0;
    assert!(up > 0 && up <= 16 * 1024, "a warm start sent {up} bytes");
}

/// The gradient field's and roughness's level-0 buffers (and the rasteriser's `vy`) are ranges of
/// height buffers that are dead while they run (`gpu::resources::Buffers`); roughness keeps its own
/// `h` for warm starts. A cold solve, a warm update after it and a second warm update match the CPU
/// oracle in heights, gradient field and roughness: an alias that overlapped live data (the heights'
/// problem, band or solution, the other field's problem, `vy`, or the kept `h`) would break one.
#[test]
fn warm_updates_with_aliased_field_buffers_match_cpu() {
    let ctx = gpu_common::device();
    let n = 128;
    let sketch = example_sketch();
    let grid = Grid::new(n, sketch.extent_m).unwrap();
    let mut gpu = GpuSolver::new(&ctx, grid, SolverParams::default()).unwrap();
    let worst = |a: &[f32], b: &[f32]| {
        let scale = b.iter().fold(1e-6f32, |m, v| m.max(v.abs()));
        max_abs_diff(a, b) / scale
    };
    let first = moved(&sketch, 0.03 * sketch.extent_m[0]);
    let second = moved(&first, 0.02 * sketch.extent_m[0]);
    let mut last_rough: Option<Vec<f32>> = None;
    for (step, sk) in [
        ("cold", &sketch),
        ("warm", &first),
        ("second warm", &second),
    ] {
        let r = if step == "cold" {
            gpu.solve_sketch(sk).unwrap()
        } else {
            gpu.update_sketch_warm(sk).unwrap()
        };
        assert!(r.converged, "{step}: {r:?}");
        gpu.refine_to(sk, 1e-7, 60).unwrap();
        let mut cpu = CpuSolver::new(grid, SolverParams::default()).unwrap();
        cpu.set_sketch(sk);
        cpu.solve();
        let (cx, cy) = cpu.gradient_field();
        let (gx, gy) = gpu.read_gradient().unwrap();
        let (ex, ey) = (worst(&gx, cx), worst(&gy, cy));
        let cr = cpu.roughness().to_vec();
        let rough = gpu.read_roughness().unwrap();
        let er = worst(&rough, &cr);
        if let Some(before) = &last_rough {
            assert!(
                worst(before, &cr) > 1e-3,
                "{step}: the edit changes the roughness"
            );
        }
        last_rough = Some(rough);
        let heights = cpu_heights(grid, sk);
        let (lo, hi) = heights
            .iter()
            .fold((f32::INFINITY, f32::NEG_INFINITY), |(l, h), &v| {
                (l.min(v), h.max(v))
            });
        let relief = hi - lo;
        assert!(relief > 100.0, "{step}: relief {relief}");
        let d = max_abs_diff(&gpu.read_heights().unwrap(), &heights);
        eprintln!("{step}: heights {d} m of {relief}, gx {ex}, gy {ey}, roughness {er}");
        assert!(
            ex <= 0.05 && ey <= 0.05,
            "{step}: gradient field {ex}, {ey}"
        );
        assert!(er <= 0.03, "{step}: roughness {er}");
        assert!(
            d <= 2e-3 * relief,
            "{step}: GPU and CPU heights differ by {d} m"
        );
    }
    // A warm update of the unchanged sketch starts every field from its kept solution (`gx`, `gy`,
    // roughness's own `h`, the heights' `h`), which already meets the tolerance: nothing iterates and
    // nothing changes, bit for bit (a kept solution or a problem clobbered by an alias would).
    let kept = (
        gpu.read_heights().unwrap(),
        gpu.read_gradient().unwrap(),
        gpu.read_roughness().unwrap(),
    );
    let again = gpu.update_sketch_warm(&second).unwrap();
    assert_eq!(again.vcycles, 0, "{again:?}");
    let now = (
        gpu.read_heights().unwrap(),
        gpu.read_gradient().unwrap(),
        gpu.read_roughness().unwrap(),
    );
    assert!(kept.0 == now.0, "heights changed");
    assert!(kept.1 == now.1, "gradient field changed");
    assert!(kept.2 == now.2, "roughness changed");
}

/// Largest differences between GPU and CPU level-0 maps (elevation weight and value, band weight;
/// the GPU has no level-0 gradient or roughness maps), and the number of texels whose elevation
/// value differs by more than `tol_m` where weighted (ties between strokes may pick another winner).
fn compare_maps(gpu: &ConstraintMaps, cpu: &ConstraintMaps, tol_m: f32) -> ([f32; 3], usize) {
    let d = [
        max_abs_diff(&gpu.elev_weight, &cpu.elev_weight),
        max_abs_diff(&gpu.elev_value, &cpu.elev_value),
        max_abs_diff(&gpu.band_weight, &cpu.band_weight),
    ];
    let off = (0..cpu.elev_value.len())
        .filter(|&k| {
            cpu.elev_weight[k] > 0.0 && (gpu.elev_value[k] - cpu.elev_value[k]).abs() > tol_m
        })
        .count();
    (d, off)
}

/// `[min, max]` of `values` over the cells where `weight > 0` (None if none).
fn value_range(weight: &[f32], values: &[f32]) -> Option<[f32; 2]> {
    weight
        .iter()
        .zip(values)
        .filter(|(w, _)| **w > 0.0)
        .map(|(_, v)| *v)
        .fold(None, |r, v| match r {
            None => Some([v, v]),
            Some([a, b]) => Some([a.min(v), b.max(v)]),
        })
}

fn check_raster(ctx: &GpuContext, sketch: &Sketch, n: usize) {
    let grid = Grid::new(n, sketch.extent_m).unwrap();
    let mut gpu = GpuSolver::new(ctx, grid, SolverParams::default()).unwrap();
    let read = gpu.rasterize_and_read(sketch).unwrap();
    let g = &read.maps;
    let c = ConstraintMaps::rasterize(sketch, &grid);
    assert!(g.grad_x.is_empty() && g.rough_weight.is_empty() && g.rough_value.is_empty());
    assert!(
        c.elev_weight.iter().filter(|w| **w >= 1.0).count() > n,
        "strokes are hard somewhere"
    );
    assert!(c.band_weight.iter().any(|w| *w > 0.0));
    let (d, off) = compare_maps(g, &c, 0.05);
    eprintln!("{n}^2: max differences {d:?}, {off} elevation values off by > 5 cm");
    // Weights are distances over a cell in f32 instead of f64: 1e-3 of a cell.
    assert!(d[0] <= 1e-3 && d[2] <= 1e-3, "{n}^2 weights: {d:?}");
    assert!(off * 1000 <= n * n, "{n}^2: {off} elevation values differ");
    // The rasteriser writes the gradient problem straight onto level 1 and the roughness problem
    // onto level 2, summing its texels in 2 x 2 and 4 x 4 blocks in workgroup memory, in the
    // order of the CPU's downsampling. Gradients are tan(slope) times a unit direction: a
    // near-tie between two strokes may pick the other one's direction at a texel, which moves its
    // level-1 cell by more than 1e-3: allow a few.
    let (cg, cgy) = fields::gradient_problem(&grid, &c);
    let gp = &read.gradient;
    assert_eq!((gp.n, gp.ax, gp.ay), (cg.n, cg.ax, cg.ay));
    let grad_off = (0..cg.weight.len())
        .filter(|&k| {
            (gp.weight[k] - cg.weight[k]).abs() > 1e-3
                || (gp.value[k] - cg.value[k]).abs() > 1e-3
                || (read.gradient_y[k] - cgy[k]).abs() > 1e-3
        })
        .count();
    let grad_exact = gp.weight == cg.weight && gp.value == cg.value && read.gradient_y == cgy;
    eprintln!(
        "{n}^2 gradient problem: {grad_off} of {} cells differ by > 1e-3, bit for bit: {grad_exact}",
        cg.weight.len()
    );
    assert!(
        cg.weight.iter().filter(|w| **w > 0.0).count() * 20 > cg.weight.len(),
        "{n}^2: the sketch has bands somewhere"
    );
    assert!(
        grad_off * 1000 <= n * n,
        "{n}^2: {grad_off} gradient problem cells differ"
    );
    // On an adapter that reproduces the CPU's level-0 maps bit for bit (lavapipe), the CPU's
    // roughness problem bit for bit (a block summed in another order differs by about 1e-7 in a
    // few percent of the cells); elsewhere (fused multiply-adds) within 1e-6 (a texel of the
    // wrong block differs by far more).
    let cr = fields::roughness_problem(&grid, &c);
    let rough = &read.roughness;
    assert_eq!((rough.n, rough.ax, rough.ay), (cr.n, cr.ax, cr.ay));
    let (dw, dv) = (
        max_abs_diff(&rough.weight, &cr.weight),
        max_abs_diff(&rough.value, &cr.value),
    );
    let exact = (0..cr.weight.len())
        .filter(|&k| rough.weight[k] == cr.weight[k] && rough.value[k] == cr.value[k])
        .count();
    eprintln!(
        "{n}^2 roughness problem: max differences weight {dw:.1e}, value {dv:.1e}, {exact} of {} cells equal",
        cr.weight.len()
    );
    assert!(
        cr.weight.iter().filter(|w| **w > 0.0).count() * 20 > cr.weight.len(),
        "{n}^2: the sketch has roughness somewhere"
    );
    assert!(
        dw <= 1e-6 && dv <= 1e-6,
        "{n}^2 roughness problem: {dw}, {dv}"
    );
    if d == [0.0; 3] && grad_exact {
        assert_eq!(
            exact,
            cr.weight.len(),
            "{n}^2: roughness problem not bit for bit"
        );
    }
    // The value ranges the problems' reliefs come from, taken in the same pass: the CPU problems'
    // ranges (each an extreme of values compared above).
    let close = |a: Option<[f32; 2]>, b: Option<[f32; 2]>, tol: f32, what: &str| match (a, b) {
        (Some(a), Some(b)) => assert!(
            (a[0] - b[0]).abs() <= tol && (a[1] - b[1]).abs() <= tol,
            "{n}^2 {what} range: {a:?} against {b:?}"
        ),
        _ => assert_eq!(a, b, "{n}^2 {what} range"),
    };
    let s = read.stats;
    close(
        s.elevation,
        value_range(&c.elev_weight, &c.elev_value),
        0.05,
        "elevation",
    );
    close(
        s.grad_x,
        value_range(&cg.weight, &cg.value),
        1e-3,
        "gradient x",
    );
    close(s.grad_y, value_range(&cg.weight, &cgy), 1e-3, "gradient y");
    close(
        s.roughness,
        value_range(&cr.weight, &cr.value),
        1e-6,
        "roughness",
    );
    assert!(s.elevation.is_some() && s.grad_x.is_some() && s.roughness.is_some());
    // The problems and reliefs are used by the solve: the heights agree with the CPU solver's to
    // the tolerance (checked in `cold_warm_and_incremental_solves_match_cpu`).
}

#[test]
fn rasterisation_matches_cpu_constraint_maps_128_and_256() {
    let ctx = gpu_common::device();
    // The example with every shape option: a polyline stroke, each falloff, a closed ring.
    let mut shapes = example_sketch();
    shapes.strokes[1].curve = terrasketch_sketch::CurveKind::Polyline;
    shapes.strokes[1].falloff = terrasketch_sketch::Falloff::Sigmoid;
    shapes.strokes[2].falloff = terrasketch_sketch::Falloff::None;
    let e = shapes.extent_m;
    let mut ring = terrasketch_sketch::Stroke::new(
        terrasketch_sketch::StrokeKind::Ridge,
        (0..9)
            .map(|k| {
                let a = std::f64::consts::TAU * k as f64 / 9.0;
                [
                    (0.7 + 0.12 * a.cos()) * e[0],
                    (0.3 + 0.12 * a.sin()) * e[1],
                    800.0,
                ]
            })
            .collect(),
    );
    ring.closed = true;
    shapes.strokes.push(ring);
    for sketch in [
        example_sketch(),
        terrasketch_sketch::benchmark_sketch(),
        shapes,
    ] {
        check_raster(&ctx, &sketch, 128);
        check_raster(&ctx, &sketch, 256);
    }
    // Only the geometry (each curve's polyline: 32 bytes a segment, 32 a run of segments, 64 a
    // stroke) goes up, 32 bytes come back.
    let sketch = example_sketch();
    let grid = Grid::new(256, sketch.extent_m).unwrap();
    let mut gpu = GpuSolver::new(&ctx, grid, SolverParams::default()).unwrap();
    let before = ctx.traffic();
    let _ = gpu.begin(&sketch, true).unwrap();
    let after = ctx.traffic();
    let [dx, dy] = grid.cell_size_m();
    let segments: usize = terrasketch_sketch::stroke_curves(&sketch, dx.max(dy))
        .iter()
        .map(|c| c.points.len() - 1)
        .sum();
    eprintln!(
        "begin: {} bytes up, {} down ({segments} segments)",
        after.0 - before.0,
        after.1 - before.1
    );
    assert!(
        after.0 - before.0 <= (40 * segments + 64 * sketch.strokes.len() + 4096) as u64,
        "{} bytes up",
        after.0 - before.0
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

/// Where the stroke geometry cannot tell whether an elevation constraint exists (every point
/// outside the map), the solver asks the rasteriser (one more wait) and agrees with the CPU: flat
/// at the base when the strokes lie far off; a stroke just off the edge whose band reaches in.
/// The relief of an ordinary take is computed on the GPU and equals the rasteriser's range.
#[test]
fn reliefs_on_the_gpu_and_strokes_outside_the_map() {
    let ctx = gpu_common::device();
    let n = 64;
    let sketch = example_sketch();
    let grid = Grid::new(n, sketch.extent_m).unwrap();
    let mut gpu = GpuSolver::new(&ctx, grid, SolverParams::default()).unwrap();
    gpu.solve_sketch(&sketch).unwrap();
    let mut cpu = CpuSolver::new(grid, SolverParams::default()).unwrap();
    cpu.set_sketch(&sketch);
    cpu.solve();
    let (g, c) = (gpu.relief_m(), cpu.relief_m());
    assert!(
        c > 100.0 && (g - c).abs() <= 1e-3 * c,
        "GPU relief {g}, CPU {c}"
    );

    let shifted = |dx_m: f64| {
        let mut s = sketch.clone();
        for st in &mut s.strokes {
            for p in &mut st.points {
                p[0] += dx_m;
            }
        }
        s
    };
    let far = shifted(3.0 * sketch.extent_m[0]);
    let counted = ctx.counters();
    let r = gpu.solve_sketch(&far).unwrap();
    assert!(r.converged, "{r:?}");
    let waits = ctx.counters().since(&counted).blocking_waits;
    assert!((2..=3).contains(&waits), "{waits} waits");
    let base = far.base_elevation_m as f32;
    assert!(gpu.read_heights().unwrap().iter().all(|h| *h == base));

    // Every point left of the map by 2 cells, the widest band reaching in.
    let cell = sketch.extent_m[0] / n as f64;
    let max_x = sketch
        .strokes
        .iter()
        .flat_map(|s| s.points.iter().map(|p| p[0]))
        .fold(f64::MIN, f64::max);
    let near = shifted(-max_x - 2.0 * cell);
    let r = gpu.solve_sketch(&near).unwrap();
    assert!(r.converged, "{r:?}");
    gpu.refine_to(&near, 1e-7, 60).unwrap();
    let d = max_abs_diff(&gpu.read_heights().unwrap(), &cpu_heights(grid, &near));
    assert!(d <= 1e-3 * c, "GPU and CPU differ by {d} m");
}

#[test]
fn rasteriser_and_gradient_add_little_gpu_memory() {
    use terrasketch_multigrid::gpu::mips::constraint_offsets;
    use terrasketch_multigrid::gpu::{GpuFieldSolver, GpuMips, allocated_sizes, borrowed_level0};
    let ctx = gpu_common::device();
    let n = 256;
    let grid = Grid::new(n, [5000.0, 5000.0]).unwrap();
    let gpu = GpuSolver::new(&ctx, grid, SolverParams::default()).unwrap();
    let [ax, ay] = grid.axis_weights();
    let p = SolverParams::default();
    // The heights as `GpuSolver` makes them: without edge-difference buffers (they compute theirs
    // inside the assembly from the kept gradient components, counted below). The gradient field and
    // roughness allocate only what `allocated_sizes` lists for them: no coarse levels, and of level 0
    // only roughness's `h` (the rest are ranges of the heights' level-0 buffers).
    let h = GpuFieldSolver::with_edges(&ctx, n, ax, ay, &p, false).unwrap();
    let m = GpuMips::new(&h).unwrap();
    let own = |side: usize, shift: usize| -> u64 {
        allocated_sizes(side, false, true, &borrowed_level0(shift))
            .iter()
            .map(|(_, b)| b)
            .sum()
    };
    // Both keep only their reductions; roughness also its `h`.
    assert_eq!(own(n / 4, 2) - own(n / 2, 1), (n / 4 * n / 4 * 4) as u64);
    // `GpuSolver`'s mips keep their constraint pyramid in the heights' `weight` (`GpuMips::new`
    // allocates one).
    let c = constraint_offsets(n);
    let pyramid = (c[c.len() - 1] * 8) as u64;
    // Its heights keep `f` in their `p`, `h` in mip 0 of the height texture (which `m` counts)
    // and level 1's `u`, `f` and tile-sweep input in their `value` and `weight` (`with_edges`
    // allocates all five).
    let f = (2 * n * n * 4 + 3 * (n / 2) * (n / 2) * 4) as u64;
    let fields = h.gpu_bytes() - f + m.gpu_bytes() - pyramid + own(n / 2, 1) + own(n / 4, 2);
    let extra = gpu.gpu_bytes().checked_sub(fields);
    // Kept gradient components (2 x n^2 / 4 floats), the geometry buffer, stats and parameter
    // blocks: the level-0 maps and the y values `vy` reuse the height solver's buffers.
    eprintln!("{n}^2: fields {fields} B, rasteriser + gradient components {extra:?} B");
    let extra = extra.expect("GpuSolver counts at least the listed buffers");
    assert!(extra >= (2 * n * n) as u64, "{extra} bytes");
    assert!(extra <= (2 * n * n + 64 * 1024) as u64, "{extra} bytes");
}

/// The warm-start requirement on the GPU (`moving_a_stroke_by_one_texel_converges_in_two_cycles`
/// in `tests/solver.rs` is the CPU's): one stroke of the benchmark sketch moved by one texel
/// converges in at most 2 V-cycles (4 without the local relaxation before FCG), and the result
/// equals a cold CPU solve of the moved sketch within 1e-3 of the relief.
#[test]
fn moving_a_stroke_by_one_texel_converges_in_two_cycles_on_the_gpu() {
    let ctx = gpu_common::device();
    for n in [128usize, 256] {
        let mut sketch = terrasketch_sketch::benchmark_sketch();
        let grid = Grid::new(n, sketch.extent_m).unwrap();
        let mut gpu = GpuSolver::new(&ctx, grid, SolverParams::default()).unwrap();
        let cold = gpu.solve_sketch(&sketch).unwrap();
        assert!(cold.converged, "{cold:?}");
        let cell = grid.cell_size_m()[0];
        for p in &mut sketch.strokes[1].points {
            p[0] += cell;
        }
        let warm = gpu.update_sketch_warm(&sketch).unwrap();
        eprintln!("{n}^2: warm start {warm:?}");
        assert!(warm.converged, "{warm:?}");
        assert!(
            warm.vcycles <= 2,
            "warm start took {} V-cycles",
            warm.vcycles
        );
        let mut cpu = CpuSolver::new(grid, SolverParams::default()).unwrap();
        cpu.set_sketch(&sketch);
        cpu.solve();
        let relief = cpu.relief_m();
        let d = max_abs_diff(&gpu.read_heights().unwrap(), cpu.heights());
        assert!(
            d <= 1e-3 * relief,
            "warm GPU vs cold CPU: {d} m over {relief} m"
        );
    }
}

/// The editor's queued path: an iteration report of a replaced take, arriving after the next
/// take, must not stand for the new take's residual (the editor took the new sketch for converged
/// and stopped iterating it).
#[test]
fn a_replaced_takes_iteration_report_does_not_stand_for_the_new_take() {
    let ctx = gpu_common::device();
    let sketch = example_sketch();
    let grid = Grid::new(128, sketch.extent_m).unwrap();
    let tolerance = SolverParams::default().tolerance;
    let drain = || {
        ctx.device
            .poll(wgpu::PollType::wait_indefinitely())
            .unwrap();
    };
    // A small move taken and iterated twice, its iteration report delivered but not yet read.
    let near = moved(&sketch, 6.0);
    let take_and_iterate = || {
        let mut gpu = GpuSolver::new(&ctx, grid, SolverParams::default()).unwrap();
        gpu.solve_sketch(&sketch).unwrap();
        gpu.take_queued(&near, false).unwrap();
        drain();
        gpu.poll().unwrap();
        gpu.queue_iterations(2).unwrap();
        drain();
        gpu
    };
    // Read at once, that report says the small move converged.
    let mut gpu = take_and_iterate();
    let r = gpu
        .poll()
        .unwrap()
        .residual
        .expect("the iterations' report arrived");
    assert!(r <= tolerance, "residual {r:e} after two iterations");
    // Read after a take of a sketch moved 400 m, it says nothing of that take.
    let mut gpu = take_and_iterate();
    let far = moved(&sketch, 400.0);
    gpu.take_queued(&far, false).unwrap();
    gpu.poll().unwrap();
    assert!(gpu.residual() > tolerance, "residual {:e}", gpu.residual());
    drain();
    let r = gpu
        .poll()
        .unwrap()
        .residual
        .expect("the new take's report arrived");
    assert!(r > tolerance, "residual {r:e} after a 400 m move");
    // The new take's own iterations count.
    gpu.queue_iterations(12).unwrap();
    drain();
    let r = gpu
        .poll()
        .unwrap()
        .residual
        .expect("the iterations' report arrived");
    assert!(r <= tolerance, "residual {r:e} after 12 iterations");
}
