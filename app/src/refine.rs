//! `terrasketch refine`: the realism pass on the command line.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use terrasketch_multigrid::{ConstraintMaps, CpuSolver, Grid, SolverParams};
use terrasketch_raster::{Format, Georef, Heightmap, ReadOptions, read_raster};
use terrasketch_sketch::{Sketch, load_sketch};
use terrasketch_synthesis::refine::field::{Field, upsample};
use terrasketch_synthesis::refine::{
    LevelView, PreparedExemplar, RefineInput, RefineParams, RefineStats, prepare_exemplars,
    refine_levels,
};
use terrasketch_synthesis::{
    Dem, LoadOptions, load_dem, load_exemplar_dir, resample_to_cell_size, shipped_exemplar_dir,
};

use crate::output::{ExportPlan, Place, check_writable, write_raster};
use crate::tiles::{TileSpec, layout};

/// Arguments of `terrasketch refine`.
pub struct RefineArgs {
    pub input: PathBuf,
    pub exemplars: Vec<PathBuf>,
    pub size: usize,
    pub output: Option<PathBuf>,
    pub seed: u64,
    pub patch_size: usize,
    pub detail_scale: Option<usize>,
    /// `--fine-detail`: [`RefineParams::fine_detail`].
    pub fine_detail: f32,
    pub cache_dir: Option<PathBuf>,
    /// `--tiles` text, `--overlap`, `--tile-name`.
    pub tiles: Option<(String, usize, String)>,
    /// `--tile I,J`: compute only this tile of the `--tiles` world (see `tiled.rs`).
    pub tile: Option<String>,
    /// `--coarse FILE`: the world's shared coarse levels, written by `--coarse-out`.
    pub coarse: Option<PathBuf>,
    /// `--coarse-out FILE`: compute the world's shared coarse levels into FILE and stop.
    pub coarse_out: Option<PathBuf>,
    pub json: bool,
}

impl RefineArgs {
    /// The refinement parameters of the command line.
    pub(crate) fn params(&self) -> RefineParams {
        RefineParams {
            seed: self.seed,
            patch_size: self.patch_size,
            lowpass_cells: self.detail_scale.unwrap_or(0),
            fine_detail: self.fine_detail,
            ..RefineParams::default()
        }
    }
}

/// A progress bar on stderr (nothing when `quiet`).
pub(crate) struct Bar {
    pub(crate) quiet: bool,
    pub(crate) last: std::sync::Mutex<(i32, String)>,
}

impl Bar {
    pub(crate) fn show(&self, frac: f32, what: &str) {
        if self.quiet {
            return;
        }
        let pct = (frac.clamp(0.0, 1.0) * 100.0) as i32;
        let mut last = self.last.lock().unwrap_or_else(|e| e.into_inner());
        if last.0 == pct && last.1 == what {
            return;
        }
        *last = (pct, what.to_owned());
        let filled = (pct / 4) as usize;
        eprint!(
            "\r[{}{}] {pct:3}% {what:<32}",
            "#".repeat(filled),
            "-".repeat(25 - filled)
        );
        let _ = std::io::stderr().flush();
    }
    pub(crate) fn finish(&self) {
        if !self.quiet {
            eprintln!();
        }
    }
}

/// Loads every exemplar path (files or folders); the shipped library when none is given.
pub(crate) fn load_exemplars(paths: &[PathBuf]) -> Result<Vec<Dem>> {
    let default = [shipped_exemplar_dir()];
    let paths = if paths.is_empty() {
        &default[..]
    } else {
        paths
    };
    let mut dems = Vec::new();
    for p in paths {
        if p.is_dir() {
            let (mut found, failures) = load_exemplar_dir(p);
            for (f, e) in failures {
                eprintln!(
                    "terrasketch: warning: exemplar {} skipped: {e}",
                    f.display()
                );
            }
            if found.is_empty() {
                bail!("exemplar folder {} holds no readable DEM", p.display());
            }
            dems.append(&mut found);
        } else if p.exists() {
            dems.push(
                load_dem(p, &LoadOptions::default())
                    .with_context(|| format!("cannot load exemplar {}", p.display()))?,
            );
        } else {
            bail!("exemplar {} does not exist", p.display());
        }
    }
    Ok(dems)
}

/// Where a heightmap target's refined square sits in its input file, so that the output keeps
/// the input's place: its georeference and no-data cells.
pub(crate) struct InputPlace {
    /// The input's georeference (north-up, as read).
    georef: Option<Georef>,
    /// The input's no-data value.
    nodata: Option<f64>,
    /// The input's no-data cells (empty when none), `width` per row.
    nodata_mask: Vec<bool>,
    width: usize,
    /// Column and row of the square's north-west cell in the input.
    origin: [usize; 2],
    /// Input cells per side of the square.
    side: usize,
}

impl InputPlace {
    /// The place of an export of the square by `plan`: the georeference moved to the square and
    /// scaled to the samples, and the no-data value. Marks no-data samples (those whose pixel
    /// centre falls in a no-data input cell) with the value when the output is a GeoTIFF.
    fn apply(&self, plan: &ExportPlan, map: &mut Heightmap, format: Format) -> Place {
        self.apply_window(plan, [0, 0], map, format)
    }

    /// [`InputPlace::apply`] for a window of the export whose first sample is the export's
    /// sample `at` (`[column, row]` from the north-west): a tile of a tiled world.
    pub(crate) fn apply_window(
        &self,
        plan: &ExportPlan,
        at: [usize; 2],
        map: &mut Heightmap,
        format: Format,
    ) -> Place {
        let (a, b) = plan.pixel_span(self.side as f64);
        let a = [a + b * at[0] as f64, a + b * at[1] as f64];
        let [x0, y0] = [self.origin[0] as f64 + a[0], self.origin[1] as f64 + a[1]];
        let georef = self.georef.as_ref().map(|g| g.remapped([x0, b], [y0, b]));
        if let Some(nodata) = self.nodata
            && format == Format::Tiff
            && !self.nodata_mask.is_empty()
        {
            let input_cell = |k: usize, o: f64, origin: usize| {
                let at = o + b * (k as f64 + 0.5);
                (at.floor().max(origin as f64) as usize).min(origin + self.side - 1)
            };
            for row in 0..map.height {
                let r = input_cell(row, y0, self.origin[1]);
                for column in 0..map.width {
                    if self.nodata_mask[r * self.width + input_cell(column, x0, self.origin[0])] {
                        map.data[row * map.width + column] = nodata as f32;
                    }
                }
            }
        }
        Place {
            georef,
            nodata: self.nodata,
        }
    }
}

/// Reads a heightmap or DEM file (any format the raster crate reads, warnings printed when
/// `warn`): its heights and the place of its centred square.
fn read_input(path: &Path, warn: bool) -> Result<(Dem, InputPlace)> {
    let options = ReadOptions {
        unit_cells_when_absent: true,
        ..ReadOptions::default()
    };
    let raster = read_raster(path, &options)?;
    if warn {
        for w in &raster.source.warnings {
            eprintln!("terrasketch: warning: {}: {w}", path.display());
        }
    }
    let nodata_mask = raster.nodata_mask.clone();
    let (georef, nodata) = (raster.source.georef.clone(), raster.source.nodata);
    let dem = Dem::from_raster(raster);
    let side = dem.width.min(dem.height);
    if side < 16 {
        bail!(
            "{} is too small ({}x{})",
            path.display(),
            dem.width,
            dem.height
        );
    }
    let place = InputPlace {
        georef,
        nodata,
        nodata_mask,
        width: dem.width,
        origin: [(dem.width - side) / 2, (dem.height - side) / 2],
        side,
    };
    Ok((dem, place))
}

/// Where the refined square of a heightmap target sits in its file (see [`heightmap_target`]).
pub(crate) fn input_place(path: &Path) -> Result<InputPlace> {
    Ok(read_input(path, false)?.1)
}

/// The target from a heightmap or DEM file: a centred square crop resampled to `n x n`, and
/// where that square sits in the file.
pub(crate) fn heightmap_target(path: &Path, n: usize) -> Result<(RefineInput, InputPlace)> {
    let (dem, place) = read_input(path, true)?;
    let (side, [x0, y0]) = (place.side, place.origin);
    let mut sq = Vec::with_capacity(side * side);
    for y in y0..y0 + side {
        sq.extend_from_slice(&dem.heights_m[y * dem.width + x0..y * dem.width + x0 + side]);
    }
    let extent = side as f64 * dem.cell_size_m[0].max(dem.cell_size_m[1]);
    let cell = extent / n as f64;
    let square = Dem {
        width: side,
        height: side,
        heights_m: sq,
        cell_size_m: [extent / side as f64; 2],
        ..dem
    };
    let r = resample_to_cell_size(&square, cell)?;
    // Rounding may leave a cell more or less: clamp-copy to exactly n x n.
    let data = (0..n * n)
        .map(|i| {
            let (x, y) = ((i % n).min(r.width - 1), (i / n).min(r.height - 1));
            r.heights_m[y * r.width + x]
        })
        .collect();
    let input = RefineInput::target_only(n, cell, data);
    Ok((input, place))
}

/// The target from a sketch: CPU solve; hard elevation constraints and the diffused roughness.
pub(crate) fn sketch_target(path: &Path, n: usize) -> Result<(RefineInput, f64)> {
    let parsed = load_sketch(path)?;
    for w in &parsed.warnings {
        eprintln!("terrasketch: warning: {}: {w}", path.display());
    }
    let sketch = parsed.sketch;
    let grid = Grid::new(n, sketch.extent_m).context("cannot refine at this size")?;
    square_cell_m(&sketch, &grid).map_err(|e| anyhow::anyhow!("{e}"))?;
    let t = Instant::now();
    // Plain FCG (no stop-test relaxation): an offline target takes the solve's every global
    // iteration, one of which costs nothing next to the synthesis, and its tiles' overlaps agree.
    let params = SolverParams {
        stop_relaxation: false,
        ..SolverParams::default()
    };
    let mut solver = CpuSolver::new(grid, params)?;
    solver.set_sketch(&sketch);
    solver.solve();
    let roughness = solver.roughness().to_vec();
    let ms_solve = t.elapsed().as_secs_f64() * 1e3;
    let maps = ConstraintMaps::rasterize(&sketch, &grid);
    let input = sketch_refine_input(&sketch, &grid, &maps, solver.heights(), Some(&roughness))
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    Ok((input, ms_solve))
}

/// Rows of a `side`-wide square raster in reverse order: converts between the solver's row 0 = south
/// and the rasters' row 0 = north (an involution).
pub(crate) fn flip_rows(v: &[f32], side: usize) -> Vec<f32> {
    (0..side)
        .rev()
        .flat_map(|j| v[j * side..(j + 1) * side].iter().copied())
        .collect()
}

/// The refinement input for a solved sketch (used by the command line and the editor): the solved
/// `heights` (row 0 = south, `grid.n`^2), the hard elevation constraints of the sketch's rasterised
/// `maps`, and the diffused
/// `roughness` of level 2 (`(n / 4)^2`, row 0 = south) upsampled to the grid. Fails on non-square
/// cells or heights of the wrong size.
pub(crate) fn sketch_refine_input(
    sketch: &Sketch,
    grid: &Grid,
    maps: &ConstraintMaps,
    heights: &[f32],
    roughness: Option<&[f32]>,
) -> std::result::Result<RefineInput, String> {
    let n = grid.n;
    let cx = square_cell_m(sketch, grid)?;
    if heights.len() != n * n {
        return Err("heights of the wrong size".into());
    }
    let mask: Vec<bool> = flip_rows(&maps.elev_weight, n)
        .iter()
        .map(|&w| w >= 1.0)
        .collect();
    // Roughness lives on level 2 (n / 4): bilinear upsampling to n.
    let rs = n / 4;
    let roughness = roughness
        .filter(|r| rs >= 1 && r.len() == rs * rs)
        .map(|r| {
            let coarse = Field::new(rs, rs, flip_rows(r, rs));
            upsample(&coarse, 4, n, n)
                .v
                .into_iter()
                .map(|v| v.clamp(0.0, 1.0))
                .collect()
        });
    Ok(RefineInput {
        target: Heightmap {
            width: n,
            height: n,
            data: flip_rows(heights, n),
            cell_size_m: [cx; 2],
        },
        constraint_mask: Some(mask),
        constraint_values: Some(flip_rows(&maps.elev_value, n)),
        constraint_tolerance: stroke_tolerance(sketch, grid),
        roughness,
        sinks: None,
    })
}

/// Each stroke's `height_tolerance_m` on the cells along its curve (row 0 = north; `None` when
/// every stroke keeps its heights exactly). A cell takes the tolerance of the nearest curve
/// sample within 1.5 cells; later strokes win ties, as in the constraint raster.
fn stroke_tolerance(sketch: &Sketch, grid: &Grid) -> Option<Vec<f32>> {
    if sketch.strokes.iter().all(|s| s.height_tolerance_m <= 0.0) {
        return None;
    }
    let n = grid.n;
    let [cell, _] = grid.cell_size_m();
    let mut best = vec![(f64::INFINITY, 0.0f32); n * n];
    let curves = terrasketch_sketch::stroke_curves(sketch, cell);
    for (stroke, curve) in sketch.strokes.iter().zip(&curves) {
        let tol = stroke.height_tolerance_m as f32;
        for seg in curve.points.windows(2) {
            let (a, b) = (seg[0], seg[1]);
            let steps = ((b[0] - a[0]).hypot(b[1] - a[1]) / (0.5 * cell))
                .ceil()
                .max(1.0) as usize;
            for s in 0..=steps {
                let t = s as f64 / steps as f64;
                let (x, y) = (a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1]));
                let (ci, cj) = (
                    (x / cell - 0.5).round() as i64,
                    (y / cell - 0.5).round() as i64,
                );
                for j in cj - 1..=cj + 1 {
                    for i in ci - 1..=ci + 1 {
                        if i < 0 || j < 0 || i >= n as i64 || j >= n as i64 {
                            continue;
                        }
                        let d = ((i as f64 + 0.5) * cell - x).hypot((j as f64 + 0.5) * cell - y);
                        // Row 0 = north.
                        let k = (n - 1 - j as usize) * n + i as usize;
                        if d <= best[k].0 {
                            best[k] = (d, tol);
                        }
                    }
                }
            }
        }
    }
    Some(best.into_iter().map(|(_, t)| t).collect())
}

/// The cell size of `grid`, which must be square (the synthesis works on square cells).
pub(crate) fn square_cell_m(sketch: &Sketch, grid: &Grid) -> std::result::Result<f64, String> {
    let [cx, cy] = grid.cell_size_m();
    if (cx - cy).abs() > 1e-6 * cx.max(cy) {
        return Err(format!(
            "refine needs square cells; the sketch's extent {:?} m gives {cx} x {cy} m",
            sketch.extent_m
        ));
    }
    Ok(cx)
}

/// Where exemplar feature networks are cached by default: `$XDG_CACHE_HOME/terrasketch/features`
/// (else `~/.cache/terrasketch/features`).
pub(crate) fn default_cache_dir() -> Option<PathBuf> {
    let base = std::env::var_os("XDG_CACHE_HOME")
        .map(PathBuf::from)
        .filter(|p| p.is_absolute())
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cache")))?;
    Some(base.join("terrasketch").join("features"))
}

/// The tiles asked for, checked before any work.
fn refine_tiles(args: &RefineArgs, plan: &ExportPlan) -> Result<Option<TileSpec>> {
    let Some((text, overlap, pattern)) = &args.tiles else {
        return Ok(None);
    };
    let spec = TileSpec::from_args(text, *overlap, pattern)?;
    layout(plan.samples, plan.samples, plan.sampling, &spec)?;
    Ok(Some(spec))
}

/// Loads, prepares, refines and writes.
pub fn run(args: &RefineArgs) -> Result<()> {
    if args.tile.is_some() || args.coarse_out.is_some() || args.coarse.is_some() {
        return crate::tiled::run(args);
    }
    let t0 = Instant::now();
    let plan = ExportPlan::new(args.size)?;
    plan.check_refine_memory()?;
    let Some(output) = args.output.as_deref() else {
        return Err(crate::output::refused("refine needs -o OUT"));
    };
    let format = check_writable(output)?;
    let tiles = refine_tiles(args, &plan)?;
    let ext = args
        .input
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .unwrap_or_default();
    if !args.input.exists() {
        bail!("{} does not exist", args.input.display());
    }
    let (input, ms_solve, input_place) = if ext == "json" {
        let (input, ms_solve) = sketch_target(&args.input, plan.solve_n)?;
        (input, ms_solve, None)
    } else {
        let (input, place) = heightmap_target(&args.input, plan.solve_n)?;
        (input, 0.0, Some(place))
    };
    let bar = Bar {
        quiet: args.json,
        last: std::sync::Mutex::new((-1, String::new())),
    };
    let t_prep = Instant::now();
    let prepared = prepare(args, input.target.cell_size_m[0], &bar)?;
    let ms_prepare = t_prep.elapsed().as_secs_f64() * 1e3;
    let params = args.params();
    let cancel = AtomicBool::new(false);
    let prog = |f: f32, what: &str| bar.show(0.1 + 0.9 * f, what);
    let t_levels = Instant::now();
    // From the exemplars' preparation to the first (coarsest) level: what the editor, which
    // has its solve already, waits before it shows refined land.
    let first_level_ms = std::cell::Cell::new(None::<f64>);
    let on_level = |l: &LevelView| {
        if first_level_ms.get().is_none() {
            first_level_ms.set(Some(t_prep.elapsed().as_secs_f64() * 1e3));
        }
        if !args.json {
            bar.finish();
            eprintln!(
                "terrasketch: level {}/{} done: {}^2 at {:.1} m, {:.1} s",
                l.index + 1,
                l.count,
                l.level.side,
                l.level.cell_m,
                t_levels.elapsed().as_secs_f64()
            );
        }
    };
    let out = refine_levels(&input, &prepared, &params, &prog, &on_level, &cancel)?;
    bar.finish();
    for w in &out.stats.warnings {
        eprintln!("terrasketch: warning: {w}");
    }
    let mut map = plan.sample_north_up(out.heights.clone())?;
    if plan.resampled() && !args.json {
        eprintln!(
            "terrasketch: {}",
            plan.describe().replace("solve", "refinement")
        );
    }
    let place = match &input_place {
        Some(p) => p.apply(&plan, &mut map, format),
        None => Place::default(),
    };
    let (_, written_json) = write_raster(
        output,
        format,
        &map,
        plan.sampling,
        tiles.as_ref(),
        &place,
        args.json,
    )?;
    let timings = [
        t0.elapsed().as_secs_f64() * 1e3,
        ms_solve,
        ms_prepare,
        first_level_ms.get().unwrap_or(0.0),
    ];
    report(
        args,
        &plan,
        output,
        &input,
        &prepared,
        &out.stats,
        timings,
        written_json,
    );
    Ok(())
}

/// Loads and prepares the exemplars for `cell_m` cells (cached), printing their warnings.
fn prepare(args: &RefineArgs, cell_m: f64, bar: &Bar) -> Result<Vec<PreparedExemplar>> {
    let dems = load_exemplars(&args.exemplars)?;
    let cache = args.cache_dir.clone().or_else(default_cache_dir);
    let prog = |f: f32, what: &str| bar.show(0.1 * f, what);
    let prepared = prepare_exemplars(&dems, cell_m, cache.as_deref(), &prog)?;
    for e in &prepared {
        if let Some(w) = &e.cache_warning {
            eprintln!("terrasketch: warning: {}: {w}", e.name);
        }
        for w in &e.warnings {
            eprintln!("terrasketch: warning: {w}");
        }
    }
    Ok(prepared)
}

/// Prints the run's figures: one JSON object on stdout with `--json`, else one line on stderr.
/// `timings` are the total, solve and exemplar-preparation milliseconds, and those from the
/// preparation's start to the first finished pyramid level.
#[allow(clippy::too_many_arguments)]
fn report(
    args: &RefineArgs,
    plan: &ExportPlan,
    output: &Path,
    input: &RefineInput,
    prepared: &[PreparedExemplar],
    s: &RefineStats,
    timings: [f64; 4],
    written: serde_json::Value,
) {
    let [ms_total, ms_solve, ms_prepare, ms_first_level] = timings;
    if args.json {
        let mut json = serde_json::json!({
            "ms_total": ms_total,
            "ms_solve": ms_solve,
            "ms_prepare_exemplars": ms_prepare,
            "ms_refine": s.ms_total,
            "ms_first_level": ms_first_level,
            "ms_phases": s.ms_phases.iter().map(|(k, v)| (k.clone(), serde_json::json!(v))).collect::<serde_json::Map<String, serde_json::Value>>(),
            "size": args.size,
            "cell_size_m": input.target.cell_size_m[0],
            "seed": args.seed,
            "patch_size": args.patch_size,
            "fine_detail": args.fine_detail,
            "patches_feature": s.patches_feature,
            "patches_fill": s.patches_fill,
            "exemplars": s.exemplars,
            "exemplar_names": prepared.iter().map(|e| e.name.clone()).collect::<Vec<_>>(),
            "features_from_cache": prepared.iter().filter(|e| e.features_from_cache).count(),
            "target_feature_lines": s.target_feature_lines,
            "fill_sites": s.fill_sites,
            "feature_sites": s.feature_sites,
            "pits_before": s.pits_before,
            "pits_after": s.pits_after,
            "pits_after_per_100km2": s.pits_after_per_100km2,
            "exemplar_pits_per_100km2": s.exemplar_pits_per_100km2,
            "constraint_max_error_m": s.constraint_max_error_m,
            "constraint_max_excess_m": s.constraint_max_excess_m,
            "constraint_tolerance_max_m": s.constraint_tolerance_max_m,
            "levels": s.levels,
            "constraint_relief_m": s.constraint_relief_m,
            "relief_m": s.relief_m,
            "slope_w1_to_exemplars": s.slope_w1_to_exemplars,
            "slope_w1_diffusion_to_exemplars": s.slope_w1_input_to_exemplars,
            "slope_w1_to_all_exemplars": s.slope_w1_to_all_exemplars,
            "slope_w1_diffusion_to_all_exemplars": s.slope_w1_input_to_all_exemplars,
            "exemplar_cells_used": s.exemplar_cells_used.iter().map(|(k, v)| (k.clone(), serde_json::json!(v))).collect::<serde_json::Map<String, serde_json::Value>>(),
            "seam_laplacian_p99_ratio": s.seam_laplacian_p99_ratio,
            "seam_gradient_jump_ratio": s.seam_gradient_jump_ratio,
            "output": output.display().to_string(),
            "refine_size": plan.solve_n,
            "sampling": plan.sampling.name(),
            "resampled": plan.resampled(),
        });
        if let (Some(out), serde_json::Value::Object(more)) = (json.as_object_mut(), written) {
            out.extend(more);
        }
        println!("{json}");
    } else {
        eprintln!(
            "terrasketch: refined {}^2 in {:.1} s with {} exemplars: {} feature + {} fill patches, pits {} -> {}, constraint error {:.3} m (tolerance up to {:.2} m, {:.3} m outside it), slope W1 to exemplars {:.2} (input {:.2}) deg",
            args.size,
            ms_total / 1e3,
            s.exemplars,
            s.patches_feature,
            s.patches_fill,
            s.pits_before,
            s.pits_after,
            s.constraint_max_error_m,
            s.constraint_tolerance_max_m,
            s.constraint_max_excess_m,
            s.slope_w1_to_exemplars,
            s.slope_w1_input_to_exemplars
        );
    }
}
