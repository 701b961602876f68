//! The look measures of a solved terrain (`tests/look_common`), converged CPU solves:
//! - `look facets [N] [RADIUS_CELLS]`: a 12-point circular ridge on an N x N grid of 10 m cells
//!   (default 1024, radius 200 cells), closed and open: largest over median aspect step along the
//!   circles at half the band width outside and inside the curve (the open one away from its join);
//! - `look laplacian SKETCH.json [N] [HILLSHADE.pgm]`: the 99.9th percentile and the maximum of
//!   |Laplacian| more than 2 cells from every hard constraint, and a hillshade.
//!
//! `SHAPE=old` rasterises every stroke as a polyline with a constant slope to the band edge
//! (`"curve": "polyline"`, `"falloff": "none"`), as strokes were before those fields existed; for
//! the circle, the old polyline is closed by repeating its first point.
#[path = "../../../multigrid/tests/look_common/mod.rs"]
mod look_common;

use look_common::*;
use terrasketch_sketch::Sketch;

fn maybe_old(sketch: &mut Sketch) {
    if std::env::var("SHAPE").is_ok_and(|v| v == "old") {
        old_shape(sketch);
    }
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let arg = |k: usize| args.get(k).cloned();
    match arg(0).as_deref() {
        Some("facets") => {
            let n: usize = arg(1).and_then(|s| s.parse().ok()).unwrap_or(1024);
            let r: f64 = arg(2).and_then(|s| s.parse().ok()).unwrap_or(200.0);
            for closed in [true, false] {
                let mut sketch = circle_sketch(n, 12, r, 150.0, closed);
                maybe_old(&mut sketch);
                let half_band = 0.5 * sketch.strokes[0].width_m / 10.0;
                let (h, _) = solve(&sketch, n);
                for (side, radius) in [("outside", r + half_band), ("inside", r - half_band)] {
                    let steps = aspect_steps(&h, n, radius);
                    let skip = if closed {
                        0.0
                    } else {
                        2.0 * std::f64::consts::TAU / 12.0
                    };
                    let (ratio, median, max) = facet_ratio(&steps, skip);
                    println!(
                        "facets n {n} radius {r} closed {closed} {side} (r = {radius}): max/median aspect step {ratio:.2} (median {median:.4} deg, max {max:.4} deg)"
                    );
                }
            }
        }
        Some("laplacian") => {
            let path = arg(1).expect("SKETCH.json");
            let n: usize = arg(2).and_then(|s| s.parse().ok()).unwrap_or(1024);
            let mut sketch = terrasketch_sketch::load_sketch(std::path::Path::new(&path))
                .expect("sketch")
                .sketch;
            maybe_old(&mut sketch);
            let (h, w) = solve(&sketch, n);
            let (p999, max, cells) = laplacian_away_from_hard(&h, &w, n, 2);
            println!(
                "laplacian {path} n {n}: |L| more than 2 cells from hard constraints ({cells} cells): p99.9 {p999:.4} m, max {max:.4} m"
            );
            if let Some(out) = arg(3) {
                let cell = sketch.extent_m[0] / n as f64;
                write_pgm(std::path::Path::new(&out), &hillshade(&h, n, cell), n).expect("write");
            }
        }
        _ => {
            eprintln!("usage: look facets [N] [RADIUS] | look laplacian SKETCH.json [N] [OUT.pgm]")
        }
    }
}
