//! `terrasketch`: the command line (and, with no subcommand, the editor).
//!
//! Errors are reported once, here, with their context. Exit status: 0 on success, 2 when an
//! argument or an input is refused (see [`exit_status`]), 1 on any other failure.

mod backend;
mod bench;
mod coarse_world;
mod detail;
mod editor;
mod masks;
mod mesh;
mod metrics;
mod output;
mod refine;
mod solve;
mod stitch;
mod tiled;
mod tiles;
mod trace;

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand, ValueEnum};

/// Real-time sketch-based terrain authoring: strokes in, heightmaps out.
#[derive(Parser, Debug)]
#[command(name = "terrasketch", version, about, long_about = None)]
#[command(args_conflicts_with_subcommands = true)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
    /// With no subcommand: a sketch to open in the editor (default: the bundled example scene).
    file: Option<PathBuf>,
    /// Run the editor driven by a scripted session (see app/EDITOR.md), then exit.
    #[arg(long, value_name = "SESSION.json")]
    replay: Option<PathBuf>,
    /// Replay: folder for the session's screenshots.
    #[arg(long, value_name = "DIR", requires = "replay")]
    screenshots: Option<PathBuf>,
    /// Replay: write one JSON line per frame to this file.
    #[arg(long, value_name = "FRAMES.jsonl", requires = "replay")]
    log: Option<PathBuf>,
}

/// A switch given as `on` or `off`.
#[derive(Copy, Clone, Debug, PartialEq, Eq, ValueEnum)]
pub enum OnOff {
    /// Enabled.
    On,
    /// Disabled.
    Off,
}

/// Which solver backend runs the multigrid.
#[derive(Copy, Clone, Debug, PartialEq, Eq, ValueEnum)]
pub enum BackendKind {
    /// rayon on the CPU (the reference implementation).
    Cpu,
    /// wgpu compute shaders.
    Gpu,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Solve a sketch into a heightmap file (.exr, .tif, .png or .r16), tiles of one, or a mesh
    /// (.glb, .obj).
    Solve {
        /// The sketch (terrasketch-sketch JSON).
        sketch: PathBuf,
        /// Output side in samples, 64 to 16385. A power of two is the solve's cell centres; any
        /// other size samples cell corners, edges included (2^n+1 for Unity, 1009 / 2017 / 4033 /
        /// 8129 for Unreal), bilinearly from the next power-of-two solve.
        #[arg(long)]
        size: usize,
        /// Solver backend.
        #[arg(long, value_enum, default_value_t = BackendKind::Cpu)]
        backend: BackendKind,
        /// Residual tolerance, relative to the relief (default keeps the error below 1e-3 of the relief).
        #[arg(long)]
        tolerance: Option<f32>,
        /// Output file; its extension picks the format: a heightmap (.exr, .tif, .png, .r16) or a
        /// mesh (.glb, .obj). With --tiles, the tiles and the manifest NAME.tiles.json go next to it.
        #[arg(short = 'o', long = "output")]
        output: PathBuf,
        /// Cut the export into NX,NY tiles (i west to east, j south to north) sharing their edge
        /// samples; corner-sampled sizes need NX and NY to divide size - 1 (4097 into 4,4).
        #[arg(long, value_name = "NX,NY")]
        tiles: Option<String>,
        /// With --tiles: extra samples on each side of a tile that has a neighbour.
        #[arg(long, value_name = "PX", default_value_t = 0, requires = "tiles")]
        overlap: usize,
        /// With --tiles: tile file names; {name} and {ext} are the output's, {i} and {j} the tile's.
        #[arg(
            long,
            value_name = "PATTERN",
            default_value = "{name}_x{i}_y{j}.{ext}",
            requires = "tiles"
        )]
        tile_name: String,
        /// Mesh outputs: simplify to triangles within this many metres of every sample (RTIN; needs
        /// --size 2^k or 2^k+1); without it every sample cell is two triangles.
        #[arg(long, value_name = "M")]
        max_error: Option<f64>,
        /// Procedural detail calibrated on real DEMs (driven by the strokes' roughness, seeded by
        /// the sketch's `seed`); `off` writes the pure diffusion.
        #[arg(long, value_enum, default_value_t = OnOff::On)]
        detail: OnOff,
        /// Print one JSON object with the solve's figures on stdout.
        #[arg(long)]
        json: bool,
    },
    /// Write the bundled example sketch (or the benchmark sketch) to a file.
    Example {
        /// Where to write the sketch (JSON).
        #[arg(short = 'o', long = "output")]
        output: PathBuf,
        /// Write the solver benchmark's sketch instead.
        #[arg(long)]
        benchmark: bool,
    },
    /// Terrain descriptors of a heightmap or DEM (slope, curvature, spectral slope, power per
    /// octave, pits, hypsometric integral), optionally compared with a reference.
    Metrics {
        /// Heightmap or DEM: .exr, .tif, .png, .r16, .hgt, .asc.
        file: PathBuf,
        /// A second file to compare with (Wasserstein distance of slopes, spectral-slope difference,
        /// power per octave over the reference's).
        #[arg(long)]
        reference: Option<PathBuf>,
        /// Cell size in metres for files that do not state one (raw PNG, plain TIFF).
        #[arg(long = "cell-size")]
        cell_size_m: Option<f64>,
        /// Print one JSON object.
        #[arg(long)]
        json: bool,
    },
    /// Realism pass: rebuild a solved sketch (or any heightmap) from patches of real DEMs, keeping
    /// the sketched heights.
    Refine {
        /// A sketch (.json; solved first, its height constraints are kept) or a heightmap / DEM
        /// (.tif, .exr, .png, .hgt, .asc; a centred square is resampled to --size).
        input: PathBuf,
        /// Exemplar DEM files or folders [default: the library shipped in synthesis/exemplars].
        #[arg(long, num_args = 1.., value_name = "PATH")]
        exemplars: Vec<PathBuf>,
        /// Output side in samples, 64 to 16385, as for solve: a power of two is the refinement's
        /// cell centres, any other size samples cell corners bilinearly from the next
        /// power-of-two refinement.
        #[arg(long)]
        size: usize,
        /// Output file; its extension picks the format (.exr, .tif, .png, .r16). A GeoTIFF
        /// input's CRS, transform and no-data value are kept in a .tif output. With --tile: the
        /// world's name; the tile (.exr or .tif) and its sidecar NAME_x{i}_y{j}.tile.json go
        /// next to it.
        #[arg(short = 'o', long = "output", required_unless_present = "coarse_out")]
        output: Option<PathBuf>,
        /// Cut the output into NX,NY tiles sharing their edge samples, as for solve.
        #[arg(long, value_name = "NX,NY")]
        tiles: Option<String>,
        /// Compute only tile I,J (I west to east, J south to north, from 0) of the --tiles
        /// world, on its window plus a halo; `terrasketch stitch` joins the tiles.
        #[arg(long, value_name = "I,J", requires = "tiles")]
        tile: Option<String>,
        /// With --tile: the world's coarse levels, computed once by --coarse-out (else each
        /// tile computes them itself, with the same result).
        #[arg(long, value_name = "FILE", requires = "tile")]
        coarse: Option<PathBuf>,
        /// Compute the world's guide and coarse pyramid levels once, write them to FILE for
        /// the tiles' --coarse, and stop.
        #[arg(long, value_name = "FILE", conflicts_with_all = ["tile", "tiles"])]
        coarse_out: Option<PathBuf>,
        /// With --tiles: extra samples on each side of a tile that has a neighbour.
        #[arg(long, value_name = "PX", default_value_t = 0, requires = "tiles")]
        overlap: usize,
        /// With --tiles: tile file names; {name} and {ext} are the output's, {i} and {j} the tile's.
        #[arg(
            long,
            value_name = "PATTERN",
            default_value = "{name}_x{i}_y{j}.{ext}",
            requires = "tiles"
        )]
        tile_name: String,
        /// Seed: the same inputs and seed give the same output.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Patch side in cells (16 to half of --size).
        #[arg(long, default_value_t = 64)]
        patch_size: usize,
        /// Detail scale in cells: the target's layout above it is kept, detail below it comes from
        /// exemplar patches [default: half the patch size].
        #[arg(long, value_name = "CELLS")]
        detail_scale: Option<usize>,
        /// Gain of the calibrated procedural detail in the octaves the exemplars do not measure
        /// (finer than two of their own cells): 1 is the law fitted on real DEMs, 0 none (see
        /// synthesis/README.md, "Octaves finer than the exemplars").
        #[arg(long, value_name = "GAIN", default_value_t = terrasketch_synthesis::refine::RefineParams::default().fine_detail, value_parser = fine_detail_gain)]
        fine_detail: f32,
        /// Where exemplar feature networks are cached [default: $XDG_CACHE_HOME/terrasketch/features].
        #[arg(long, value_name = "DIR")]
        cache_dir: Option<PathBuf>,
        /// Print one JSON object with the figures on stdout (no progress bar).
        #[arg(long)]
        json: bool,
    },
    /// Join the tiles of `refine --tile` into one seamless raster (overlaps blended by a smooth
    /// ramp); the output is any heightmap format.
    Stitch {
        /// A tile's sidecar (NAME_x{i}_y{j}.tile.json) or the folder holding the world's tiles
        /// and sidecars.
        manifest: PathBuf,
        /// Output file (.exr, .tif, .png, .r16).
        #[arg(short = 'o', long = "output")]
        output: PathBuf,
        /// Print one JSON object with the figures (tile-border seam ratio) on stdout.
        #[arg(long)]
        json: bool,
    },
    /// Texturing masks of a heightmap: slope, hillshade, mean curvature, D8 flow accumulation and
    /// normalised height (definitions and ranges: app/README.md).
    Masks {
        /// The heightmap: .exr, .tif, .png or .r16.
        input: PathBuf,
        /// Folder for slope, curvature, flow, height (.png or .exr), hillshade.png and masks.json.
        #[arg(short = 'o', long = "output", value_name = "DIR")]
        output_dir: PathBuf,
        /// 16-bit PNG over each mask's range, or f32 EXR in the mask's units (the hillshade is
        /// always an 8-bit PNG).
        #[arg(long, value_enum, default_value_t = masks::MaskFormat::Png)]
        format: masks::MaskFormat,
        /// Cell size in metres, for files that do not state one.
        #[arg(long = "cell-size", value_name = "M")]
        cell_size_m: Option<f64>,
    },
    /// Trace a DEM's main valleys and ridges into an editable sketch: valley and ridge strokes with
    /// the DEM's heights, side slopes and widths (see synthesis/README.md, "Trace").
    Trace(trace::TraceArgs),
    /// Benchmarks (print figures; `--json` for machines).
    Bench {
        #[command(subcommand)]
        which: bench::BenchCommand,
    },
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Some(Command::Solve {
            sketch,
            size,
            backend,
            tolerance,
            output,
            tiles,
            overlap,
            tile_name,
            max_error,
            detail,
            json,
        }) => solve::run(&solve::SolveArgs {
            sketch,
            size,
            backend,
            tolerance,
            output,
            tiles: tiles.map(|t| (t, overlap, tile_name)),
            max_error_m: max_error,
            detail: detail == OnOff::On,
            json,
        }),
        Some(Command::Bench { which }) => bench::run(which),
        Some(Command::Trace(args)) => trace::run(&args),
        Some(Command::Masks {
            input,
            output_dir,
            format,
            cell_size_m,
        }) => masks::run(&masks::MasksArgs {
            input,
            output_dir,
            format,
            cell_size_m,
        }),
        Some(Command::Refine {
            input,
            exemplars,
            size,
            output,
            seed,
            patch_size,
            detail_scale,
            fine_detail,
            cache_dir,
            tiles,
            overlap,
            tile_name,
            tile,
            coarse,
            coarse_out,
            json,
        }) => refine::run(&refine::RefineArgs {
            input,
            exemplars,
            size,
            output,
            seed,
            patch_size,
            detail_scale,
            fine_detail,
            cache_dir,
            tiles: tiles.map(|t| (t, overlap, tile_name)),
            tile,
            coarse,
            coarse_out,
            json,
        }),
        Some(Command::Stitch {
            manifest,
            output,
            json,
        }) => stitch::run(&manifest, &output, json),
        Some(Command::Metrics {
            file,
            reference,
            cell_size_m,
            json,
        }) => metrics::run(&metrics::MetricsArgs {
            file,
            reference,
            cell_size_m,
            json,
        }),
        Some(Command::Example { output, benchmark }) => {
            let sketch = if benchmark {
                terrasketch_sketch::benchmark_sketch()
            } else {
                terrasketch_sketch::example_sketch()
            };
            terrasketch_sketch::save_sketch_atomic(&sketch, &output).map_err(anyhow::Error::from)
        }
        None => editor::run(editor::EditorArgs {
            file: cli.file,
            replay: cli.replay,
            screenshots: cli.screenshots,
            log: cli.log,
        }),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("terrasketch: error: {e:#}");
            ExitCode::from(exit_status(&e))
        }
    }
}

/// 2 when an argument or an input was refused (as clap does for usage errors): a sketch or a
/// heightmap file that breaks the format's rules or bounds, a size or path that cannot work;
/// 1 for any other failure (I/O while working, GPU, solver).
fn exit_status(error: &anyhow::Error) -> u8 {
    use terrasketch_multigrid::SolverError;
    use terrasketch_raster::RasterError;
    use terrasketch_sketch::SketchError;
    let refused = error.chain().any(|cause| {
        cause.is::<output::Refused>()
            || matches!(cause.downcast_ref::<SketchError>(), Some(e) if !matches!(e, SketchError::Io { .. }))
            || matches!(cause.downcast_ref::<RasterError>(), Some(e) if !matches!(e, RasterError::Io { .. }))
            || matches!(
                cause.downcast_ref::<SolverError>(),
                Some(SolverError::BadSize { .. } | SolverError::BadExtent { .. })
            )
    });
    if refused { 2 } else { 1 }
}

/// `--fine-detail`: a finite gain from 0 to `MAX_FINE_DETAIL` (four times the detail of real land).
fn fine_detail_gain(s: &str) -> Result<f32, String> {
    use terrasketch_synthesis::refine::MAX_FINE_DETAIL;
    let g: f32 = s
        .trim()
        .parse()
        .map_err(|_| format!("{s:?} is not a number"))?;
    if !(0.0..=MAX_FINE_DETAIL).contains(&g) {
        return Err(format!(
            "the gain must be from 0 to {MAX_FINE_DETAIL}, got {s}"
        ));
    }
    Ok(g)
}
