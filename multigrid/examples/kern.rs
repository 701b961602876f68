//! Times the CPU kernels (default 1024^2; prints "min / median" of repeated runs).
//!
//! `cargo run --release -p terrasketch-multigrid --example kern [n]`: every kernel once.
//! Other modes, chosen by environment variable:
//! - `ONLY=<kernel>` (`pre`, `post`, `cycle`, `sweep0`, `sweep1`, `sweepk` with `LEVEL=k`, `levels`,
//!   `assemble`, `fmg`, `dir`, `upd`), `PROB=1` for the benchmark sketch's constraints: one kernel
//!   in a loop (for `perf record`).
//! - `BENCH=<n>` (`NO_DRAG=1`, `NO_SOLVE=1`, `REPS=`): the `bench solver` / `bench drag` workloads.
//! - `FIELDS=<n>`: the pieces of a cold solve (field solves, edge differences, heights).
//! - `FIELD_TOL=<n>`, `SCHEDULE=<n>`, `PAR_FIELDS=<n>`: schedule experiments.
//! - `STATS=1`: standard / general / inactive cells per coarse level.

use std::time::{Duration, Instant};

use terrasketch_multigrid::{
    Budget, ConstraintMaps, CpuSolver, FieldProblem, Grid, SolverParams, cpu::Fcg, cpu::Hierarchy,
};
use terrasketch_sketch::benchmark_sketch;

/// Times the pieces of a cold solve's field phase with the public API (as `CpuSolver` runs them).
fn fields(n: usize) {
    use terrasketch_multigrid::fields;
    let sketch = benchmark_sketch();
    let grid = Grid::new(n, sketch.extent_m).unwrap();
    let maps = ConstraintMaps::rasterize(&sketch, &grid);
    let [ax, ay] = grid.axis_weights();
    let params = SolverParams::default();
    let fparams = SolverParams {
        tolerance: params.tolerance.max(1e-4),
        ..params
    };
    let mut grad = Hierarchy::new(n / 2, ax, ay);
    let mut rough = Hierarchy::new(n / 4, ax, ay);
    let mut heights = Hierarchy::new(n, ax, ay);
    let (mut gx, mut gy, mut rs, mut hs) = (
        grad.new_state(),
        grad.new_state(),
        rough.new_state(),
        heights.new_state(),
    );
    for _ in 0..3 {
        let t = Instant::now();
        let (mut px, vy) = fields::gradient_problem(&grid, &maps);
        let pr = fields::roughness_problem(&grid, &maps);
        let t_down = t.elapsed();
        let t = Instant::now();
        grad.assemble(&px);
        let t_ga = t.elapsed();
        let t = Instant::now();
        let (sx, ix) = grad.solve(&mut gx, &fparams);
        let t_gx = t.elapsed();
        let t = Instant::now();
        px.value = vy;
        grad.assemble_values_rows(&px, 0..n / 2);
        let (sy, iy) = grad.solve(&mut gy, &fparams);
        let t_gy = t.elapsed();
        let t = Instant::now();
        rough.assemble(&pr);
        let (sr, ir) = rough.solve(&mut rs, &fparams);
        let t_r = t.elapsed();
        let t = Instant::now();
        let (mut de, mut dn) = (vec![0.0; n * n], vec![0.0; n * n]);
        fields::edge_differences(&grid, &maps, (&gx.h, &gy.h), 0..n, (&mut de, &mut dn));
        let t_e = t.elapsed();
        let p = FieldProblem {
            n,
            ax,
            ay,
            weight: maps.elev_weight.clone(),
            value: maps.elev_value.clone(),
            d_east: de,
            d_north: dn,
        };
        let t = Instant::now();
        heights.assemble(&p);
        let t_ha = t.elapsed();
        let t = Instant::now();
        let (sh, ih) = heights.solve(&mut hs, &params);
        let t_hs = t.elapsed();
        let t = Instant::now();
        heights.fmg(&mut hs, &params);
        let t_fmg = t.elapsed();
        let mut fcg = Fcg::default();
        fcg.start(&heights, &mut hs, &params);
        let t = Instant::now();
        fcg.start(&heights, &mut hs, &params);
        let t_start = t.elapsed();
        let t = Instant::now();
        let mut k = 0;
        while fcg.residual > params.tolerance && k < 40 {
            fcg.iterate(&heights, &mut hs, &params);
            k += 1;
        }
        println!(
            "   heights: fmg {t_fmg:.2?}, fcg start (warm buffers) {t_start:.2?}, {k} iterations {:.2?}",
            t.elapsed()
        );
        println!(
            "n={n}: downsample {t_down:.2?}, grad assemble {t_ga:.2?}, gx solve {t_gx:.2?} ({ix} it, {:.1} WU), gy values+solve {t_gy:.2?} ({iy} it, {:.1} WU), rough assemble+solve {t_r:.2?} ({ir} it, {:.1} WU), edge differences {t_e:.2?}, heights assemble {t_ha:.2?}, heights solve {t_hs:.2?} ({ih} it, {:.1} WU)",
            sx.work_units, sy.work_units, sr.work_units, sh.work_units
        );
    }
}

/// Schedule experiment: how the field tolerance changes field-solve time and the final heights.
fn field_tolerance(n: usize) {
    use terrasketch_multigrid::fields;
    let sketch = benchmark_sketch();
    let grid = Grid::new(n, sketch.extent_m).unwrap();
    let maps = ConstraintMaps::rasterize(&sketch, &grid);
    let [ax, ay] = grid.axis_weights();
    let params = SolverParams::default();
    let mut reference: Option<Vec<f32>> = None;
    for tol in [1e-6f32, 3e-4, 1e-3, 3e-3, 1e-2, 1.0] {
        let fparams = SolverParams {
            tolerance: tol,
            ..params
        };
        let mut grad = Hierarchy::new(n / 2, ax, ay);
        let (mut px, vy) = fields::gradient_problem(&grid, &maps);
        grad.assemble(&px);
        let (mut gx, mut gy) = (grad.new_state(), grad.new_state());
        grad.solve(&mut gx, &fparams);
        let t = Instant::now();
        let (_, ix) = grad.solve(&mut gx, &fparams);
        px.value = vy;
        grad.assemble_values_rows(&px, 0..n / 2);
        let (_, iy) = grad.solve(&mut gy, &fparams);
        let t_fields = t.elapsed();
        let (mut de, mut dn) = (vec![0.0; n * n], vec![0.0; n * n]);
        fields::edge_differences(&grid, &maps, (&gx.h, &gy.h), 0..n, (&mut de, &mut dn));
        let p = FieldProblem {
            n,
            ax,
            ay,
            weight: maps.elev_weight.clone(),
            value: maps.elev_value.clone(),
            d_east: de,
            d_north: dn,
        };
        let mut heights = Hierarchy::new(n, ax, ay);
        heights.assemble(&p);
        let mut hs = heights.new_state();
        heights.solve(
            &mut hs,
            &SolverParams {
                tolerance: 1e-6,
                ..params
            },
        );
        let relief = heights.relief();
        let err = reference.as_ref().map_or(0.0, |r| {
            r.iter()
                .zip(&hs.h)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0f32, f32::max)
                / relief
        });
        println!(
            "field tolerance {tol:.0e}: gradient solves {t_fields:.2?} ({ix} + {iy} iterations), heights vs tight fields: {err:.2e}"
        );
        if reference.is_none() {
            reference = Some(hs.h.clone());
        }
    }
}

/// Schedule experiment: cycle shapes for the heights solve (time, iterations, error vs converged).
fn schedule(n: usize) {
    use terrasketch_multigrid::fields;
    let sketch = benchmark_sketch();
    let grid = Grid::new(n, sketch.extent_m).unwrap();
    let maps = ConstraintMaps::rasterize(&sketch, &grid);
    let [ax, ay] = grid.axis_weights();
    let base = SolverParams::default();
    let mut grad = Hierarchy::new(n / 2, ax, ay);
    let (mut px, vy) = fields::gradient_problem(&grid, &maps);
    grad.assemble(&px);
    let (mut gx, mut gy) = (grad.new_state(), grad.new_state());
    grad.solve(&mut gx, &base);
    px.value = vy;
    grad.assemble_values_rows(&px, 0..n / 2);
    grad.solve(&mut gy, &base);
    let (mut de, mut dn) = (vec![0.0; n * n], vec![0.0; n * n]);
    fields::edge_differences(&grid, &maps, (&gx.h, &gy.h), 0..n, (&mut de, &mut dn));
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
    let mut conv = h.new_state();
    h.solve(
        &mut conv,
        &SolverParams {
            tolerance: 1e-7,
            max_vcycles: 80,
            ..base
        },
    );
    let relief = h.relief();
    let cases = [
        ("W from level 1 (default)", base),
        ("V everywhere", SolverParams { gamma: 1, ..base }),
        (
            "W from level 2",
            SolverParams {
                gamma_from_level: 2,
                ..base
            },
        ),
        (
            "W from level 3",
            SolverParams {
                gamma_from_level: 3,
                ..base
            },
        ),
        (
            "W(2,1) from level 1",
            SolverParams {
                pre_sweeps: 2,
                ..base
            },
        ),
        (
            "W(1,2) from level 1",
            SolverParams {
                post_sweeps: 2,
                ..base
            },
        ),
    ];
    for (name, params) in cases {
        let mut st = h.new_state();
        h.solve(&mut st, &params);
        let mut times = Vec::new();
        let mut res = (Default::default(), 0);
        for _ in 0..5 {
            let mut st2 = h.new_state();
            let t = Instant::now();
            res = h.solve(&mut st2, &params);
            times.push(t.elapsed());
            st = st2;
        }
        times.sort();
        let err =
            st.h.iter()
                .zip(&conv.h)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0f32, f32::max)
                / relief;
        let (stats, it): (terrasketch_multigrid::cpu::CycleStats, u32) = res;
        println!(
            "{name:>26}: {:>9.2?} median, {it} iterations, {:.1} WU, residual {:.1e}, error vs converged {err:.1e}",
            times[2], stats.work_units, stats.residual
        );
    }
}

/// Schedule experiment: the two gradient-field solves one after the other vs concurrently
/// (`rayon::join`, one hierarchy per right-hand side).
fn par_fields(n: usize) {
    use terrasketch_multigrid::fields;
    let sketch = benchmark_sketch();
    let grid = Grid::new(n, sketch.extent_m).unwrap();
    let maps = ConstraintMaps::rasterize(&sketch, &grid);
    let [ax, ay] = grid.axis_weights();
    let params = SolverParams::default();
    let (mut px, vy) = fields::gradient_problem(&grid, &maps);
    let mut ha = Hierarchy::new(n / 2, ax, ay);
    ha.assemble(&px);
    px.value = vy;
    let mut hb = Hierarchy::new(n / 2, ax, ay);
    hb.assemble(&px);
    let (mut a, mut b) = (ha.new_state(), hb.new_state());
    let mut seq = Vec::new();
    let mut par = Vec::new();
    for _ in 0..7 {
        let t = Instant::now();
        ha.solve(&mut a, &params);
        hb.solve(&mut b, &params);
        seq.push(t.elapsed());
        let t = Instant::now();
        rayon::join(|| ha.solve(&mut a, &params), || hb.solve(&mut b, &params));
        par.push(t.elapsed());
    }
    seq.sort();
    par.sort();
    println!(
        "gradient solves at {}: sequential {:.2?}, concurrent {:.2?} (medians)",
        n / 2,
        seq[3],
        par[3]
    );
}

/// What `terrasketch bench solver` and `bench drag` time, without the app: cold solves of the
/// benchmark sketch (rasterisation included) and warm updates while dragging stroke 0.
fn bench(size: usize) {
    let mut sketch = benchmark_sketch();
    let grid = Grid::new(size, sketch.extent_m).unwrap();
    let mut s = CpuSolver::new(grid, SolverParams::default()).unwrap();
    let reps = if std::env::var("NO_SOLVE").is_ok() {
        1
    } else {
        std::env::var("REPS")
            .ok()
            .and_then(|s| s.parse().ok())
            .unwrap_or(if size >= 4096 { 1 } else { 7 })
    };
    let mut times = Vec::new();
    let mut rep = Default::default();
    for _ in 0..reps {
        let t = Instant::now();
        s.set_sketch(&sketch);
        rep = s.solve();
        times.push(t.elapsed().as_secs_f64() * 1e3);
    }
    times.sort_by(f64::total_cmp);
    println!(
        "solver {size}: min {:.1} ms, median {:.1} ms; {rep:?}",
        times[0],
        times[reps / 2]
    );
    if size > 2048 || std::env::var("NO_DRAG").is_ok() {
        return;
    }
    let mut times = Vec::new();
    for _ in 0..60 {
        let old = ConstraintMaps::stroke_rows(&sketch, 0, &grid);
        for p in &mut sketch.strokes[0].points {
            p[0] += 6.0;
            p[1] += 4.0;
        }
        let new = ConstraintMaps::stroke_rows(&sketch, 0, &grid);
        let t = Instant::now();
        s.update_sketch(&sketch, old.start.min(new.start)..old.end.max(new.end));
        while !s.step(Budget::Unlimited).converged {}
        times.push(t.elapsed().as_secs_f64() * 1e3);
    }
    times.sort_by(f64::total_cmp);
    println!(
        "drag {size}: p50 {:.1} ms, min {:.1} ms, p95 {:.1} ms",
        times[30], times[0], times[57]
    );
}

/// Wall time of `reps` runs of `f`: "min / median" (the minimum is robust on a shared machine).
fn time(reps: usize, mut f: impl FnMut()) -> String {
    f();
    let mut t: Vec<Duration> = (0..reps)
        .map(|_| {
            let s = Instant::now();
            f();
            s.elapsed()
        })
        .collect();
    t.sort();
    format!("{:>10.3?} / {:>10.3?}", t[0], t[reps / 2])
}

fn main() {
    if let Ok(size) = std::env::var("BENCH") {
        bench(size.parse().unwrap_or(1024));
        return;
    }
    if let Ok(size) = std::env::var("FIELDS") {
        fields(size.parse().unwrap_or(1024));
        return;
    }
    if let Ok(size) = std::env::var("FIELD_TOL") {
        field_tolerance(size.parse().unwrap_or(1024));
        return;
    }
    if let Ok(size) = std::env::var("SCHEDULE") {
        schedule(size.parse().unwrap_or(1024));
        return;
    }
    if let Ok(size) = std::env::var("PAR_FIELDS") {
        par_fields(size.parse().unwrap_or(1024));
        return;
    }
    if std::env::var("STATS").is_ok() {
        // Cell kinds per level for the benchmark sketch's height problem.
        let sketch = benchmark_sketch();
        for n in [256usize, 1024] {
            let grid = Grid::new(n, sketch.extent_m).unwrap();
            let maps = ConstraintMaps::rasterize(&sketch, &grid);
            let [ax, ay] = grid.axis_weights();
            let p = FieldProblem {
                n,
                ax,
                ay,
                weight: maps.elev_weight.clone(),
                value: maps.elev_value.clone(),
                ..Default::default()
            };
            let mut h = Hierarchy::new(n, ax, ay);
            h.assemble(&p);
            for (side, s, g, i) in h.level_stats() {
                let t = (side * side) as f64 / 100.0;
                println!(
                    "n={n} level side {side:>4}: standard {:5.1}%, general {:5.1}%, inactive {:5.1}%",
                    s as f64 / t,
                    g as f64 / t,
                    i as f64 / t
                );
            }
        }
        return;
    }
    if let Ok(only) = std::env::var("ONLY") {
        // Profiling aid: one kernel in a loop.
        let n = 1024;
        let p = if std::env::var("PROB").is_ok() {
            // The benchmark sketch's elevation constraints (no prescribed differences).
            let sketch = benchmark_sketch();
            let grid = Grid::new(n, sketch.extent_m).unwrap();
            let maps = ConstraintMaps::rasterize(&sketch, &grid);
            FieldProblem {
                n,
                ax: 1.0,
                ay: 1.0,
                weight: maps.elev_weight.clone(),
                value: maps.elev_value.clone(),
                ..Default::default()
            }
        } else {
            let mut p = FieldProblem {
                n,
                ax: 1.0,
                ay: 1.0,
                weight: vec![0.0; n * n],
                value: vec![0.0; n * n],
                ..Default::default()
            };
            for i in 0..n {
                p.weight[(n / 2) * n + i] = 1.0;
            }
            p
        };
        let mut h = Hierarchy::new(n, 1.0, 1.0);
        h.assemble(&p);
        let mut st = h.new_state();
        let params = SolverParams::default();
        let mut z = vec![0.0; n * n];
        let r = vec![1.0; n * n];
        let t = match only.as_str() {
            "cycle" => time(200, || h.bench_coarse_cycle(&mut st, &params)),
            "pre" => time(500, || h.bench_pre_phase(&r, &mut z, &mut st)),
            "post" => time(500, || h.bench_post_phase(&r, &mut z, &mut st)),
            "sweep1" => time(500, || h.bench_coarse_sweep(1, &mut st)),
            "sweepk" => {
                let k = std::env::var("LEVEL")
                    .ok()
                    .and_then(|s| s.parse().ok())
                    .unwrap_or(4);
                time(20000, || h.bench_coarse_sweep(k, &mut st))
            }
            "levels" => {
                for k in 1..h.levels() - 1 {
                    println!(
                        "level {k} sweep {}",
                        time(200, || h.bench_coarse_sweep(k, &mut st))
                    );
                }
                time(1, || {})
            }
            "assemble" => time(50, || h.assemble(&p)),
            "fmg" => time(50, || {
                h.fmg(&mut st, &params);
            }),
            "dir" | "upd" => {
                let (mut pp, mut q, mut rr) =
                    (vec![0.0; n * n], vec![0.0; n * n], vec![1.0; n * n]);
                let which = if only == "dir" { 0 } else { 1 };
                time(200, || {
                    h.bench_fcg_passes(&z, &mut pp, &mut q, &mut rr, &mut st, which)
                })
            }
            _ => time(500, || h.bench_level0_sweep(&mut st)),
        };
        println!("{only} {t}");
        return;
    }
    let n: usize = std::env::args()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(1024);
    let mut p = FieldProblem {
        n,
        ax: 1.0,
        ay: 1.0,
        weight: vec![0.0; n * n],
        value: vec![0.0; n * n],
        ..Default::default()
    };
    for i in 0..n {
        p.weight[(n / 2) * n + i] = 1.0;
        p.value[(n / 2) * n + i] = 100.0;
    }
    let mut h = Hierarchy::new(n, 1.0, 1.0);
    println!("n = {n}");
    println!("assemble                 {}", time(15, || h.assemble(&p)));
    let mut st = h.new_state();
    let params = SolverParams::default();
    println!(
        "level0 sweep             {}",
        time(60, || h.bench_level0_sweep(&mut st))
    );
    println!(
        "level0 residual_restrict {}",
        time(60, || h.bench_level0_residual(&mut st))
    );
    println!(
        "level1 sweep             {}",
        time(60, || h.bench_coarse_sweep(1, &mut st))
    );
    for k in 2..h.levels() - 1 {
        println!(
            "level{k} sweep             {}",
            time(60, || h.bench_coarse_sweep(k, &mut st))
        );
    }
    let mut z = vec![0.0; n * n];
    let r = vec![1.0; n * n];
    println!(
        "pre phase (fused)        {}",
        time(60, || h.bench_pre_phase(&r, &mut z, &mut st))
    );
    println!(
        "coarse cycle (level 1)   {}",
        time(60, || h.bench_coarse_cycle(&mut st, &params))
    );
    println!(
        "post phase (fused)       {}",
        time(60, || h.bench_post_phase(&r, &mut z, &mut st))
    );
    println!(
        "precondition             {}",
        time(60, || {
            h.precondition(&r, &mut z, &mut st, &params);
        })
    );
    let mut st = h.new_state();
    println!(
        "fmg                      {}",
        time(15, || {
            h.fmg(&mut st, &params);
        })
    );
    let mut fcg = Fcg::default();
    fcg.start(&h, &mut st, &params);
    let p0 = SolverParams {
        tolerance: 0.0,
        ..params
    };
    println!(
        "fcg iteration            {}",
        time(30, || {
            fcg.iterate(&h, &mut st, &p0);
        })
    );
}
