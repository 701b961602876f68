//! Times the rasteriser on the benchmark sketch and prints a checksum of the maps (to check that an
//! optimisation does not change what it computes). Usage: `raster [SIZE] [REPEAT]`; `SHAPE=old`
//! rasterises every stroke as a polyline with a constant slope to the band edge (`"curve":
//! "polyline"`, `"falloff": "none"`: the maps of the code before those fields existed).
use std::time::Instant;
use terrasketch_multigrid::{ConstraintMaps, Grid};
use terrasketch_sketch::benchmark_sketch;

fn checksum(v: &[f32]) -> u64 {
    v.iter().fold(0xcbf29ce484222325u64, |h, x| {
        (h ^ x.to_bits() as u64).wrapping_mul(0x100000001b3)
    })
}

fn main() {
    let mut args = std::env::args().skip(1);
    let n: usize = args.next().and_then(|s| s.parse().ok()).unwrap_or(1024);
    let repeat: usize = args.next().and_then(|s| s.parse().ok()).unwrap_or(5);
    let mut sketch = benchmark_sketch();
    if std::env::var("SHAPE").is_ok_and(|v| v == "old") {
        for s in &mut sketch.strokes {
            s.curve = terrasketch_sketch::CurveKind::Polyline;
            s.falloff = terrasketch_sketch::Falloff::None;
        }
    }
    let Ok(grid) = Grid::new(n, sketch.extent_m) else {
        eprintln!("bad size {n}");
        return;
    };
    let mut times = Vec::new();
    let mut maps = ConstraintMaps::new(n);
    for _ in 0..repeat {
        let t = Instant::now();
        maps = ConstraintMaps::rasterize(&sketch, &grid);
        times.push(t.elapsed().as_secs_f64() * 1e3);
    }
    times.sort_by(f64::total_cmp);
    println!(
        "rasterize {n}: median {:.2} ms, min {:.2} ms",
        times[times.len() / 2],
        times[0]
    );
    for (name, v) in [
        ("elev_weight", &maps.elev_weight),
        ("elev_value", &maps.elev_value),
        ("band_weight", &maps.band_weight),
        ("grad_x", &maps.grad_x),
        ("grad_y", &maps.grad_y),
        ("rough_weight", &maps.rough_weight),
        ("rough_value", &maps.rough_value),
    ] {
        println!("{name:>12} {:016x}", checksum(v));
    }
}
