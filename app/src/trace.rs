//! `terrasketch trace`: a real DEM's main valleys and ridges as an editable sketch.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result};
use clap::{Args, ValueEnum};
use terrasketch_raster::{Heightmap, write_heightmap};
use terrasketch_sketch::{Falloff, MAX_EXTENT_M, save_sketch_atomic};
use terrasketch_synthesis::protocol::square_at_own_cell;
use terrasketch_synthesis::trace::{MAX_TRACE_STROKES, TraceError, TraceGrid, TraceParams, trace};
use terrasketch_synthesis::{DemError, LoadOptions, load_dem};

use crate::output::{check_folder, check_writable, refused};

/// Falloff of the traced strokes.
#[derive(Copy, Clone, Debug, PartialEq, Eq, ValueEnum)]
pub enum FalloffChoice {
    /// Fitted per stroke to the DEM's cross-sections, among the fading `foot` and `sigmoid`.
    Auto,
    /// `foot` on every stroke.
    Foot,
    /// `sigmoid` on every stroke.
    Sigmoid,
    /// `none` (constant slope) on every stroke.
    None,
}

/// Arguments of `terrasketch trace`.
#[derive(Args, Debug)]
pub struct TraceArgs {
    /// The DEM: .tif, .hgt, .asc, .png (16-bit grey or Terrarium).
    pub dem: PathBuf,
    /// The sketch to write (JSON); the DEM's extent, x east and y north from its south-west corner.
    #[arg(short = 'o', long = "output")]
    pub output: PathBuf,
    /// Most strokes: half valleys (rounded up), half ridges, the largest first.
    #[arg(long, default_value_t = 200)]
    pub strokes: usize,
    /// Shortest stroke in metres [default: 1/32 of the DEM's larger side, at least 8 cells].
    #[arg(long = "min-length", value_name = "M")]
    pub min_length_m: Option<f64>,
    /// Cells a valley or ridge line drains at least [default: 1/1000 of the DEM's cells].
    #[arg(long = "channel-cells", value_name = "CELLS")]
    pub channel_cells: Option<u32>,
    /// Falloff of the strokes' slopes.
    #[arg(long, value_enum, default_value_t = FalloffChoice::Auto)]
    pub falloff: FalloffChoice,
    /// Trace only the DEM's centred square of the largest power of two up to CELLS a side (64 or
    /// more), on its own grid: `solve --size` that power then samples the DEM's own cells.
    #[arg(long, value_name = "CELLS")]
    pub crop: Option<usize>,
    /// Also write the grid that was traced (after --crop) as a heightmap (.exr, .tif, .png, .r16),
    /// to compare the solved sketch with.
    #[arg(long = "dem-output", value_name = "FILE")]
    pub dem_output: Option<PathBuf>,
    /// Cell size in metres, for DEM files that do not state one.
    #[arg(long = "cell-size", value_name = "M")]
    pub cell_size_m: Option<f64>,
    /// Print one JSON object with the figures on stdout.
    #[arg(long)]
    pub json: bool,
}

/// Loads, traces and writes.
pub fn run(args: &TraceArgs) -> Result<()> {
    check_args(args)?;
    let opts = LoadOptions {
        cell_size_m: args.cell_size_m,
        ..LoadOptions::default()
    };
    let dem = load_dem(&args.dem, &opts).map_err(|e| match e {
        DemError::Io { .. } => anyhow::Error::new(e),
        other => refused(other.to_string()),
    })?;
    for w in &dem.source.warnings {
        eprintln!("terrasketch: warning: {}: {w}", args.dem.display());
    }
    let (heights, width, height, cell) = match args.crop {
        Some(max_side) => {
            let (h, n, cell) = square_at_own_cell(&dem, max_side).map_err(refused)?;
            (h, n, n, cell)
        }
        None => (dem.heights_m, dem.width, dem.height, dem.cell_size_m),
    };
    let params = TraceParams {
        max_strokes: args.strokes,
        min_length_m: args.min_length_m,
        channel_cells: args.channel_cells,
        falloff: match args.falloff {
            FalloffChoice::Auto => None,
            FalloffChoice::Foot => Some(Falloff::Foot),
            FalloffChoice::Sigmoid => Some(Falloff::Sigmoid),
            FalloffChoice::None => Some(Falloff::None),
        },
    };
    let grid = TraceGrid {
        heights: &heights,
        width,
        height,
        cell_size_m: cell,
    };
    let start = Instant::now();
    let traced = trace(&grid, &params).map_err(|e| match e {
        TraceError::Sketch(_) => anyhow::Error::new(e),
        other => refused(format!("{}: {other}", args.dem.display())),
    })?;
    let ms_trace = start.elapsed().as_secs_f64() * 1e3;
    for w in &traced.warnings {
        eprintln!("terrasketch: warning: {}: {w}", args.dem.display());
    }
    save_sketch_atomic(&traced.sketch, &args.output)
        .with_context(|| format!("cannot write {}", args.output.display()))?;
    if let Some(path) = &args.dem_output {
        let map = Heightmap {
            width,
            height,
            data: heights,
            cell_size_m: cell,
        };
        write_heightmap(path, &map).with_context(|| format!("cannot write {}", path.display()))?;
    }
    let points: usize = traced.sketch.strokes.iter().map(|s| s.points.len()).sum();
    if args.json {
        let out = serde_json::json!({
            "dem": args.dem.display().to_string(),
            "width": width,
            "height": height,
            "cell_size_m": cell,
            "extent_m": traced.sketch.extent_m,
            "valleys": traced.valleys,
            "ridges": traced.ridges,
            "lines_split": traced.lines_split,
            "points": points,
            "ms_trace": ms_trace,
            "warnings": traced.warnings,
            "output": args.output.display().to_string(),
        });
        println!("{out}");
    } else {
        eprintln!(
            "terrasketch: traced {} valleys and {} ridges ({points} control points) from {width}x{height} cells of {:.1} x {:.1} m in {ms_trace:.0} ms; wrote {}",
            traced.valleys,
            traced.ridges,
            cell[0],
            cell[1],
            args.output.display()
        );
    }
    Ok(())
}

/// Refuses bad options before the DEM is read, and outputs that cannot be written.
fn check_args(args: &TraceArgs) -> Result<()> {
    if !(1..=MAX_TRACE_STROKES).contains(&args.strokes) {
        return Err(refused(format!(
            "--strokes must be 1 to {MAX_TRACE_STROKES}, got {}",
            args.strokes
        )));
    }
    if let Some(m) = args.min_length_m
        && !(0.0..=MAX_EXTENT_M).contains(&m)
    {
        return Err(refused(format!(
            "--min-length must be 0 to {MAX_EXTENT_M} metres, got {m}"
        )));
    }
    if args.channel_cells == Some(0) {
        return Err(refused("--channel-cells must be at least 1"));
    }
    if let Some(c) = args.cell_size_m
        && !(c.is_finite() && c > 0.0)
    {
        return Err(refused(format!(
            "--cell-size must be a positive number of metres, got {c}"
        )));
    }
    if let Some(n) = args.crop
        && n < 64
    {
        return Err(refused(format!(
            "--crop must be at least 64 cells, got {n}"
        )));
    }
    check_folder(&args.output)?;
    if let Some(p) = &args.dem_output {
        check_writable(p)?;
    }
    Ok(())
}
