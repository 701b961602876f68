//! `terrasketch stitch`: joins the tiles of `refine --tile` into one raster.
//!
//! Every tile's sidecar must name the same world (input, exemplars, size, seed, parameters,
//! tiles and overlap), every tile must be there once, and every tile file must be the one its
//! sidecar describes (size and digest); otherwise nothing is written. Where two tiles overlap
//! (`2 * overlap` cells across each border) the output is their blend with a smoothstep ramp
//! across the overlap, weights summing to 1; elsewhere it is the tile itself, bit for bit.
//! `--json` reports the seam figures and how far apart the tiles are where they overlap.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result};
use terrasketch_raster::{Format, Heightmap, ReadOptions, Sampling, read_raster};

use crate::output::{ExportPlan, Place, check_writable, refused, write_raster};
use crate::tiled::{FORMAT_VERSION, Fnv, TileSidecar};
use crate::tiles::{TileSpec, layout};

/// Largest sidecar read, bytes.
const MAX_SIDECAR_BYTES: u64 = 1 << 20;

/// The sidecars named by `manifest`: a sidecar (then every sidecar of its world in its folder)
/// or a folder (every sidecar in it, which must be of one world).
fn gather(manifest: &Path) -> Result<Vec<(PathBuf, TileSidecar)>> {
    let (folder, world) = if manifest.is_dir() {
        (manifest.to_path_buf(), None)
    } else if manifest.is_file() {
        let first = read_sidecar(manifest)?;
        let folder = match manifest.parent() {
            Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
            _ => PathBuf::from("."),
        };
        (folder, Some(first.world))
    } else {
        return Err(refused(format!("{} does not exist", manifest.display())));
    };
    let entries = std::fs::read_dir(&folder)
        .map_err(|e| refused(format!("cannot list {} ({e})", folder.display())))?;
    let mut paths: Vec<PathBuf> = entries
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.file_name()
                .and_then(|n| n.to_str())
                .is_some_and(|n| n.ends_with(".tile.json") && !n.starts_with('.'))
        })
        .collect();
    paths.sort();
    let mut out = Vec::new();
    for p in paths {
        let s = read_sidecar(&p)?;
        if world.as_ref().is_none_or(|w| *w == s.world) {
            out.push((p, s));
        }
    }
    if out.is_empty() {
        return Err(refused(format!(
            "{} holds no tile sidecar (NAME_x{{i}}_y{{j}}.tile.json)",
            folder.display()
        )));
    }
    let first = &out[0].1.world;
    if let Some((p, s)) = out.iter().find(|(_, s)| s.world != *first) {
        return Err(refused(format!(
            "{} holds tiles of several worlds ({first}, {}: {}); name one tile's sidecar",
            folder.display(),
            s.world,
            p.display()
        )));
    }
    Ok(out)
}

fn read_sidecar(path: &Path) -> Result<TileSidecar> {
    let len = std::fs::metadata(path)
        .map_err(|e| refused(format!("cannot read {} ({e})", path.display())))?
        .len();
    if len > MAX_SIDECAR_BYTES {
        return Err(refused(format!(
            "{} is not a tile sidecar (too large)",
            path.display()
        )));
    }
    let text = std::fs::read(path)
        .map_err(|e| refused(format!("cannot read {} ({e})", path.display())))?;
    let s: TileSidecar = serde_json::from_slice(&text)
        .map_err(|e| refused(format!("{} is not a tile sidecar: {e}", path.display())))?;
    if s.format != "terrasketch-tile" || s.version != FORMAT_VERSION {
        return Err(refused(format!(
            "{} is not a version {FORMAT_VERSION} terrasketch tile sidecar",
            path.display()
        )));
    }
    Ok(s)
}

/// Smoothstep ramp: 0 below 0, 1 above 1, C1 in between.
fn ramp(t: f32) -> f32 {
    let t = t.clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// A tile's blend weight along one axis at world position `x`, for its window `[start, end)`
/// of an `n`-cell axis: rising across the `2 overlap` cells at its start and falling across
/// those at its end where it has a neighbour there. The neighbours' weights sum to 1.
pub fn axis_weight(x: usize, start: usize, end: usize, n: usize, overlap: usize) -> f32 {
    if overlap == 0 {
        return 1.0;
    }
    let width = (2 * overlap) as f32;
    let mut w = 1.0;
    if start > 0 {
        w *= ramp((x as f32 - start as f32 + 0.5) / width);
    }
    if end < n {
        w *= 1.0 - ramp((x as f32 - (end - 2 * overlap) as f32 + 0.5) / width);
    }
    w
}

/// 99th percentile of `v` (0 when empty).
fn p99(v: &mut [f32]) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    let k = ((v.len() as f64 * 0.99) as usize).min(v.len() - 1);
    f64::from(*v.select_nth_unstable_by(k, f32::total_cmp).1)
}

/// Seam figures of a stitched `n x n` world cut into `nx x ny` tiles: p99 |Laplacian| on the
/// tile borders (the two cells either side of each border line) and over the overlap zones
/// (`overlap` either side), each over the p99 of all interior cells.
pub fn seam_ratios(h: &[f32], n: usize, nx: usize, ny: usize, overlap: usize) -> (f64, f64) {
    let near = |v: usize, k: usize, r: usize| {
        let core = n / k;
        (1..k).any(|t| {
            let b = t * core;
            v + r >= b && v < b + r.max(1)
        })
    };
    let (mut all, mut border, mut zone) = (Vec::new(), Vec::new(), Vec::new());
    for y in 1..n - 1 {
        for x in 1..n - 1 {
            let i = y * n + x;
            let lap = (h[i - 1] + h[i + 1] + h[i - n] + h[i + n] - 4.0 * h[i]).abs();
            all.push(lap);
            if near(x, nx, 1) || near(y, ny, 1) {
                border.push(lap);
            }
            if near(x, nx, overlap) || near(y, ny, overlap) {
                zone.push(lap);
            }
        }
    }
    let a = p99(&mut all);
    if a <= 0.0 {
        return (0.0, 0.0);
    }
    (p99(&mut border) / a, p99(&mut zone) / a)
}

/// Checks that the sidecars are one complete world and returns its export plan.
fn check_world(sidecars: &[(PathBuf, TileSidecar)]) -> Result<ExportPlan> {
    let (first_path, first) = &sidecars[0];
    for (p, s) in &sidecars[1..] {
        if let Some(d) = first.key.difference(&s.key) {
            return Err(refused(format!(
                "{} is not of the same world as {}: {d}",
                p.display(),
                first_path.display()
            )));
        }
        if s.tiles != first.tiles || s.overlap != first.overlap {
            return Err(refused(format!(
                "{} has tiles {:?} overlap {}, {} has {:?} overlap {}",
                p.display(),
                s.tiles,
                s.overlap,
                first_path.display(),
                first.tiles,
                first.overlap
            )));
        }
    }
    let [nx, ny] = first.tiles;
    // The tiles are windows of the world's solve cells; the output samples them to `--size`.
    let plan = ExportPlan::new(first.key.size)?;
    let n = plan.solve_n;
    let spec = TileSpec {
        nx,
        ny,
        overlap: first.overlap,
        pattern: String::new(),
    };
    let tiles = layout(n, n, Sampling::Cells, &spec)?;
    let mut seen: Vec<Option<&Path>> = vec![None; nx * ny];
    for (p, s) in sidecars {
        let [i, j] = s.tile;
        if i >= nx || j >= ny {
            return Err(refused(format!(
                "{}: tile {i},{j} is outside the {nx},{ny} tiles",
                p.display()
            )));
        }
        if let Some(other) = seen[j * nx + i] {
            return Err(refused(format!(
                "tile {i},{j} is given twice: {} and {}",
                other.display(),
                p.display()
            )));
        }
        seen[j * nx + i] = Some(p);
        let t = tiles[j * nx + i];
        if s.window != [t.column, t.row, t.width, t.height] {
            return Err(refused(format!(
                "{}: window {:?} is not tile {i},{j}'s of the {nx},{ny} layout",
                p.display(),
                s.window
            )));
        }
    }
    let missing: Vec<String> = (0..nx * ny)
        .filter(|&k| seen[k].is_none())
        .map(|k| format!("{},{}", k % nx, k / nx))
        .collect();
    if !missing.is_empty() {
        return Err(refused(format!(
            "tiles {} of world {} are missing (no sidecar in the folder)",
            missing.join(" "),
            first.world
        )));
    }
    Ok(plan)
}

/// Reads the tile file that sidecar `s` (at `p`) names, checking that it is the one described.
fn read_tile(p: &Path, s: &TileSidecar) -> Result<terrasketch_raster::Raster> {
    let folder = p.parent().unwrap_or(Path::new(""));
    let file = folder.join(&s.file);
    if s.file.contains('/') || s.file.contains('\\') {
        return Err(refused(format!(
            "{}: tile file {:?} is not a file name",
            p.display(),
            s.file
        )));
    }
    let bytes = std::fs::read(&file).map_err(|e| {
        refused(format!(
            "tile file {} of {} cannot be read ({e})",
            file.display(),
            p.display()
        ))
    })?;
    let mut digest = Fnv::new();
    digest.add(&bytes);
    if digest.hex() != s.file_digest {
        return Err(refused(format!(
            "tile file {} is not the one its sidecar describes (digest {} against {})",
            file.display(),
            digest.hex(),
            s.file_digest
        )));
    }
    drop(bytes);
    let options = ReadOptions {
        unit_cells_when_absent: true,
        ..ReadOptions::default()
    };
    let raster = read_raster(&file, &options)?;
    let [_, _, width, height] = s.window;
    if raster.map.width != width || raster.map.height != height {
        return Err(refused(format!(
            "tile file {} is {}x{}, its window {width}x{height}",
            file.display(),
            raster.map.width,
            raster.map.height
        )));
    }
    Ok(raster)
}

/// The world's cells joined from its tiles.
struct Joined {
    /// `n x n` heights, north-up.
    heights: Vec<f32>,
    /// No-data cells (empty when none): every tile marks the same ones.
    hole: Vec<bool>,
    /// The world's CRS and transform (of its cells) and no-data value, from the tiles.
    place: Place,
    /// RMS difference of two tiles where they overlap, metres.
    overlap_rms_m: f64,
}

/// Blends the tiles into the `n x n` world cells.
fn join(sidecars: &[(PathBuf, TileSidecar)], n: usize) -> Result<Joined> {
    let mut acc = vec![0.0f32; n * n];
    let (mut hole, mut place) = (Vec::new(), Place::default());
    // The first tile's value where two tiles overlap, to measure how far apart they are.
    let mut first_value = vec![f32::NAN; n * n];
    let (mut diff2, mut diff_cells) = (0.0f64, 0usize);
    for (p, s) in sidecars {
        let raster = read_tile(p, s)?;
        let [column, row, width, height] = s.window;
        if let Some(g) = &raster.source.georef
            && place.georef.is_none()
        {
            // The tile's first pixel is the world cell (column, row).
            place.georef = Some(g.remapped([-(column as f64), 1.0], [-(row as f64), 1.0]));
            place.nodata = raster.source.nodata;
        }
        if !raster.nodata_mask.is_empty() {
            hole.resize(n * n, false);
            for (dy, src) in raster.nodata_mask.chunks(width).enumerate() {
                let dst = &mut hole[(row + dy) * n + column..(row + dy) * n + column + width];
                for (d, &h) in dst.iter_mut().zip(src) {
                    *d |= h;
                }
            }
        }
        let wx: Vec<f32> = (column..column + width)
            .map(|x| axis_weight(x, column, column + width, n, s.overlap))
            .collect();
        for (dy, src) in raster.map.data.chunks(width).enumerate() {
            let y = row + dy;
            let wy = axis_weight(y, row, row + height, n, s.overlap);
            let dst = &mut acc[y * n + column..y * n + column + width];
            let firsts = &mut first_value[y * n + column..y * n + column + width];
            for (((d, f), v), w) in dst.iter_mut().zip(firsts).zip(src).zip(&wx) {
                let w = w * wy;
                if w >= 1.0 {
                    *d = *v;
                } else if w > 0.0 {
                    *d += w * v;
                    if f.is_nan() {
                        *f = *v;
                    } else {
                        diff2 += f64::from(*v - *f).powi(2);
                        diff_cells += 1;
                    }
                }
            }
        }
    }
    let overlap_rms_m = if diff_cells > 0 {
        (diff2 / diff_cells as f64).sqrt()
    } else {
        0.0
    };
    Ok(Joined {
        heights: acc,
        hole,
        place,
        overlap_rms_m,
    })
}

/// Samples the joined cells to the plan's size, with the place moved to the samples and the
/// no-data samples (pixel centre in a no-data cell) marked in a GeoTIFF.
fn world_samples(
    joined: Joined,
    plan: &ExportPlan,
    cell: f64,
    format: Format,
) -> Result<(Heightmap, Place)> {
    let n = plan.solve_n;
    let cells = Heightmap {
        width: n,
        height: n,
        data: joined.heights,
        cell_size_m: [cell; 2],
    };
    let mut world = plan.sample_north_up(cells)?;
    let mut place = joined.place;
    let (a, b) = plan.pixel_span(n as f64);
    place.georef = place.georef.map(|g| g.remapped([a, b], [a, b]));
    if let Some(nodata) = place.nodata
        && format == Format::Tiff
        && !joined.hole.is_empty()
    {
        let cell = |k: usize| ((a + b * (k as f64 + 0.5)).floor().max(0.0) as usize).min(n - 1);
        for y in 0..world.height {
            for x in 0..world.width {
                if joined.hole[cell(y) * n + cell(x)] {
                    world.data[y * world.width + x] = nodata as f32;
                }
            }
        }
    }
    Ok((world, place))
}

/// Gathers, checks, blends and writes; prints the seam figures.
pub fn run(manifest: &Path, output: &Path, json: bool) -> Result<()> {
    let t0 = Instant::now();
    let format: Format = check_writable(output)?;
    let sidecars = gather(manifest)?;
    let plan = check_world(&sidecars)?;
    let first = &sidecars[0].1;
    let ([nx, ny], n) = (first.tiles, plan.solve_n);
    let joined = join(&sidecars, n)?;
    let (seam, zone) = seam_ratios(&joined.heights, n, nx, ny, first.overlap);
    let overlap_rms_m = joined.overlap_rms_m;
    let (world, place) = world_samples(joined, &plan, first.cell_size_m, format)?;
    let (_, written) = write_raster(output, format, &world, plan.sampling, None, &place, json)
        .with_context(|| format!("cannot write {}", output.display()))?;
    let ms_total = t0.elapsed().as_secs_f64() * 1e3;
    if json {
        let mut j = serde_json::json!({
            "output": output.display().to_string(),
            "world": first.world,
            "size": plan.samples,
            "tiles": [nx, ny],
            "overlap": first.overlap,
            "seed": first.key.seed,
            "seam_laplacian_p99_ratio": seam,
            "overlap_laplacian_p99_ratio": zone,
            "overlap_rms_difference_m": overlap_rms_m,
            "ms_total": ms_total,
        });
        if let (Some(o), serde_json::Value::Object(more)) = (j.as_object_mut(), written) {
            o.extend(more);
        }
        println!("{j}");
    } else {
        eprintln!(
            "terrasketch: stitched {} tiles of {} into {} ({}); tile-border |Laplacian| p99 \
             ratio {seam:.3}, overlaps {zone:.3}",
            nx * ny,
            first.world,
            output.display(),
            plan.describe()
        );
    }
    Ok(())
}
