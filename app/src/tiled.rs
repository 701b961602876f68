//! A world refined tile by tile (`terrasketch refine --tile I,J`), each tile on any machine.
//!
//! The world's guide (the sketch's solve, or the heightmap target) and the pyramid levels above
//! the finest are computed once for the whole world: by `--coarse-out FILE`, or by every tile
//! itself when no `--coarse FILE` is given (the same bits either way). A tile then runs the
//! finest level on its window plus a halo, seeded by world position
//! (`RefineParams::origin`), cuts its window out and writes it with a sidecar
//! `NAME_x{i}_y{j}.tile.json` that `terrasketch stitch` reads.

use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;
use std::time::Instant;

use anyhow::{Context, Result};
use serde::{Deserialize, Serialize};
use terrasketch_raster::{Format, Heightmap, Sampling, write_file_atomically};
use terrasketch_synthesis::Dem;
use terrasketch_synthesis::refine::{CoarseWorld, prepare_exemplars, refine_coarse, refine_region};

use crate::coarse_world::{World, open_coarse, write_coarse};
use crate::output::{ExportPlan, Place, check_folder, refused, write_raster};
use crate::refine::{
    Bar, InputPlace, RefineArgs, default_cache_dir, heightmap_target, input_place, load_exemplars,
    sketch_target,
};
use crate::tiles::{Tile, TileSpec, layout, tile_name};

/// Cells of synthesis computed around a tile's window and thrown away: the patch synthesis,
/// the pit removal and the Poisson merge see the region's border, not the world's.
pub const HALO_CELLS: usize = 32;
/// A region starts and ends on multiples of this many world cells, so its block averages
/// (the layout's low-pass, 32 cells by default) fall on the world's blocks.
const REGION_ALIGN: usize = 32;
/// Version of the coarse-world file and of the tile sidecar.
pub const FORMAT_VERSION: u32 = 1;

/// What makes two runs the same world: tiles of one world may be stitched together, and a
/// coarse file may serve only the world it was made for.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq)]
pub struct WorldKey {
    /// The input's file name.
    pub input: String,
    /// FNV-1a 64 of the input file's bytes.
    pub input_digest: String,
    /// FNV-1a 64 of the exemplars as loaded (sizes, cell sizes, heights).
    pub exemplars_digest: String,
    /// `--size`.
    pub size: usize,
    /// `--seed`.
    pub seed: u64,
    /// `--patch-size`.
    pub patch_size: usize,
    /// `--detail-scale`.
    pub detail_scale: Option<usize>,
    /// `--fine-detail` (absent in files made before it, which had none: 0).
    #[serde(default)]
    pub fine_detail: f32,
}

impl WorldKey {
    /// The first field in which `other` differs, as `"name other vs self"`.
    pub fn difference(&self, other: &WorldKey) -> Option<String> {
        let fields = [
            ("input", self.input.clone(), other.input.clone()),
            (
                "input file contents (digest)",
                self.input_digest.clone(),
                other.input_digest.clone(),
            ),
            (
                "exemplars (digest)",
                self.exemplars_digest.clone(),
                other.exemplars_digest.clone(),
            ),
            ("size", self.size.to_string(), other.size.to_string()),
            ("seed", self.seed.to_string(), other.seed.to_string()),
            (
                "patch size",
                self.patch_size.to_string(),
                other.patch_size.to_string(),
            ),
            (
                "detail scale",
                format!("{:?}", self.detail_scale),
                format!("{:?}", other.detail_scale),
            ),
            (
                "fine detail",
                self.fine_detail.to_string(),
                other.fine_detail.to_string(),
            ),
        ];
        fields
            .into_iter()
            .find(|(_, a, b)| a != b)
            .map(|(name, a, b)| format!("{name} {b} against {a}"))
    }
}

/// FNV-1a, 64 bits: a digest to tell files apart, not a security measure.
pub struct Fnv(u64);

impl Fnv {
    pub fn new() -> Fnv {
        Fnv(0xcbf2_9ce4_8422_2325)
    }
    pub fn add(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 ^= u64::from(b);
            self.0 = self.0.wrapping_mul(0x0000_0100_0000_01b3);
        }
    }
    pub fn hex(&self) -> String {
        format!("{:016x}", self.0)
    }
}

/// The key of this run's world.
fn world_key(args: &RefineArgs, dems: &[Dem]) -> Result<WorldKey> {
    let bytes = std::fs::read(&args.input)
        .with_context(|| format!("cannot read {}", args.input.display()))?;
    let mut input = Fnv::new();
    input.add(&bytes);
    let mut ex = Fnv::new();
    for d in dems {
        ex.add(&(d.width as u64).to_le_bytes());
        ex.add(&(d.height as u64).to_le_bytes());
        for c in d.cell_size_m {
            ex.add(&c.to_le_bytes());
        }
        for h in &d.heights_m {
            ex.add(&h.to_le_bytes());
        }
    }
    Ok(WorldKey {
        input: args
            .input
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default(),
        input_digest: input.hex(),
        exemplars_digest: ex.hex(),
        size: args.size,
        seed: args.seed,
        patch_size: args.patch_size,
        detail_scale: args.detail_scale,
        fine_detail: args.fine_detail,
    })
}

/// A square region of the world, in cells from the north-west corner.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct Region {
    pub column: usize,
    pub row: usize,
    pub side: usize,
}

/// The region computed for `tile`: its window plus [`HALO_CELLS`] on every side, aligned to
/// [`REGION_ALIGN`], made square (the larger side) and kept inside the `n`-cell world.
pub fn region_for(tile: &Tile, n: usize) -> Region {
    let align_down = |v: usize| v / REGION_ALIGN * REGION_ALIGN;
    let span = |start: usize, len: usize| {
        let a = align_down(start.saturating_sub(HALO_CELLS));
        let b = (start + len + HALO_CELLS)
            .div_ceil(REGION_ALIGN)
            .saturating_mul(REGION_ALIGN)
            .min(n);
        (a, b - a)
    };
    let (x0, w) = span(tile.column, tile.width);
    let (y0, h) = span(tile.row, tile.height);
    let side = w.max(h).min(n);
    // The shorter side grows east or south, or back from the world's edge.
    let fit = |start: usize| start.min(n - side);
    Region {
        column: fit(x0),
        row: fit(y0),
        side,
    }
}

/// Whether the refine input is a sketch (`.json`) rather than a heightmap.
fn is_sketch(input: &Path) -> bool {
    input
        .extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("json"))
}

/// Solves or reads the world's input and runs its coarse levels in this process; also returns
/// the solve's milliseconds and a heightmap input's place in its file.
fn world_in_memory(
    args: &RefineArgs,
    plan: &ExportPlan,
    dems: &[Dem],
    bar: &Bar,
) -> Result<(World, f64, Option<InputPlace>)> {
    let (input, ms_solve, place) = if is_sketch(&args.input) {
        let (input, ms) = sketch_target(&args.input, plan.solve_n)?;
        (input, ms, None)
    } else {
        let (input, place) = heightmap_target(&args.input, plan.solve_n)?;
        (input, 0.0, Some(place))
    };
    let cache = args.cache_dir.clone().or_else(default_cache_dir);
    let prog = |f: f32, what: &str| bar.show(0.1 * f, what);
    let prepared = prepare_exemplars(dems, input.target.cell_size_m[0], cache.as_deref(), &prog)?;
    let cancel = AtomicBool::new(false);
    let prog = |f: f32, what: &str| bar.show(0.1 + 0.4 * f, &format!("world {what}"));
    let coarse = refine_coarse(&input, &prepared, &args.params(), &prog, &|_| {}, &cancel)?;
    Ok((World::Memory { input, coarse }, ms_solve, place))
}

/// `refine --coarse-out FILE` or `refine --tile I,J ...`.
pub fn run(args: &RefineArgs) -> Result<()> {
    let t0 = Instant::now();
    // Tiles are windows of the world's solve cells (`plan.solve_n`); `stitch` samples the
    // joined cells to `--size` (corners for 2^n+1 and other sizes), as a single refine would.
    let plan = ExportPlan::new(args.size)?;
    if !args.input.exists() {
        return Err(refused(format!("{} does not exist", args.input.display())));
    }
    if let Some(path) = &args.coarse_out {
        check_folder(path)?;
        plan.check_refine_memory()?;
        return coarse_out(args, &plan, path, t0);
    }
    let Some(index) = &args.tile else {
        return Err(refused("--coarse needs --tile I,J"));
    };
    tile(args, &plan, index, t0)
}

/// Computes the world's input and coarse levels and writes them to `path`.
fn coarse_out(args: &RefineArgs, plan: &ExportPlan, path: &Path, t0: Instant) -> Result<()> {
    let dems = load_exemplars(&args.exemplars)?;
    let key = world_key(args, &dems)?;
    let bar = Bar {
        quiet: args.json,
        last: std::sync::Mutex::new((-1, String::new())),
    };
    let (world, ms_solve, _) = world_in_memory(args, plan, &dems, &bar)?;
    bar.finish();
    let World::Memory { input, coarse } = world else {
        return Err(anyhow::anyhow!("the world was not computed in memory"));
    };
    let plan_levels = coarse.plan.clone();
    let bytes = write_coarse(path, key, input, coarse)?;
    let ms_total = t0.elapsed().as_secs_f64() * 1e3;
    if args.json {
        println!(
            "{}",
            serde_json::json!({
                "coarse": path.display().to_string(),
                "bytes": bytes,
                "levels": plan_levels,
                "ms_solve": ms_solve,
                "ms_total": ms_total,
                "peak_rss_mb": crate::output::peak_rss_mb(),
            })
        );
    } else {
        eprintln!(
            "terrasketch: coarse world {} written ({:.0} MB, {} levels) in {:.1} s",
            path.display(),
            bytes as f64 / 1e6,
            plan_levels.len(),
            ms_total / 1e3
        );
    }
    Ok(())
}

/// What a tile run leaves next to its file, for `terrasketch stitch`.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq)]
pub struct TileSidecar {
    pub format: String,
    pub version: u32,
    /// The world's name (the output's file stem).
    pub world: String,
    pub key: WorldKey,
    /// `[nx, ny]`.
    pub tiles: [usize; 2],
    pub overlap: usize,
    /// `[i, j]`: west to east, south to north.
    pub tile: [usize; 2],
    /// The tile's raster, in the sidecar's folder.
    pub file: String,
    /// FNV-1a 64 of the tile file's bytes.
    pub file_digest: String,
    /// `[column, row, width, height]` of the tile in the north-up world raster.
    pub window: [usize; 4],
    pub cell_size_m: f64,
}

/// Parses `--tile I,J` against `[nx, ny]`.
fn parse_index(text: &str, [nx, ny]: [usize; 2]) -> Result<[usize; 2]> {
    let mut parts = text.split(',').map(|p| p.trim().parse::<usize>());
    match (parts.next(), parts.next(), parts.next()) {
        (Some(Ok(i)), Some(Ok(j)), None) if i < nx && j < ny => Ok([i, j]),
        (Some(Ok(_)), Some(Ok(_)), None) => Err(refused(format!(
            "--tile {text} is outside the {nx},{ny} tiles (I from 0 to {}, J from 0 to {})",
            nx - 1,
            ny - 1
        ))),
        _ => Err(refused(format!(
            "--tile {text:?} is not I,J: two whole numbers, e.g. 0,1"
        ))),
    }
}

/// The sidecar's path for a tile file.
pub fn sidecar_path(tile_file: &Path) -> PathBuf {
    let stem = tile_file
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    tile_file.with_file_name(format!("{stem}.tile.json"))
}

/// One tile's request, checked before any work.
struct TileJob {
    /// `[i, j]` and the layout's `[nx, ny]`.
    index: [usize; 2],
    tiles: [usize; 2],
    overlap: usize,
    /// The tile's window of the world's cells, and the region computed around it.
    window: Tile,
    region: Region,
    format: Format,
    world_name: String,
    file_name: String,
    tile_path: PathBuf,
}

impl TileJob {
    /// Checks `--tile`, `--tiles`, `--overlap`, the region's size and the output.
    fn check(args: &RefineArgs, plan: &ExportPlan, index: &str) -> Result<TileJob> {
        let Some((text, overlap, pattern)) = &args.tiles else {
            return Err(refused("--tile needs --tiles NX,NY"));
        };
        let spec = TileSpec::from_args(text, *overlap, pattern)?;
        let [nx, ny] = [spec.nx, spec.ny];
        let [i, j] = parse_index(index, [nx, ny])?;
        let n = plan.solve_n;
        let tiles = layout(n, n, Sampling::Cells, &spec)?;
        let (core_x, core_y) = (n / nx, n / ny);
        if 2 * overlap > core_x.min(core_y) {
            return Err(refused(format!(
                "--overlap {overlap} is more than half a tile ({} cells): the blends of a tile's \
                 two sides would meet",
                core_x.min(core_y)
            )));
        }
        let Some(&window) = tiles.iter().find(|t| t.i == i && t.j == j) else {
            return Err(refused(format!("--tile {index} is not in the layout")));
        };
        let region = region_for(&window, n);
        if region.side < 2 * args.patch_size || region.side < 64 {
            return Err(refused(format!(
                "tile {i},{j} and its halo are {} cells a side, too small for --patch-size {} \
                 (at least twice the patch and 64): use fewer tiles",
                region.side, args.patch_size
            )));
        }
        let Some(output) = args.output.as_deref() else {
            return Err(refused("--tile needs -o OUT (the world's name)"));
        };
        let format = Format::from_path(output)?;
        if !matches!(format, Format::Exr | Format::Tiff) {
            return Err(refused(format!(
                "{}: tiles are written as f32 .exr or .tif (stitch writes any format)",
                output.display()
            )));
        }
        check_folder(output)?;
        if args.coarse.is_none() {
            // This process computes the whole world's guide and coarse levels.
            plan.check_refine_memory()?;
        }
        let world_name = output
            .file_stem()
            .and_then(|s| s.to_str())
            .ok_or_else(|| refused(format!("{}: the file name is not UTF-8", output.display())))?
            .to_owned();
        let ext = output.extension().and_then(|s| s.to_str()).unwrap_or("");
        let folder = output.parent().unwrap_or(Path::new(""));
        let file_name = tile_name(pattern, &world_name, ext, i, j);
        Ok(TileJob {
            index: [i, j],
            tiles: [nx, ny],
            overlap: *overlap,
            window,
            region,
            format,
            world_name,
            tile_path: folder.join(&file_name),
            file_name,
        })
    }
}

/// Computes and writes one tile and its sidecar.
fn tile(args: &RefineArgs, plan: &ExportPlan, index: &str, t0: Instant) -> Result<()> {
    let job = TileJob::check(args, plan, index)?;
    let (n, region, t, [i, j]) = (plan.solve_n, job.region, job.window, job.index);
    let dems = load_exemplars(&args.exemplars)?;
    let key = world_key(args, &dems)?;
    let bar = Bar {
        quiet: args.json,
        last: std::sync::Mutex::new((-1, String::new())),
    };
    let (mut world, ms_solve, place) = match &args.coarse {
        Some(path) if is_sketch(&args.input) => (open_coarse(path, &key, n)?, 0.0, None),
        Some(path) => (
            open_coarse(path, &key, n)?,
            0.0,
            Some(input_place(&args.input)?),
        ),
        None => world_in_memory(args, plan, &dems, &bar)?,
    };
    let t_tile = Instant::now();
    let (input, start) = world.region(&region)?;
    let world_plan = world.plan();
    let level1 = start.is_some();
    let coarse = CoarseWorld {
        plan: world_plan,
        level1: None,
    };
    let cache = args.cache_dir.clone().or_else(default_cache_dir);
    let base = if args.coarse.is_some() { 0.0 } else { 0.5 };
    let prog = |f: f32, what: &str| bar.show(base + 0.05 * f, what);
    let t_prep = Instant::now();
    let prepared = prepare_exemplars(&dems, world.cell_size_m(), cache.as_deref(), &prog)?;
    let ms_prepare = t_prep.elapsed().as_secs_f64() * 1e3;
    drop(world);
    let mut p = args.params();
    p.origin = [region.column as i64, region.row as i64];
    let cancel = AtomicBool::new(false);
    let prog = |f: f32, what: &str| {
        bar.show(
            base + 0.05 + (0.95 - base) * f,
            &format!("tile {i},{j}: {what}"),
        )
    };
    let out = refine_region(&input, &prepared, &p, &coarse, start, &prog, &cancel)?;
    bar.finish();
    let (sidecar, side_path) = write_tile(&job, n, &out.heights, key, place.as_ref())?;
    let tile_path = &job.tile_path;
    let s = &out.stats;
    let ms_total = t0.elapsed().as_secs_f64() * 1e3;
    if args.json {
        println!(
            "{}",
            serde_json::json!({
                "tile": [i, j],
                "file": tile_path.display().to_string(),
                "sidecar": side_path.display().to_string(),
                "window": sidecar.window,
                "region": region,
                "coarse_levels_shared": level1,
                "ms_solve": ms_solve,
                "ms_tile": t_tile.elapsed().as_secs_f64() * 1e3,
                "ms_prepare_exemplars": ms_prepare,
                "ms_phases": s.ms_phases.iter().map(|(k, v)| (k.clone(), serde_json::json!(v))).collect::<serde_json::Map<String, serde_json::Value>>(),
                "ms_total": ms_total,
                "patches_feature": s.patches_feature,
                "patches_fill": s.patches_fill,
                "pits_after": s.pits_after,
                "constraint_max_error_m": s.constraint_max_error_m,
                "constraint_max_excess_m": s.constraint_max_excess_m,
                "seam_laplacian_p99_ratio": s.seam_laplacian_p99_ratio,
                "peak_rss_mb": crate::output::peak_rss_mb(),
            })
        );
    } else {
        eprintln!(
            "terrasketch: tile {i},{j} ({}x{} of the {n}^2 world, region {}^2) written to {} \
             in {:.1} s",
            t.width,
            t.height,
            region.side,
            tile_path.display(),
            ms_total / 1e3
        );
    }
    Ok(())
}

/// Cuts the tile's window out of the refined region's `heights`, writes it (with a heightmap
/// target's `place`) and its sidecar; returns the sidecar and its path.
fn write_tile(
    job: &TileJob,
    n: usize,
    heights: &Heightmap,
    key: WorldKey,
    place: Option<&InputPlace>,
) -> Result<(TileSidecar, PathBuf)> {
    let (t, region, format, tile_path) = (job.window, job.region, job.format, &job.tile_path);
    let (dx, dy) = (t.column - region.column, t.row - region.row);
    let mut data = Vec::with_capacity(t.width * t.height);
    for y in dy..dy + t.height {
        let row = y * region.side + dx;
        data.extend_from_slice(&heights.data[row..row + t.width]);
    }
    let mut map = Heightmap {
        width: t.width,
        height: t.height,
        data,
        cell_size_m: heights.cell_size_m,
    };
    // A DEM target's georeference and no-data cells, moved to the tile's window of the cells.
    let place = match place {
        Some(p) => p.apply_window(&ExportPlan::new(n)?, [t.column, t.row], &mut map, format),
        None => Place::default(),
    };
    write_raster(tile_path, format, &map, Sampling::Cells, None, &place, true)?;
    let bytes = std::fs::read(tile_path)
        .with_context(|| format!("cannot read back {}", tile_path.display()))?;
    let mut digest = Fnv::new();
    digest.add(&bytes);
    let sidecar = TileSidecar {
        format: "terrasketch-tile".into(),
        version: FORMAT_VERSION,
        world: job.world_name.clone(),
        key,
        tiles: job.tiles,
        overlap: job.overlap,
        tile: job.index,
        file: job.file_name.clone(),
        file_digest: digest.hex(),
        window: [t.column, t.row, t.width, t.height],
        cell_size_m: heights.cell_size_m[0],
    };
    let side_path = sidecar_path(tile_path);
    let mut text = serde_json::to_vec_pretty(&sidecar)?;
    text.push(b'\n');
    write_file_atomically(&side_path, &text)
        .with_context(|| format!("cannot write {}", side_path.display()))?;
    Ok((sidecar, side_path))
}
