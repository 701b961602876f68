//! Error of a long drag of warm updates: moves stroke 0 of the benchmark sketch as `bench drag` does
//! (6 m east, 4 m north per frame, only the moved texels re-rasterised, solved warm to the default
//! tolerance) and every `EVERY` frames prints the error against a converged solve (fields and
//! heights at 1e-7), relative to the relief, with the level-0 iterations and the residuals of the
//! updates since the last line.
//!
//! `cargo run --release -p terrasketch-tools --bin drift [n] [frames]` (defaults 1024, 300);
//! `EVERY=k` (default 30); `WHERE=1` also prints where the largest error is and the box of the cells
//! above half of it; `TOL=t` solves the warm updates to tolerance `t` instead of the default.
use terrasketch_multigrid::{Budget, ConstraintMaps, CpuSolver, Grid, SolverParams};
use terrasketch_sketch::{Sketch, benchmark_sketch};

fn converged(grid: Grid, sketch: &Sketch) -> (Vec<f32>, f32) {
    let tight = SolverParams {
        tolerance: 1e-7,
        max_vcycles: 60,
        ..SolverParams::default()
    };
    let mut s = CpuSolver::new(grid, tight).expect("solver");
    s.set_field_params(tight);
    s.set_sketch(sketch);
    s.solve();
    (s.heights().to_vec(), s.relief_m())
}

fn main() {
    let arg = |i: usize, d: usize| {
        std::env::args()
            .nth(i)
            .and_then(|s| s.parse().ok())
            .unwrap_or(d)
    };
    let (n, frames) = (arg(1, 1024), arg(2, 300));
    let every: usize = std::env::var("EVERY")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(30)
        .max(1);
    let mut sketch = benchmark_sketch();
    let grid = Grid::new(n, sketch.extent_m).expect("grid");
    let mut s = CpuSolver::new(grid, SolverParams::default()).expect("solver");
    s.set_sketch(&sketch);
    s.solve();
    if let Some(t) = std::env::var("TOL")
        .ok()
        .and_then(|v| v.parse::<f32>().ok())
    {
        s.set_params(SolverParams {
            tolerance: t,
            ..SolverParams::default()
        });
    }
    let (mut iters, mut zero, mut rmax) = (Vec::new(), 0, 0.0f32);
    for frame in 1..=frames {
        let mut spans = ConstraintMaps::stroke_spans(&sketch, 0, &grid);
        for p in &mut sketch.strokes[0].points {
            p[0] += 6.0;
            p[1] += 4.0;
        }
        spans.extend(ConstraintMaps::stroke_spans(&sketch, 0, &grid));
        s.update_sketch_spans(&sketch, &spans);
        let mut cycles = 0;
        loop {
            let p = s.step(Budget::Unlimited);
            cycles += p.vcycles;
            if p.converged {
                rmax = rmax.max(p.residual);
                break;
            }
        }
        zero += (cycles == 0) as usize;
        iters.push(cycles);
        if frame % every == 0 {
            let (reference, relief) = converged(grid, &sketch);
            // Per cell, relative to the relief; the largest is the reported error.
            let errs: Vec<f32> = s
                .heights()
                .iter()
                .zip(&reference)
                .map(|(a, b)| (a - b).abs() / relief)
                .collect();
            let err = errs.iter().copied().fold(0.0f32, f32::max);
            if std::env::var_os("WHERE").is_some() {
                let (mut bx, mut by, mut cnt) = ((n, 0), (n, 0), 0);
                let mut at = (0, 0);
                for (k, e) in errs.iter().enumerate() {
                    if *e == err {
                        at = (k % n, k / n);
                    }
                    if *e > 0.5 * err {
                        cnt += 1;
                        bx = (bx.0.min(k % n), bx.1.max(k % n));
                        by = (by.0.min(k / n), by.1.max(k / n));
                    }
                }
                println!("  max at {at:?}; {cnt} cells above half of it, in x {bx:?} y {by:?}");
            }
            let mean = iters.iter().sum::<u32>() as f64 / iters.len() as f64;
            println!(
                "frame {frame:4}  error {err:.3e}  iterations/update {mean:.2} (0 in {zero})  max final residual {rmax:.2e}"
            );
            (iters, zero, rmax) = (Vec::new(), 0, 0.0);
        }
    }
}
