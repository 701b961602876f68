//! `terrasketch solve`.

use std::path::PathBuf;

use anyhow::{Context, Result};
use serde_json::{Value, json};
use terrasketch_multigrid::{Grid, SolverParams};
use terrasketch_raster::{Heightmap, write_file_atomically};
use terrasketch_sketch::{check_cell_size, load_sketch};

use crate::BackendKind;
use crate::backend::AnySolver;
use crate::mesh::{self, MAX_MESH_SIDE};
use crate::output::{ExportPlan, OutputKind, Place, check_output, refused, write_raster};
use crate::tiles::{TileSpec, layout};

/// Arguments of `terrasketch solve`.
pub struct SolveArgs {
    pub sketch: PathBuf,
    pub size: usize,
    pub backend: BackendKind,
    pub tolerance: Option<f32>,
    pub output: PathBuf,
    /// `--tiles` text, `--overlap`, `--tile-name`.
    pub tiles: Option<(String, usize, String)>,
    /// `--max-error` of a mesh, metres.
    pub max_error_m: Option<f64>,
    /// Add the procedural detail (`--detail on`, the default).
    pub detail: bool,
    pub json: bool,
}

/// Loads, checks, solves and writes.
pub fn run(args: &SolveArgs) -> Result<()> {
    let parsed = load_sketch(&args.sketch)?;
    for w in &parsed.warnings {
        eprintln!("terrasketch: warning: {}: {w}", args.sketch.display());
    }
    let sketch = parsed.sketch;
    let kind = check_output(&args.output)?;
    let plan = plan_for(args, kind)?;
    let grid = Grid::new(plan.solve_n, sketch.extent_m).context("cannot solve at this size")?;
    check_cell_size(sketch.extent_m, grid.n)?;
    let tiles = tile_spec(args, kind, &plan)?;
    let mut params = SolverParams::default();
    if let Some(t) = args.tolerance {
        if !(t.is_finite() && t > 0.0 && t < 1.0) {
            return Err(refused(format!(
                "--tolerance must be a number between 0 and 1 (exclusive), got {t}"
            )));
        }
        params.tolerance = t;
    }
    let mesh_bytes_per_sample = if matches!(kind, OutputKind::Raster(_)) {
        0
    } else {
        200
    };
    plan.check_memory(mesh_bytes_per_sample)?;
    let mut solver = AnySolver::new(args.backend, grid, params)?;
    let report = solver.solve_sketch(&sketch)?;
    let mut heights = solver.heights()?;
    let t_detail = std::time::Instant::now();
    if args.detail {
        let amp = crate::detail::amplitude_any(&mut solver, &sketch, &grid)?;
        terrasketch_detail::add_detail(&mut heights, grid.n, sketch.extent_m, &amp, sketch.seed);
    }
    let detail_ms = t_detail.elapsed().as_secs_f64() * 1e3;
    let (adapter, backend) = (solver.adapter(), solver.backend_name());
    // The solver's arrays are freed before the export allocates its own.
    drop(solver);
    let map = plan.sample(&heights, sketch.extent_m)?;
    drop(heights);
    if plan.resampled() {
        eprintln!("terrasketch: {}", plan.describe());
    }
    let written = write_output(args, kind, &plan, tiles.as_ref(), &map)?;
    if args.json {
        let mut out = json!({
            "size": plan.samples,
            "solve_size": grid.n,
            "sampling": plan.sampling.name(),
            "resampled": plan.resampled(),
            "cell_size_m": map.cell_size_m,
            "backend": backend,
            "adapter": adapter,
            "levels": report.levels,
            "vcycles": report.vcycles,
            "work_units": report.work_units,
            "field_work_units": report.field_work_units,
            "residual_initial": report.residual_initial,
            "residual_final": report.residual_final,
            "converged": report.converged,
            "ms_total": report.ms_total,
            "detail": args.detail,
            "detail_ms": detail_ms,
            "height_min_m": report.height_min_m,
            "height_max_m": report.height_max_m,
            "output": args.output.display().to_string(),
        });
        if let (Some(out), Value::Object(more)) = (out.as_object_mut(), written) {
            out.extend(more);
        }
        println!("{out}");
    } else {
        eprintln!(
            "terrasketch: solved {}^2 on {} in {:.1} ms ({} V-cycles, {:.2} WU, residual {:.2e}); heights {:.1} .. {:.1} m",
            grid.n,
            adapter,
            report.ms_total,
            report.vcycles,
            report.work_units,
            report.residual_final,
            report.height_min_m,
            report.height_max_m
        );
    }
    Ok(())
}

/// The export plan: rasters take `--size` as it is; a mesh is always corner-sampled, so a
/// power-of-two size gives the `size + 1` corners of the `size` cells.
fn plan_for(args: &SolveArgs, kind: OutputKind) -> Result<ExportPlan> {
    let plan = ExportPlan::new(args.size)?;
    if matches!(kind, OutputKind::Raster(_)) {
        if args.max_error_m.is_some() {
            return Err(refused("--max-error applies to mesh outputs (.glb, .obj)"));
        }
        return Ok(plan);
    }
    ExportPlan::new(mesh_samples(args.size, args.max_error_m)?)
}

/// The samples per side of a mesh export at `--size`: a power of two gives the `size + 1`
/// corners of its cells. Checks `--max-error`.
pub(crate) fn mesh_samples(size: usize, max_error_m: Option<f64>) -> Result<usize> {
    let samples = if size.is_power_of_two() {
        size + 1
    } else {
        size
    };
    if samples > MAX_MESH_SIDE {
        return Err(refused(format!(
            "--size {size}: a mesh has at most {MAX_MESH_SIDE} samples per side (--size 4096 or 4097)"
        )));
    }
    if let Some(m) = max_error_m {
        if !(m.is_finite() && m > 0.0) {
            return Err(refused(format!(
                "--max-error must be a positive number of metres, got {m}"
            )));
        }
        if !(samples - 1).is_power_of_two() {
            return Err(refused(format!(
                "--max-error needs --size 2^k or 2^k+1 (e.g. 1024 or 1025), got {size}"
            )));
        }
    }
    Ok(samples)
}

/// The tiles asked for, checked before the solve (rasters only).
fn tile_spec(args: &SolveArgs, kind: OutputKind, plan: &ExportPlan) -> Result<Option<TileSpec>> {
    let Some((text, overlap, pattern)) = &args.tiles else {
        return Ok(None);
    };
    if !matches!(kind, OutputKind::Raster(_)) {
        return Err(refused(
            "--tiles writes rasters (.exr, .tif, .png, .r16), not meshes",
        ));
    }
    let spec = TileSpec::from_args(text, *overlap, pattern)?;
    layout(plan.samples, plan.samples, plan.sampling, &spec)?;
    Ok(Some(spec))
}

/// Writes the raster, its tiles or the mesh; returns the JSON fields that describe what was
/// written.
fn write_output(
    args: &SolveArgs,
    kind: OutputKind,
    plan: &ExportPlan,
    tiles: Option<&TileSpec>,
    map: &Heightmap,
) -> Result<Value> {
    let format = match kind {
        OutputKind::Raster(format) => format,
        OutputKind::Glb | OutputKind::Obj => {
            let mesh = mesh::build(map, args.max_error_m)?;
            let bytes = match kind {
                OutputKind::Glb => mesh::to_glb(&mesh)?,
                _ => mesh::to_obj(&mesh)?,
            };
            write_file_atomically(&args.output, &bytes)
                .with_context(|| format!("cannot write {}", args.output.display()))?;
            let triangles = mesh.indices.len() / 3;
            eprintln!(
                "terrasketch: {} written: {} vertices, {triangles} triangles",
                args.output.display(),
                mesh.positions.len()
            );
            return Ok(json!({
                "format": if kind == OutputKind::Glb { "glb" } else { "obj" },
                "vertices": mesh.positions.len(),
                "triangles": triangles,
                "max_error_m": args.max_error_m,
            }));
        }
    };
    let quiet = false;
    let (_, json) = write_raster(
        &args.output,
        format,
        map,
        plan.sampling,
        tiles,
        &Place::default(),
        quiet,
    )?;
    Ok(json)
}
