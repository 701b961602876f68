//! Error history of a cold solve: after FMG and after each level-0 iteration, the work units so
//! far, the normalised residual, the error against a tight solve (fields and heights at 1e-7) and the
//! largest change since the previous line, all relative to the relief. The stop points of a
//! tolerance can be read off (`residual <= tolerance`), with the error they leave.
//!
//! `cargo run --release -p terrasketch-tools --bin errhist [n]`; `MOVE=k` moves stroke 0 as
//! after k frames of `bench drag`; `SKETCH=path.json` for a
//! sketch file instead of the benchmark sketch; `PRE`, `POST`, `GAMMA`, `GFROM`, `GUNTIL` for the cycle.
use terrasketch_multigrid::{Budget, CpuSolver, Grid, SolverParams};
use terrasketch_sketch::benchmark_sketch;

fn maxdiff(a: &[f32], b: &[f32]) -> f32 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f32::max)
}

fn main() {
    let n: usize = std::env::args()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(1024);
    let mut sketch = match std::env::var("SKETCH") {
        Ok(path) => {
            terrasketch_sketch::load_sketch(std::path::Path::new(&path))
                .expect("sketch")
                .sketch
        }
        Err(_) => benchmark_sketch(),
    };
    // `MOVE=k`: stroke 0 moved as after k frames of `bench drag` (6 m east, 4 m north each).
    if let Some(k) = std::env::var("MOVE")
        .ok()
        .and_then(|v| v.parse::<f64>().ok())
        && let Some(s) = sketch.strokes.first_mut()
    {
        for p in &mut s.points {
            p[0] += 6.0 * k;
            p[1] += 4.0 * k;
        }
    }
    let grid = Grid::new(n, sketch.extent_m).expect("grid");
    let env = |k: &str, d: u32| {
        std::env::var(k)
            .ok()
            .and_then(|v| v.parse().ok())
            .unwrap_or(d)
    };
    let d = SolverParams::default();
    let params = SolverParams {
        pre_sweeps: env("PRE", d.pre_sweeps),
        post_sweeps: env("POST", d.post_sweeps),
        gamma: env("GAMMA", d.gamma),
        gamma_from_level: env("GFROM", d.gamma_from_level),
        gamma_until_level: env("GUNTIL", d.gamma_until_level),
        ..d
    };
    let tight = SolverParams {
        tolerance: 1e-7,
        max_vcycles: 60,
        ..params
    };
    let mut s = CpuSolver::new(grid, tight).expect("solver");
    s.set_field_params(tight);
    s.set_sketch(&sketch);
    s.solve();
    let reference = s.heights().to_vec();
    let relief = s.relief_m();
    let mut s = CpuSolver::new(
        grid,
        SolverParams {
            tolerance: 1e-7,
            max_vcycles: 6,
            ..params
        },
    )
    .expect("solver");
    s.set_field_params(tight);
    s.set_sketch(&sketch);
    let mut prev: Option<Vec<f32>> = None;
    let mut wu = 0.0;
    println!("level-0 iterations after FMG: 0 = FMG's result");
    let mut it = 0;
    loop {
        // The work units of an iteration include the preconditioner for the next one.
        let p = s.step(Budget::WorkUnits(1e-9));
        if p.finest_ready_level == Some(0) {
            let h = s.heights();
            let err = maxdiff(h, &reference) / relief;
            let upd = prev.as_ref().map_or(f32::NAN, |q| maxdiff(h, q) / relief);
            println!(
                "it {it} wu_if_stopped_here {wu:6.2} residual {:9.3e} error {err:9.3e} change {upd:9.3e}",
                p.residual
            );
            prev = Some(h.to_vec());
            it += 1;
        }
        wu += p.work_units;
        if p.converged {
            break;
        }
    }
}
