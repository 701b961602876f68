//! `terrasketch bench ...`: deterministic benchmarks that print medians (see the README for targets).

use std::time::Instant;

use anyhow::{Context, Result, bail};
use clap::Subcommand;
use terrasketch_multigrid::{CpuSolver, Grid, PhaseMs, SolverParams};
use terrasketch_sketch::{Sketch, benchmark_sketch};

use crate::BackendKind;
use crate::backend::AnySolver;

use crate::output::peak_rss_mb;

/// The benchmarks.
#[derive(Subcommand, Debug)]
pub enum BenchCommand {
    /// Cold solves of the built-in benchmark sketch.
    Solver {
        /// Heightmap side (power of two, 64..16384).
        #[arg(long)]
        size: usize,
        /// Solver backend.
        #[arg(long, value_enum, default_value_t = BackendKind::Cpu)]
        backend: BackendKind,
        /// Number of timed solves.
        #[arg(long, default_value_t = 5)]
        repeat: usize,
        /// Residual tolerance (default: the solver's).
        #[arg(long)]
        tolerance: Option<f32>,
        /// Residual tolerance of the gradient-field and roughness solves (CPU backend; default: the
        /// solver's).
        #[arg(long)]
        field_tolerance: Option<f32>,
        /// Print one JSON object.
        #[arg(long)]
        json: bool,
    },
    /// Drags one stroke of the benchmark sketch over 60 frames, re-solving warm each frame.
    Drag {
        /// Heightmap side (power of two, 64..16384).
        #[arg(long)]
        size: usize,
        /// Solver backend.
        #[arg(long, value_enum, default_value_t = BackendKind::Cpu)]
        backend: BackendKind,
        /// Frames of the drag (1..=60): the first frames of the same drag, for counting a large
        /// grid where a software device is slow (the medians and the error are then of those).
        #[arg(long, default_value_t = DRAG_FRAMES)]
        frames: usize,
        /// Print one JSON object.
        #[arg(long)]
        json: bool,
    },
    /// Quadtree LOD selection over a fixed 1920x1080 camera path above the benchmark sketch.
    Lod {
        /// Heightmap side (power of two, 64..16384). Above 4096 the min/max pyramid comes from a
        /// solve at 1024 over the same extent (its 64x64 bounds cover the same cells).
        #[arg(long)]
        size: usize,
        /// Camera-path frames.
        #[arg(long, default_value_t = 300)]
        frames: usize,
        /// Print one JSON object.
        #[arg(long)]
        json: bool,
    },
}

/// Runs a benchmark.
pub fn run(cmd: BenchCommand) -> Result<()> {
    match cmd {
        BenchCommand::Solver {
            size,
            backend,
            repeat,
            tolerance,
            field_tolerance,
            json,
        } => solver(size, backend, repeat, tolerance, field_tolerance, json),
        BenchCommand::Drag {
            size,
            backend,
            frames,
            json,
        } => drag(size, backend, frames, json),
        BenchCommand::Lod { size, frames, json } => lod(size, frames, json),
    }
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n == 0 {
        return f64::NAN;
    }
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

fn percentile(v: &mut [f64], p: f64) -> f64 {
    v.sort_by(f64::total_cmp);
    if v.is_empty() {
        return f64::NAN;
    }
    let k = ((p / 100.0) * (v.len() - 1) as f64).round() as usize;
    v[k.min(v.len() - 1)]
}

fn emit(json: bool, value: serde_json::Value) {
    if json {
        println!("{value}");
    } else if let Some(obj) = value.as_object() {
        for (k, v) in obj {
            println!("{k:>24}: {v}");
        }
    }
}

fn solver(
    size: usize,
    backend: BackendKind,
    repeat: usize,
    tolerance: Option<f32>,
    field_tolerance: Option<f32>,
    json: bool,
) -> Result<()> {
    if repeat == 0 || repeat > 1000 {
        bail!("--repeat must be between 1 and 1000, got {repeat}");
    }
    for (name, t) in [
        ("--tolerance", tolerance),
        ("--field-tolerance", field_tolerance),
    ] {
        if let Some(t) = t
            && !(t.is_finite() && t > 0.0 && t < 1.0)
        {
            bail!("{name} must be between 0 and 1 (exclusive), got {t}");
        }
    }
    let sketch = benchmark_sketch();
    let grid = Grid::new(size, sketch.extent_m)?;
    let mut params = SolverParams::default();
    if let Some(t) = tolerance {
        params.tolerance = t;
    }
    let mut solver = AnySolver::new(backend, grid, params)?;
    if let Some(t) = field_tolerance {
        let AnySolver::Cpu(s) = &mut solver else {
            bail!("--field-tolerance applies to the CPU backend only");
        };
        let mut fp = *s.field_params();
        fp.tolerance = t;
        s.set_field_params(fp);
    }
    let mut times = Vec::new();
    let mut report = Default::default();
    let mut counted = None;
    for _ in 0..repeat {
        let before = solver.gpu_counters();
        report = solver.solve_sketch(&sketch)?;
        times.push(report.ms_total);
        counted = solver.gpu_counters().zip(before).map(|(a, b)| a.since(&b));
    }
    let ms_min = times.iter().cloned().fold(f64::INFINITY, f64::min);
    let ms_median = median(&mut times);
    let convergence_factor = if report.vcycles > 0 && report.residual_initial > 0.0 {
        ((report.residual_final / report.residual_initial) as f64).powf(1.0 / report.vcycles as f64)
    } else {
        0.0
    };
    // Peak memory of the timed solves (the reference below needs a copy of the heights).
    let peak_rss_mb = peak_rss_mb();
    let error_vs_converged = error_vs_converged(&mut solver, &sketch, params)?;
    emit(
        json,
        serde_json::json!({
            "bench": "solver",
            "size": size,
            "backend": solver.backend_name(),
            "adapter": solver.adapter(),
            "repeat": repeat,
            "ms_median": ms_median,
            "ms_min": ms_min,
            "work_units": report.work_units,
            "field_work_units": report.field_work_units,
            "vcycles": report.vcycles,
            "levels": report.levels,
            "residual_initial": report.residual_initial,
            "residual_final": report.residual_final,
            "convergence_factor": convergence_factor,
            "error_vs_converged": error_vs_converged,
            "tolerance": params.tolerance,
            "peak_rss_mb": peak_rss_mb,
            "gpu_bytes": solver.gpu_bytes(),
            // GPU solver only: the device counters of one solve (the last one).
            "gpu_counts": counters_json(counted.as_ref()),
            // The same solve's dispatches and estimated bytes per kernel, most bytes first.
            "gpu_bytes_by_pass": bytes_by_pass_json(counted.as_ref(), size),
            // CPU solver only (the GPU backend runs its phases in one submission).
            // On a backend that times its phases (the report carries the last solve's).
            "phase_ms": if solver.solver_mut().take_phase_ms().is_some() {
                phase_json(&report.phase_ms)
            } else {
                serde_json::Value::Null
            },
        }),
    );
    Ok(())
}

/// Device counters and the paper model's times as a JSON object (null on the CPU).
fn counters_json(c: Option<&terrasketch_multigrid::gpu::GpuCounters>) -> serde_json::Value {
    match c {
        None => serde_json::Value::Null,
        Some(c) => {
            use terrasketch_multigrid::gpu::{H100_CLASS_GPU, MID_RANGE_GPU};
            serde_json::json!({
                "dispatches": c.dispatches,
                "submits": c.submits,
                "blocking_waits": c.blocking_waits,
                "bytes_read_back": c.bytes_read_back,
                "bytes_up": c.bytes_up,
                "bytes_moved_estimate": c.bytes_moved_estimate,
                // ALGORITHM.md's paper model: milliseconds on two reference GPUs.
                "paper_model_ms": {
                    MID_RANGE_GPU.name: c.paper_model_ms(&MID_RANGE_GPU),
                    H100_CLASS_GPU.name: c.paper_model_ms(&H100_CLASS_GPU),
                },
            })
        }
    }
}

/// Dispatches, estimated bytes and bytes per level-0 texel of each kernel a solve of side `size`
/// ran, most bytes first (null on the CPU).
fn bytes_by_pass_json(
    c: Option<&terrasketch_multigrid::gpu::GpuCounters>,
    size: usize,
) -> serde_json::Value {
    let Some(c) = c else {
        return serde_json::Value::Null;
    };
    let texels = (size * size) as f64;
    c.by_pass
        .nonzero()
        .into_iter()
        .map(|(k, dispatches, bytes)| {
            serde_json::json!({
                "pass": k.name(),
                "dispatches": dispatches,
                "bytes": bytes,
                "bytes_per_texel": bytes as f64 / texels,
            })
        })
        .collect()
}

/// The CPU solver's phase times as a JSON object.
fn phase_json(p: &PhaseMs) -> serde_json::Value {
    serde_json::json!({
        "rasterize": p.rasterize,
        "fields": p.fields,
        "heights": p.heights,
        "publish": p.publish,
    })
}

/// Largest height error at the current stop point against a converged solve of `sketch`, relative to
/// the relief. CPU: a new cold solve with the fields and the heights at a tolerance near f32 round-off,
/// so that the error of the loose field solves counts. GPU: the height solve continued from the stop
/// point.
fn error_vs_converged(
    solver: &mut AnySolver,
    sketch: &Sketch,
    params: SolverParams,
) -> Result<f64> {
    let h_stop = solver.heights()?;
    let relief = solver.relief_m();
    match solver {
        AnySolver::Cpu(s) => {
            let tight = SolverParams {
                tolerance: 1e-7,
                max_vcycles: 60,
                ..params
            };
            s.set_field_params(tight);
            s.set_params(tight);
            s.set_sketch(sketch);
            s.solve();
        }
        AnySolver::Gpu(_) => solver.converge_fully(sketch)?,
    }
    let conv = solver.heights()?;
    Ok((h_stop
        .iter()
        .zip(&conv)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0f32, f32::max)
        / relief) as f64)
}

/// Frames of the benchmark drag.
const DRAG_FRAMES: usize = 60;

fn drag(size: usize, backend: BackendKind, frames: usize, json: bool) -> Result<()> {
    if !(1..=DRAG_FRAMES).contains(&frames) {
        bail!("--frames must be 1..={DRAG_FRAMES}, got {frames}");
    }
    let mut sketch = benchmark_sketch();
    let grid = Grid::new(size, sketch.extent_m)?;
    let params = SolverParams::default();
    let mut solver = AnySolver::new(backend, grid, params)?;
    solver.solve_sketch(&sketch)?;
    let stroke = 0;
    let mut times = Vec::with_capacity(frames);
    let mut wus = Vec::with_capacity(frames);
    let mut vcycles = Vec::with_capacity(frames);
    let mut phases: [Vec<f64>; 5] = Default::default();
    let mut counts = Vec::with_capacity(frames);
    for _ in 0..frames {
        let before = solver.gpu_counters();
        let t = Instant::now();
        let from = sketch.clone();
        drag_step(&mut sketch, stroke);
        let r = solver.solver_mut().update_warm(&sketch, &from)?;
        if let AnySolver::Cpu(s) = &mut solver {
            // The editor's CPU detail follows every edit: roughness (incremental) and amplitude (the
            // GPU editor computes it on the device, outside the solver).
            let td = Instant::now();
            std::hint::black_box(crate::detail::amplitude_cpu(s));
            phases[4].push(td.elapsed().as_secs_f64() * 1e3);
        }
        if let Some(ph) = solver.solver_mut().take_phase_ms() {
            for (v, x) in phases
                .iter_mut()
                .zip([ph.rasterize, ph.fields, ph.heights, ph.publish])
            {
                v.push(x);
            }
        }
        let (wu, cycles) = (r.work_units + r.field_work_units, r.vcycles);
        times.push(t.elapsed().as_secs_f64() * 1e3);
        if let Some(c) = solver.gpu_counters().zip(before).map(|(a, b)| a.since(&b)) {
            counts.push(c);
        }
        wus.push(wu);
        vcycles.push(cycles as f64);
    }
    let updates = times.len();
    // Error after the last update against a converged solve of the final sketch.
    let error_vs_converged = error_vs_converged(&mut solver, &sketch, params)?;
    let (backend_name, adapter, gpu_bytes) =
        (solver.backend_name(), solver.adapter(), solver.gpu_bytes());
    let (mut frame_counts, frames_error) = match solver {
        AnySolver::Gpu(g) => {
            let (c, e) = editor_frames(*g, &mut sketch, stroke, frames, params)?;
            (c, Some(e))
        }
        AnySolver::Cpu(_) => (Vec::new(), None),
    };
    emit(
        json,
        serde_json::json!({
            "bench": "drag",
            "size": size,
            "backend": backend_name,
            "adapter": adapter,
            "updates": updates,
            "p50_ms": percentile(&mut times.clone(), 50.0),
            "p95_ms": percentile(&mut times, 95.0),
            "work_units_per_update": median(&mut wus),
            "vcycles_per_update": median(&mut vcycles),
            "phase_p50_ms": if !phases[0].is_empty() {
                serde_json::json!({
                    "rasterize": median(&mut phases[0]),
                    "fields": median(&mut phases[1]),
                    "heights": median(&mut phases[2]),
                    "publish": median(&mut phases[3]),
                    "detail": median(&mut phases[4]),
                })
            } else {
                serde_json::Value::Null
            },
            "error_vs_converged": error_vs_converged,
            "peak_rss_mb": peak_rss_mb(),
            "gpu_bytes": gpu_bytes,
            // GPU solver only: the device counters of the median update (by dispatches).
            "gpu_counts_per_update": counters_json(median_counts(&mut counts).as_ref()),
            // The median update's dispatches and estimated bytes per kernel, most bytes first.
            "gpu_bytes_by_pass_per_update": bytes_by_pass_json(median_counts(&mut counts).as_ref(), size),
            // GPU solver only: the same drag as the editor's frames run it (no wait for reports;
            // see `editor_frames`), counters of the median frame and the last frame's error.
            "gpu_counts_per_editor_frame": counters_json(median_counts(&mut frame_counts).as_ref()),
            "editor_frame_error_vs_converged": frames_error,
        }),
    );
    Ok(())
}

/// Moves every point of the dragged stroke by one frame's step.
fn drag_step(sketch: &mut Sketch, stroke: usize) {
    for p in &mut sketch.strokes[stroke].points {
        p[0] += 6.0;
        p[1] += 4.0;
    }
}

/// The GPU drag as the editor's frames run it (`editor::HeadlessFrames`: the follow rule's queued
/// take and iterations, the publish, nothing waited for): settled on `sketch` first, then
/// `frames` frames that each move the stroke once. Returns each frame's counters and the error of
/// the last frame's heights against a converged solve, relative to the relief.
fn editor_frames(
    solver: terrasketch_multigrid::gpu_solver::GpuSolver,
    sketch: &mut Sketch,
    stroke: usize,
    frames: usize,
    params: SolverParams,
) -> Result<(Vec<terrasketch_multigrid::gpu::GpuCounters>, f64)> {
    const SETTLE_FRAMES: usize = 1000;
    let mut live = crate::editor::HeadlessFrames::new(solver);
    let mut settle = 0;
    while !live.converged_for(sketch) {
        live.frame(sketch, settle == 0)?;
        settle += 1;
        if settle > SETTLE_FRAMES {
            bail!("the editor's GPU engine did not converge on the benchmark sketch");
        }
    }
    let mut counts = Vec::with_capacity(frames);
    for _ in 0..frames {
        // The frames' pacing: a real GPU ends a frame's few milliseconds of work within the
        // frame, a software one does not, and the next take would wait for it.
        live.solver()
            .context()
            .device
            .poll(wgpu::PollType::wait_indefinitely())
            .context("waiting for the device between frames")?;
        let before = live.solver().context().counters();
        drag_step(sketch, stroke);
        live.frame(sketch, true)?;
        counts.push(live.solver().context().counters().since(&before));
    }
    let mut solver = AnySolver::Gpu(Box::new(live.into_solver()));
    let err = error_vs_converged(&mut solver, sketch, params)?;
    Ok((counts, err))
}

/// The update with the median number of dispatches (None if none was counted).
fn median_counts(
    c: &mut [terrasketch_multigrid::gpu::GpuCounters],
) -> Option<terrasketch_multigrid::gpu::GpuCounters> {
    c.sort_by_key(|c| c.dispatches);
    c.get(c.len() / 2).copied()
}

fn lod(size: usize, frames: usize, json: bool) -> Result<()> {
    use terrasketch_quadtree::{LodSettings, MinMaxPyramid, bench_lod};
    if frames == 0 || frames > 100_000 {
        bail!("--frames must be between 1 and 100000, got {frames}");
    }
    let sketch = benchmark_sketch();
    Grid::new(size, sketch.extent_m)?; // checks the size
    let solve_size = if size > 4096 { 1024 } else { size };
    let grid = Grid::new(solve_size, sketch.extent_m)?;
    let mut solver = CpuSolver::new(grid, SolverParams::default())?;
    solver.set_sketch(&sketch);
    let t = Instant::now();
    solver.solve();
    let solve_ms = t.elapsed().as_secs_f64() * 1e3;
    let levels = solver
        .minmax()
        .iter()
        .map(|l| (l.side, l.cells.clone()))
        .collect();
    let pyramid =
        MinMaxPyramid::from_levels(levels).context("the solver's min/max pyramid was refused")?;
    let settings = LodSettings::new(size, [sketch.extent_m[0] as f32, sketch.extent_m[1] as f32]);
    let r = bench_lod(&pyramid, &settings, frames).context("LOD selection failed")?;
    emit(
        json,
        serde_json::json!({
            "bench": "lod",
            "size": size,
            "pyramid_from_size": solve_size,
            "pyramid_finest_side": pyramid.finest_side(),
            "solve_ms": solve_ms,
            "frames": r.frames,
            "viewport_px": [1920, 1080],
            "pixel_budget": settings.pixel_budget,
            "leaf_cells": settings.leaf_cells,
            "select_us_median": r.select_us_median,
            "select_us_max": r.select_us_max,
            "patches_median": r.patches_median,
            "triangles_median": r.triangles_median,
            "max_neighbour_level_diff": r.max_neighbour_level_diff,
            "nodes_median": r.nodes_median,
        }),
    );
    Ok(())
}
