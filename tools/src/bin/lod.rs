//! Times the LOD selection for a 16384^2 heightmap (64x64 min/max pyramid) over the fixed
//! benchmark camera path. Run: `cargo run --release -p terrasketch-tools --bin lod`.

use terrasketch_quadtree::{LodSettings, MinMaxPyramid, bench_lod};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let extent_m = [20480.0_f32, 20480.0];
    // A synthetic relief (ridges up to about 1500 m) on a 1024^2 grid: the pyramid only keeps
    // its 64x64 min/max levels, as the solver's read-back would.
    let side = 1024;
    let heights: Vec<f32> = (0..side * side)
        .map(|k| {
            let (x, y) = (
                (k % side) as f32 / side as f32,
                (k / side) as f32 / side as f32,
            );
            let ridge = (x * 9.0 + (y * 4.0).sin()).sin() * (y * 7.0 - x * 3.0).cos();
            750.0 + 700.0 * ridge + 50.0 * (x * 91.0).sin() * (y * 83.0).cos()
        })
        .collect();
    let pyramid = MinMaxPyramid::from_heights(side, &heights, 64)?;
    for budget in [128.0, 192.0] {
        let settings = LodSettings {
            pixel_budget: budget,
            ..LodSettings::new(16384, extent_m)
        };
        let report = bench_lod(&pyramid, &settings, 300)?;
        println!(
            "n = 16384, leaf_cells = {}, pixel_budget = {budget} px, {} frames at 1920x1080: \
             select median {:.1} us (max {:.1} us), patches median {}, triangles median {}, \
             nodes median {}, max neighbour level diff {}",
            settings.leaf_cells,
            report.frames,
            report.select_us_median,
            report.select_us_max,
            report.patches_median,
            report.triangles_median,
            report.nodes_median,
            report.max_neighbour_level_diff
        );
    }
    Ok(())
}
