//! Times the CPU kernels at 1024^2 (median of repeated runs).
//!
//! `cargo run --release -p terrasketch-multigrid --example kern [n]`

use std::time::{Duration, Instant};

use terrasketch_multigrid::{
    Budget, ConstraintMaps, CpuSolver, FieldProblem, Grid, SolverParams, cpu::Fcg, cpu::Hierarchy,
};
use terrasketch_sketch::benchmark_sketch;

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
