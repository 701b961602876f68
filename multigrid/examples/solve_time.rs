//! Times cold solves (`set_sketch` + `solve`, as `bench solver` does) of the benchmark sketch.
//! Usage: `solve_time [SIZE] [REPEAT]`. Prints the median and minimum in ms and the work units.
use std::time::Instant;
use terrasketch_multigrid::{CpuSolver, Grid, SolverParams};
use terrasketch_sketch::benchmark_sketch;

fn main() {
    let mut args = std::env::args().skip(1);
    let n: usize = args.next().and_then(|s| s.parse().ok()).unwrap_or(1024);
    let repeat: usize = args.next().and_then(|s| s.parse().ok()).unwrap_or(5);
    let sketch = benchmark_sketch();
    let Ok(grid) = Grid::new(n, sketch.extent_m) else {
        eprintln!("bad size {n}");
        return;
    };
    let Ok(mut s) = CpuSolver::new(grid, SolverParams::default()) else {
        eprintln!("cannot allocate a solver for {n}");
        return;
    };
    let mut times = Vec::new();
    let mut report = Default::default();
    for _ in 0..repeat.max(1) {
        let t = Instant::now();
        s.set_sketch(&sketch);
        report = s.solve();
        times.push(t.elapsed().as_secs_f64() * 1e3);
    }
    times.sort_by(f64::total_cmp);
    println!(
        "solve {n}: median {:.1} ms, min {:.1} ms, work_units {:.2}, field_work_units {:.2}",
        times[times.len() / 2],
        times[0],
        report.work_units,
        report.field_work_units
    );
}
