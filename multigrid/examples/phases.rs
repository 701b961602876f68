use std::time::Instant;
use terrasketch_multigrid::{Budget, ConstraintMaps, CpuSolver, Grid, SolverParams};
use terrasketch_sketch::benchmark_sketch;
fn mem() -> String {
    let s = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    s.lines()
        .filter(|l| l.starts_with("VmRSS") || l.starts_with("VmHWM"))
        .map(|l| {
            l.split_whitespace()
                .nth(1)
                .unwrap_or("0")
                .parse::<u64>()
                .unwrap_or(0)
                / 1024
        })
        .map(|m| m.to_string())
        .collect::<Vec<_>>()
        .join("/")
}

fn main() {
    let n: usize = std::env::args()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(1024);
    let sketch = benchmark_sketch();
    let grid = Grid::new(n, sketch.extent_m).unwrap();
    let t = Instant::now();
    let _m = ConstraintMaps::rasterize(&sketch, &grid);
    println!("rasterize {:?} mem(hwm/rss MB) {}", t.elapsed(), mem());
    drop(_m);
    let mut s = CpuSolver::new(grid, SolverParams::default()).unwrap();
    println!("new mem {}", mem());
    for _ in 0..2 {
        let t = Instant::now();
        s.set_sketch(&sketch);
        println!("set_sketch {:?} mem {}", t.elapsed(), mem());
        let t = Instant::now();
        let p = s.step(Budget::WorkUnits(0.0001));
        println!(
            "fields {:?} fwu {:.2} mem {}",
            t.elapsed(),
            p.field_work_units,
            mem()
        );
        let t = Instant::now();
        let mut wu = 0.0;
        loop {
            let p = s.step(Budget::WorkUnits(0.0001));
            wu += p.work_units;
            if p.finest_ready_level == Some(0) {
                break;
            }
        }
        println!("fmg {:?} wu {wu:.2} mem {}", t.elapsed(), mem());
        let t = Instant::now();
        let mut wu = 0.0;
        let mut c = 0;
        loop {
            let p = s.step(Budget::WorkUnits(0.0001));
            wu += p.work_units;
            c += 1;
            if p.converged {
                break;
            }
        }
        println!("fcg {:?} wu {wu:.2} steps {c} mem {}", t.elapsed(), mem());
    }
}
