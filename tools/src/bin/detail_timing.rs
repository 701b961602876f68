//! Times the detail's pieces at 1024^2 (`cargo run --release -p terrasketch-tools --bin detail_timing
//! -- [SKETCH.json] [REPEATS]`): the octave sum on a constant amplitude, the amplitude map on
//! synthetic inputs and its bound pyramid (medians of 25), and with a sketch (default `examples/range.json`) `solve --size 1024`'s detail
//! path on the CPU solver, piece by piece: the heights' solve, the cold roughness solve, the hard
//! counts and amplitude map, the octave sum.
use std::time::Instant;

use terrasketch_multigrid::{CpuSolver, Grid, SolverParams};

fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let path = args.first().map_or("examples/range.json", String::as_str);
    let repeats: usize = args.get(1).and_then(|r| r.parse().ok()).unwrap_or(5);
    let n = 1024;
    let m = terrasketch_detail::amplitude_side(n);
    let amp = vec![10.0f32; m * m];
    for _ in 0..3 {
        let t = Instant::now();
        let d = terrasketch_detail::detail_field(n, [10240.0, 10240.0], &amp, 1);
        // A checksum of the bits: kernels that must give the same results are compared by it.
        let sum = d
            .iter()
            .fold(0u64, |a, v| a.rotate_left(5) ^ u64::from(v.to_bits()));
        println!("detail_field {n}: {:.1} ms (checksum {sum:016x})", ms(t));
    }
    let mip: Vec<f32> = (0..m * m).map(|k| (k % 97) as f32).collect();
    let rough = vec![0.5f32; n / 4 * n / 4];
    let counts: Vec<u32> = (0..m * m).map(|k| u32::from(k % 31 == 0)).collect();
    let mut times = Vec::new();
    let mut sum = 0u64;
    for _ in 0..25 {
        let t = Instant::now();
        let a = terrasketch_detail::amplitude_map(&terrasketch_detail::AmplitudeInputs {
            m,
            cell_m: [20.0, 20.0],
            heights: &mip,
            roughness: &rough,
            roughness_side: n / 4,
            hard: terrasketch_detail::HardCells::Counts(&counts),
        });
        times.push(ms(t));
        sum = a
            .iter()
            .fold(0u64, |s, v| s.rotate_left(5) ^ u64::from(v.to_bits()));
    }
    times.sort_by(f64::total_cmp);
    println!(
        "amplitude_map {m}: median {:.2} ms, min {:.2} ms of 25 (checksum {sum:016x})",
        times[12], times[0]
    );
    let amp: Vec<f32> = (0..m * m).map(|k| ((k * 7919) % 1013) as f32).collect();
    let sides = [64usize, 32, 16, 8, 4, 2, 1];
    let mut times = Vec::new();
    for _ in 0..25 {
        let t = Instant::now();
        let p = terrasketch_detail::max_pyramid(m, &amp, &sides);
        times.push(ms(t));
        sum = p
            .iter()
            .flatten()
            .fold(0u64, |s, v| s.rotate_left(5) ^ u64::from(v.to_bits()));
    }
    times.sort_by(f64::total_cmp);
    println!(
        "max_pyramid {m} to sides 64..1: median {:.2} ms, min {:.2} ms of 25 (checksum {sum:016x})",
        times[12], times[0]
    );
    let sketch = match terrasketch_sketch::load_sketch(std::path::Path::new(path)) {
        Ok(p) => p.sketch,
        Err(e) => {
            eprintln!("{path}: {e}");
            std::process::exit(2);
        }
    };
    let Ok(grid) = Grid::new(n, sketch.extent_m) else {
        eprintln!("{path}: no {n}^2 grid for its extent");
        std::process::exit(2);
    };
    println!("{path} at {n}^2 (ms): solve, roughness (cold), counts + amplitude, octave sum");
    for _ in 0..repeats {
        let Ok(mut s) = CpuSolver::new(grid, SolverParams::default()) else {
            return;
        };
        let t = Instant::now();
        s.set_sketch(&sketch);
        s.solve();
        let t_solve = ms(t);
        let t = Instant::now();
        let r = s.roughness().len();
        let t_rough = ms(t);
        let t = Instant::now();
        let rough = s.roughness().to_vec();
        let amp = terrasketch_detail::amplitude_map(&terrasketch_detail::AmplitudeInputs {
            m,
            cell_m: {
                let [dx, dy] = grid.cell_size_m();
                [2.0 * dx as f32, 2.0 * dy as f32]
            },
            heights: s.mip(terrasketch_detail::amplitude::AMPLITUDE_LEVEL as usize),
            roughness: &rough,
            roughness_side: n / 4,
            hard: terrasketch_detail::HardCells::Counts(&terrasketch_detail::hard_counts(
                n,
                &s.constraints().elev_weight,
            )),
        });
        let t_amp = ms(t);
        let mut h = s.heights().to_vec();
        let t = Instant::now();
        terrasketch_detail::add_detail(&mut h, n, sketch.extent_m, &amp, sketch.seed);
        let t_sum = ms(t);
        println!(
            "  {t_solve:.1}  {t_rough:.1}  {t_amp:.1}  {t_sum:.1}  ({r} {})",
            h[777]
        );
    }
}
