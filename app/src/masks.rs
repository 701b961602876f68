//! `terrasketch masks`: texturing masks of a heightmap (slope, hillshade, curvature, flow
//! accumulation, normalised height). Definitions and ranges are in app/README.md.
//!
//! Derivatives use 3 x 3 finite differences on the north-up grid (x east, y north); past the
//! border the heights are extended linearly (`2 z_edge - z_inner`), which keeps planes exact up
//! to the edge.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use clap::ValueEnum;
use terrasketch_raster::{
    Format, Heightmap, Stretch, WriteOptions, read_heightmap, write_file_atomically,
    write_grey8_png, write_heightmap_with,
};

use crate::output::refused;

/// Sun azimuth of the hillshade, degrees clockwise from north.
const SUN_AZIMUTH_DEG: f64 = 315.0;
/// Sun altitude of the hillshade, degrees above the horizon.
const SUN_ALTITUDE_DEG: f64 = 45.0;

/// File format of the 16-bit masks (the hillshade is always an 8-bit PNG).
#[derive(Copy, Clone, Debug, PartialEq, Eq, ValueEnum)]
pub enum MaskFormat {
    /// 16-bit greyscale PNG over each mask's documented range.
    Png,
    /// 32-bit float OpenEXR in the mask's own units.
    Exr,
}

/// Arguments of `terrasketch masks`.
pub struct MasksArgs {
    pub input: PathBuf,
    pub output_dir: PathBuf,
    pub format: MaskFormat,
    pub cell_size_m: Option<f64>,
}

/// Partial derivatives at every sample: `[p, q, r, s, t]` = `dz/dx`, `dz/dy`, `d2z/dx2`,
/// `d2z/dxdy`, `d2z/dy2` (x east, y north).
fn derivatives(map: &Heightmap) -> Vec<[f64; 5]> {
    let (w, h) = (map.width as i64, map.height as i64);
    let [dx, dy] = map.cell_size_m;
    let at = |c: i64, r: i64| f64::from(map.data[(r * w + c) as usize]);
    // Height at (column in range, any row), extended linearly past the north and south edges.
    let by_row = |c: i64, r: i64| {
        if r < 0 {
            2.0 * at(c, 0) - at(c, 1)
        } else if r >= h {
            2.0 * at(c, h - 1) - at(c, h - 2)
        } else {
            at(c, r)
        }
    };
    // Height at any (column, row), extended linearly past every edge.
    let z = |c: i64, r: i64| {
        if c < 0 {
            2.0 * by_row(0, r) - by_row(1, r)
        } else if c >= w {
            2.0 * by_row(w - 1, r) - by_row(w - 2, r)
        } else {
            by_row(c, r)
        }
    };
    let mut out = Vec::with_capacity(map.data.len());
    for r in 0..h {
        for c in 0..w {
            let [nw, n, ne] = [z(c - 1, r - 1), z(c, r - 1), z(c + 1, r - 1)];
            let [west, mid, east] = [z(c - 1, r), z(c, r), z(c + 1, r)];
            let [sw, s, se] = [z(c - 1, r + 1), z(c, r + 1), z(c + 1, r + 1)];
            // Horn's weighted differences for the gradient (row r - 1 is north).
            let p = ((ne + 2.0 * east + se) - (nw + 2.0 * west + sw)) / (8.0 * dx);
            let q = ((nw + 2.0 * n + ne) - (sw + 2.0 * s + se)) / (8.0 * dy);
            let rr = (west - 2.0 * mid + east) / (dx * dx);
            let tt = (n - 2.0 * mid + s) / (dy * dy);
            let ss = (ne - nw - se + sw) / (4.0 * dx * dy);
            out.push([p, q, rr, ss, tt]);
        }
    }
    out
}

/// Slope in degrees, `[0, 90)`.
fn slope_deg(d: &[f64; 5]) -> f64 {
    (d[0] * d[0] + d[1] * d[1]).sqrt().atan().to_degrees()
}

/// Hillshade in `[0, 1]`: the cosine between the surface normal and the sun's direction
/// (azimuth 315, altitude 45), clamped at 0 for faces turned away.
fn hillshade(d: &[f64; 5]) -> f64 {
    let (az, alt) = (SUN_AZIMUTH_DEG.to_radians(), SUN_ALTITUDE_DEG.to_radians());
    let sun = [az.sin() * alt.cos(), az.cos() * alt.cos(), alt.sin()];
    let normal = [-d[0], -d[1], 1.0];
    let len = (d[0] * d[0] + d[1] * d[1] + 1.0).sqrt();
    ((normal[0] * sun[0] + normal[1] * sun[1] + normal[2] * sun[2]) / len).max(0.0)
}

/// Mean curvature of the surface, 1/m, positive where it is convex (ridges, peaks) and negative
/// where it is concave (valleys, pits).
fn mean_curvature(d: &[f64; 5]) -> f64 {
    let [p, q, r, s, t] = *d;
    let g = 1.0 + p * p + q * q;
    -((1.0 + q * q) * r - 2.0 * p * q * s + (1.0 + p * p) * t) / (2.0 * g * g.sqrt())
}

/// D8 flow accumulation: how many samples (itself included) drain through each sample when
/// every sample sends its flow to the neighbour of steepest descent (drop over distance; the
/// first in N, NE, E, SE, S, SW, W, NW order on ties). Pits and flats keep their flow.
fn flow_accumulation(map: &Heightmap) -> Vec<f64> {
    let (w, h) = (map.width, map.height);
    let [dx, dy] = map.cell_size_m;
    let diag = (dx * dx + dy * dy).sqrt();
    let steps: [(i64, i64, f64); 8] = [
        (0, -1, dy),
        (1, -1, diag),
        (1, 0, dx),
        (1, 1, diag),
        (0, 1, dy),
        (-1, 1, diag),
        (-1, 0, dx),
        (-1, -1, diag),
    ];
    let receiver = |i: usize| -> Option<usize> {
        let (c, r) = ((i % w) as i64, (i / w) as i64);
        let here = f64::from(map.data[i]);
        let mut best: Option<(f64, usize)> = None;
        for &(sc, sr, dist) in &steps {
            let (nc, nr) = (c + sc, r + sr);
            if nc < 0 || nr < 0 || nc >= w as i64 || nr >= h as i64 {
                continue;
            }
            let j = nr as usize * w + nc as usize;
            let drop = (here - f64::from(map.data[j])) / dist;
            if drop > 0.0 && best.is_none_or(|(b, _)| drop > b) {
                best = Some((drop, j));
            }
        }
        best.map(|(_, j)| j)
    };
    // Highest first: a receiver is strictly lower, so it is visited after its donors.
    let mut order: Vec<usize> = (0..w * h).collect();
    order.sort_by(|&a, &b| map.data[b].total_cmp(&map.data[a]).then(a.cmp(&b)));
    let mut acc = vec![1.0f64; w * h];
    for i in order {
        if let Some(j) = receiver(i) {
            acc[j] += acc[i];
        }
    }
    acc
}

/// One mask: its file stem, values and the fixed range its PNG spans.
struct Mask {
    name: &'static str,
    values: Vec<f32>,
    png_range: [f32; 2],
}

/// Computes every 16-bit mask of `map`, and the hillshade as 8-bit pixels.
fn compute(map: &Heightmap) -> (Vec<Mask>, Vec<u8>) {
    let d = derivatives(map);
    let (lo, hi) = map
        .data
        .iter()
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), &v| {
            (a.min(v), b.max(v))
        });
    let range = f64::from(hi) - f64::from(lo);
    let height: Vec<f32> = map
        .data
        .iter()
        .map(|&v| {
            if range > 0.0 {
                ((f64::from(v) - f64::from(lo)) / range) as f32
            } else {
                0.0
            }
        })
        .collect();
    let curvature: Vec<f32> = d.iter().map(|d| mean_curvature(d) as f32).collect();
    let curvature_max = curvature.iter().fold(0.0f32, |m, v| m.max(v.abs()));
    let flow: Vec<f32> = flow_accumulation(map)
        .into_iter()
        .map(|a| a as f32)
        .collect();
    let shade = d
        .iter()
        .map(|d| (hillshade(d) * 255.0).round() as u8)
        .collect();
    let masks = vec![
        Mask {
            name: "slope",
            values: d.iter().map(|d| slope_deg(d) as f32).collect(),
            png_range: [0.0, 90.0],
        },
        Mask {
            name: "curvature",
            values: curvature,
            png_range: [-curvature_max, curvature_max],
        },
        Mask {
            name: "flow",
            values: flow,
            png_range: [0.0, ((map.width * map.height) as f32).ln()],
        },
        Mask {
            name: "height",
            values: height,
            png_range: [0.0, 1.0],
        },
    ];
    (masks, shade)
}

/// Reads the heightmap, computes the masks and writes them (and `masks.json`) into the folder.
pub fn run(args: &MasksArgs) -> Result<()> {
    let mut map = read_heightmap(&args.input)?;
    if let Some(cell) = args.cell_size_m {
        if !(cell.is_finite() && cell >= 0.01) {
            return Err(refused(format!(
                "--cell-size must be a number of metres from 0.01 up, got {cell}"
            )));
        }
        map.cell_size_m = [cell, cell];
    }
    if map.width < 3 || map.height < 3 {
        return Err(refused(format!(
            "{} is {} x {} samples: masks need at least 3 x 3",
            args.input.display(),
            map.width,
            map.height
        )));
    }
    write_masks(&map, &args.output_dir, args.format)?;
    eprintln!(
        "terrasketch: 5 masks of {} written to {}",
        args.input.display(),
        args.output_dir.display()
    );
    Ok(())
}

/// Computes the masks of `map` (at least 3 x 3) and writes them and `masks.json` into `dir`
/// (created if needed): the command line's `masks` and the editor's export.
pub fn write_masks(map: &Heightmap, dir: &Path, mask_format: MaskFormat) -> Result<()> {
    if dir.exists() && !dir.is_dir() {
        return Err(refused(format!("-o {}: not a folder", dir.display())));
    }
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let (masks, shade) = compute(map);
    let (ext, format) = match mask_format {
        MaskFormat::Png => ("png", Format::Png16),
        MaskFormat::Exr => ("exr", Format::Exr),
    };
    let mut listed = Vec::new();
    for mask in masks {
        let mut values = mask.values;
        if format == Format::Png16 && mask.name == "flow" {
            values.iter_mut().for_each(|a| *a = a.ln());
        }
        let path = dir.join(format!("{}.{ext}", mask.name));
        let out = Heightmap {
            width: map.width,
            height: map.height,
            data: values,
            cell_size_m: map.cell_size_m,
        };
        let stretch = (format == Format::Png16).then_some(Stretch {
            min_m: mask.png_range[0],
            max_m: mask.png_range[1],
        });
        let options = WriteOptions {
            stretch,
            ..WriteOptions::default()
        };
        write_heightmap_with(&path, &out, &options)
            .with_context(|| format!("cannot write {}", path.display()))?;
        listed.push(describe(mask.name, &path, stretch));
    }
    let path = dir.join("hillshade.png");
    write_grey8_png(&path, map.width, map.height, &shade)
        .with_context(|| format!("cannot write {}", path.display()))?;
    listed.push(serde_json::json!({ "mask": "hillshade", "file": "hillshade.png",
        "values": "8-bit, 255 * cos(angle to the sun at azimuth 315, altitude 45), 0 when facing away" }));
    let json = serde_json::to_string_pretty(&serde_json::json!({ "masks": listed }))?;
    write_file_atomically(&dir.join("masks.json"), json.as_bytes())?;
    Ok(())
}

/// A `masks.json` entry: the file, what its values are and, in a PNG, what codes 0 and 65535 mean.
fn describe(name: &str, path: &Path, stretch: Option<Stretch>) -> serde_json::Value {
    let values = match name {
        "slope" => "degrees from horizontal, 0 to 90",
        "curvature" => "mean curvature, 1/m, > 0 convex (ridges), < 0 concave (valleys)",
        "flow" if stretch.is_some() => {
            "ln(D8 flow accumulation in samples), 0 to ln(width * height)"
        }
        "flow" => {
            "D8 flow accumulation, samples draining through (itself included), 1 to width * height"
        }
        _ => "height normalised over the map, 0 (lowest) to 1 (highest)",
    };
    let file = path.file_name().map(|f| f.to_string_lossy().into_owned());
    serde_json::json!({
        "mask": name,
        "file": file,
        "values": values,
        "code_0": stretch.map(|s| s.min_m),
        "code_65535": stretch.map(|s| s.max_m),
    })
}
