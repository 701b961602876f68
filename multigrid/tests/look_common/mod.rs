//! What a person sees in a solved terrain, as numbers (`../shared/LOOK.md`-style measures used by
//! the look tests and `tools/src/bin/look.rs`): aspect steps along a circle (facets), the Laplacian away
//! from hard constraints (creases at band edges), and hillshades. Heights are the solver's, row 0 =
//! south, `n x n`, square cells of `cell_m`.
#![allow(dead_code)]

use terrasketch_multigrid::{CpuSolver, Grid, SolverParams};
use terrasketch_sketch::{Sketch, Stroke, StrokeKind};

/// Every stroke as a polyline with a constant slope to the band edge (`"curve": "polyline"`,
/// `"falloff": "none"`: how strokes were rasterised before those fields existed); a closed stroke
/// becomes an open polyline that repeats its first point.
pub fn old_shape(sketch: &mut Sketch) {
    for s in &mut sketch.strokes {
        s.curve = terrasketch_sketch::CurveKind::Polyline;
        s.falloff = terrasketch_sketch::Falloff::None;
        if s.closed {
            let first = s.points[0];
            s.points.push(first);
            s.closed = false;
        }
    }
}

/// A converged CPU solve of `sketch` on an `n x n` grid: heights and the elevation weight map.
pub fn solve(sketch: &Sketch, n: usize) -> (Vec<f32>, Vec<f32>) {
    let grid = Grid::new(n, sketch.extent_m).expect("grid");
    let params = SolverParams {
        tolerance: 1e-6,
        max_vcycles: 60,
        ..SolverParams::default()
    };
    let mut s = CpuSolver::new(grid, params).expect("solver");
    s.set_sketch(sketch);
    s.solve();
    (s.heights().to_vec(), s.constraints().elev_weight.clone())
}

/// A ridge through `count` points on a circle of `radius_cells` around the centre of an `n x n`
/// grid of 10 m cells, crest at 1000 m, base 0, default ridge attributes but a band of
/// `width_cells`. `closed`: a loop (the format's `closed`); else open (the stroke ends at its first
/// point's neighbour).
pub fn circle_sketch(
    n: usize,
    count: usize,
    radius_cells: f64,
    width_cells: f64,
    closed: bool,
) -> Sketch {
    let cell = 10.0;
    let c = 0.5 * n as f64 * cell;
    let r = radius_cells * cell;
    let points = (0..count)
        .map(|k| {
            let a = std::f64::consts::TAU * k as f64 / count as f64;
            [c + r * a.cos(), c + r * a.sin(), 1000.0]
        })
        .collect();
    let mut stroke = Stroke::new(StrokeKind::Ridge, points);
    stroke.closed = closed;
    stroke.width_m = width_cells * cell;
    Sketch {
        extent_m: [n as f64 * cell; 2],
        base_elevation_m: 0.0,
        seed: 0,
        strokes: vec![stroke],
    }
}

/// Heights' gradient (central differences, per cell) at a point in cells (bilinear in the
/// gradients of the four texels around it).
fn gradient_at(h: &[f32], n: usize, x: f64, y: f64) -> (f64, f64) {
    let g = |i: usize, j: usize| {
        let at = |i: usize, j: usize| h[j * n + i] as f64;
        (
            0.5 * (at(i + 1, j) - at(i - 1, j)),
            0.5 * (at(i, j + 1) - at(i, j - 1)),
        )
    };
    let (fx, fy) = (x - 0.5, y - 0.5);
    let (i0, j0) = (fx.floor() as usize, fy.floor() as usize);
    let (tx, ty) = (fx - i0 as f64, fy - j0 as f64);
    let mut out = (0.0, 0.0);
    for (i, j, w) in [
        (i0, j0, (1.0 - tx) * (1.0 - ty)),
        (i0 + 1, j0, tx * (1.0 - ty)),
        (i0, j0 + 1, (1.0 - tx) * ty),
        (i0 + 1, j0 + 1, tx * ty),
    ] {
        let (gx, gy) = g(i, j);
        out.0 += w * gx;
        out.1 += w * gy;
    }
    out
}

/// Steps of the aspect (degrees) between neighbouring samples one cell apart along the circle of
/// `radius_cells` around the grid's centre, with the sample's angle on the circle (radians from
/// east, counter-clockwise).
pub fn aspect_steps(h: &[f32], n: usize, radius_cells: f64) -> Vec<(f64, f64)> {
    let c = 0.5 * n as f64;
    let count = (std::f64::consts::TAU * radius_cells).round() as usize;
    let aspect = |k: usize| {
        let a = std::f64::consts::TAU * k as f64 / count as f64;
        let (gx, gy) = gradient_at(h, n, c + radius_cells * a.cos(), c + radius_cells * a.sin());
        gy.atan2(gx)
    };
    (0..count)
        .map(|k| {
            let d = aspect((k + 1) % count) - aspect(k);
            let d =
                (d + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU) - std::f64::consts::PI;
            let a = std::f64::consts::TAU * (k as f64 + 0.5) / count as f64;
            (a, d.abs().to_degrees())
        })
        .collect()
}

/// Largest step over the median step, of the steps whose angle is farther than `skip_rad` from
/// angle 0 (the join of an open circle; 0 keeps every step).
pub fn facet_ratio(steps: &[(f64, f64)], skip_rad: f64) -> (f64, f64, f64) {
    let mut s: Vec<f64> = steps
        .iter()
        .filter(|(a, _)| a.min(std::f64::consts::TAU - a) > skip_rad)
        .map(|(_, d)| *d)
        .collect();
    s.sort_by(f64::total_cmp);
    let (median, max) = (s[s.len() / 2], s[s.len() - 1]);
    (max / median, median, max)
}

/// The 5-point Laplacian (metres: sum of the 4 neighbours minus 4 times the cell) at the interior
/// cells more than `clear` cells (Chebyshev) from every hard cell (`weight >= 1`), as
/// (99.9th percentile of |L|, max |L|, cells counted).
pub fn laplacian_away_from_hard(
    h: &[f32],
    weight: &[f32],
    n: usize,
    clear: usize,
) -> (f64, f64, usize) {
    // Distance to the nearest hard cell, dilated `clear` times.
    let mut near = weight.iter().map(|&w| w >= 1.0).collect::<Vec<bool>>();
    for _ in 0..clear {
        let prev = near.clone();
        for j in 0..n {
            for i in 0..n {
                if prev[j * n + i] {
                    continue;
                }
                let hit = (j.saturating_sub(1)..(j + 2).min(n))
                    .any(|jj| (i.saturating_sub(1)..(i + 2).min(n)).any(|ii| prev[jj * n + ii]));
                near[j * n + i] = hit;
            }
        }
    }
    let mut l: Vec<f64> = Vec::new();
    for j in 1..n - 1 {
        for i in 1..n - 1 {
            if near[j * n + i] {
                continue;
            }
            let at = |i: usize, j: usize| h[j * n + i] as f64;
            let v = at(i + 1, j) + at(i - 1, j) + at(i, j + 1) + at(i, j - 1) - 4.0 * at(i, j);
            l.push(v.abs());
        }
    }
    l.sort_by(f64::total_cmp);
    let p = l[((l.len() as f64 * 0.999) as usize).min(l.len() - 1)];
    (p, l[l.len() - 1], l.len())
}

/// Hillshade (sun azimuth 315, altitude 45 degrees), one byte per cell, north-up (row 0 = north).
pub fn hillshade(h: &[f32], n: usize, cell_m: f64) -> Vec<u8> {
    let (az, alt) = (315f64.to_radians(), 45f64.to_radians());
    let light = [alt.cos() * az.sin(), alt.cos() * az.cos(), alt.sin()];
    let mut out = vec![0u8; n * n];
    for j in 0..n {
        for i in 0..n {
            let at = |i: usize, j: usize| h[j.min(n - 1) * n + i.min(n - 1)] as f64;
            let (il, ir) = (i.saturating_sub(1), (i + 1).min(n - 1));
            let (jd, ju) = (j.saturating_sub(1), (j + 1).min(n - 1));
            let gx = (at(ir, j) - at(il, j)) / ((ir - il) as f64 * cell_m);
            let gy = (at(i, ju) - at(i, jd)) / ((ju - jd) as f64 * cell_m);
            let norm = (gx * gx + gy * gy + 1.0).sqrt();
            let shade = (-gx * light[0] - gy * light[1] + light[2]) / norm;
            out[(n - 1 - j) * n + i] = (shade.clamp(0.0, 1.0) * 255.0).round() as u8;
        }
    }
    out
}

/// Writes a greyscale PGM (binary).
pub fn write_pgm(path: &std::path::Path, pixels: &[u8], n: usize) -> std::io::Result<()> {
    let mut data = format!("P5\n{n} {n}\n255\n").into_bytes();
    data.extend_from_slice(pixels);
    std::fs::write(path, data)
}
