//! `terrasketch solve`.

use std::path::PathBuf;

use anyhow::{Context, Result};
use terrasketch_multigrid::{Grid, SolverParams};
use terrasketch_raster::{Format, WriteOptions, write_heightmap_with};
use terrasketch_sketch::{check_cell_size, load_sketch};

use crate::BackendKind;
use crate::backend::AnySolver;
use crate::output::{ExportPlan, check_writable, refused};

/// Arguments of `terrasketch solve`.
pub struct SolveArgs {
    pub sketch: PathBuf,
    pub size: usize,
    pub backend: BackendKind,
    pub tolerance: Option<f32>,
    pub output: PathBuf,
    pub json: bool,
}

/// Loads, checks, solves and writes.
pub fn run(args: &SolveArgs) -> Result<()> {
    let parsed = load_sketch(&args.sketch)?;
    for w in &parsed.warnings {
        eprintln!("terrasketch: warning: {}: {w}", args.sketch.display());
    }
    let sketch = parsed.sketch;
    let plan = ExportPlan::new(args.size)?;
    let grid = Grid::new(plan.solve_n, sketch.extent_m).context("cannot solve at this size")?;
    check_cell_size(sketch.extent_m, grid.n)?;
    let format = check_writable(&args.output)?;
    let mut params = SolverParams::default();
    if let Some(t) = args.tolerance {
        if !(t.is_finite() && t > 0.0 && t < 1.0) {
            return Err(refused(format!(
                "--tolerance must be a number between 0 and 1 (exclusive), got {t}"
            )));
        }
        params.tolerance = t;
    }
    plan.check_memory()?;
    let mut solver = AnySolver::new(args.backend, grid, params)?;
    let report = solver.solve_sketch(&sketch)?;
    let heights = solver.heights()?;
    let (adapter, backend) = (solver.adapter(), solver.backend_name());
    // The solver's arrays are freed before the export allocates its own.
    drop(solver);
    let map = plan.sample(&heights, sketch.extent_m)?;
    drop(heights);
    if plan.resampled() {
        eprintln!("terrasketch: {}", plan.describe());
    }
    let options = WriteOptions {
        sampling: plan.sampling,
        ..WriteOptions::default()
    };
    let info = write_heightmap_with(&args.output, &map, &options)
        .with_context(|| format!("cannot write {}", args.output.display()))?;
    let stretch = info.stretch;
    if let Some(s) = stretch {
        eprintln!(
            "terrasketch: {} stretched over {} .. {} m (0 -> {} m, 65535 -> {} m){}",
            args.output.display(),
            s.min_m,
            s.max_m,
            s.min_m,
            s.max_m,
            if format == Format::Png16 {
                "; stored in the PNG's text chunks"
            } else {
                ""
            }
        );
    }
    if args.json {
        let out = serde_json::json!({
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
            "height_min_m": report.height_min_m,
            "height_max_m": report.height_max_m,
            "output": args.output.display().to_string(),
            "format": format.extension(),
            "stretch_min_m": stretch.map(|s| s.min_m),
            "stretch_max_m": stretch.map(|s| s.max_m),
        });
        println!("{out}");
    } else {
        let r = &report;
        eprintln!(
            "terrasketch: solved {}^2 on {} in {:.1} ms ({} V-cycles, {:.2} WU, residual {:.2e}); heights {:.1} .. {:.1} m",
            grid.n,
            adapter,
            r.ms_total,
            r.vcycles,
            r.work_units,
            r.residual_final,
            r.height_min_m,
            r.height_max_m
        );
    }
    Ok(())
}
