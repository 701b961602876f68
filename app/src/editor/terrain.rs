//! The terrain as the editor sees it: the GPU solver (on the editor's device, its texture drawn
//! directly) or the CPU solver, stepped within a frame budget; the min/max pyramid for the quadtree;
//! height sampling (probes, picking) that matches the vertex shader; and, for the CPU solver, the
//! row-level change tracking that decides what is uploaded to the heightmap texture.

use std::ops::Range;
use std::sync::Arc;
use std::time::Duration;

use anyhow::{Context, Result};
use glam::Vec3;
use terrasketch_multigrid::gpu::{GpuContext, GpuError};
use terrasketch_multigrid::gpu_solver::GpuSolver;
use terrasketch_multigrid::{Budget, ConstraintMaps, CpuSolver, Grid, Progress, SolverParams};
use terrasketch_quadtree::MinMaxPyramid;
use terrasketch_sketch::Sketch;

use super::refine::Refined;

use super::camera::Ray;

/// A sampled copy of one mip (the frozen "depth map" of a stroke, or the live terrain for picking).
#[derive(Debug, Clone)]
pub struct HeightField {
    /// Cells per side.
    pub side: usize,
    /// Extent, metres.
    pub extent_m: [f32; 2],
    /// Heights, row 0 = south.
    pub data: Vec<f32>,
}

impl HeightField {
    /// Bilinear height at world `(x, y)` with texel centres at `(c + 0.5) / side`, clamped at the
    /// borders: the vertex shader's `sample_height`.
    pub fn height_at(&self, x_m: f32, y_m: f32) -> f32 {
        sample_bilinear(
            &self.data,
            self.side,
            x_m / self.extent_m[0],
            y_m / self.extent_m[1],
        )
    }

    /// First intersection of a ray with the height field inside the extent (march, then bisect).
    pub fn raycast(&self, ray: &Ray) -> Option<Vec3> {
        let [ex, ey] = self.extent_m;
        // Clip the ray to the extent's box in x and y.
        let (mut t0, mut t1) = (0.0f32, 1.0e7f32);
        for (o, d, hi) in [(ray.origin.x, ray.dir.x, ex), (ray.origin.y, ray.dir.y, ey)] {
            if d.abs() < 1e-9 {
                if o < 0.0 || o > hi {
                    return None;
                }
            } else {
                let (a, b) = ((0.0 - o) / d, (hi - o) / d);
                t0 = t0.max(a.min(b));
                t1 = t1.min(a.max(b));
            }
        }
        if t0 >= t1 {
            return None;
        }
        let step = 0.5 * ex.max(ey) / self.side as f32;
        let above = |t: f32| {
            let p = ray.origin + ray.dir * t;
            p.z - self.height_at(p.x, p.y)
        };
        let mut t = t0;
        let mut prev = above(t);
        if prev < 0.0 {
            return Some(ray.origin + ray.dir * t0);
        }
        let max_steps = 200_000;
        for _ in 0..max_steps {
            let next = (t + step).min(t1);
            let a = above(next);
            if a <= 0.0 {
                let (mut lo, mut hi) = (t, next);
                for _ in 0..30 {
                    let mid = 0.5 * (lo + hi);
                    if above(mid) > 0.0 {
                        lo = mid;
                    } else {
                        hi = mid;
                    }
                }
                let _ = prev;
                return Some(ray.origin + ray.dir * hi);
            }
            prev = a;
            t = next;
            if t >= t1 {
                break;
            }
        }
        None
    }
}

/// The four texels and weights of a bilinear sample (as `sample_bilinear`).
pub struct Corners {
    /// `(x0, y0), (x1, y0), (x0, y1), (x1, y1)`.
    pub texels: [[usize; 2]; 4],
    fx: f32,
    fy: f32,
}

impl Corners {
    /// The bilinear combination of the four texel values (same order as `texels`).
    pub fn combine(&self, h: [f32; 4]) -> f32 {
        let (fx, fy) = (self.fx, self.fy);
        let south = h[0] * (1.0 - fx) + h[1] * fx;
        let north = h[2] * (1.0 - fx) + h[3] * fx;
        south * (1.0 - fy) + north * fy
    }
}

/// Texels and weights of the bilinear sample at `(u, v)` (extent fractions, clamped at the borders).
pub fn bilinear_corners(side: usize, u: f32, v: f32) -> Corners {
    let s = side as f32;
    let px = (u * s - 0.5).clamp(0.0, s - 1.0);
    let py = (v * s - 0.5).clamp(0.0, s - 1.0);
    let (x0, y0) = (px.floor() as usize, py.floor() as usize);
    let (x1, y1) = ((x0 + 1).min(side - 1), (y0 + 1).min(side - 1));
    Corners {
        texels: [[x0, y0], [x1, y0], [x0, y1], [x1, y1]],
        fx: px - x0 as f32,
        fy: py - y0 as f32,
    }
}

/// Bilinear sample of a `side x side` grid at `(u, v)` in extent fractions, clamped at the borders.
pub fn sample_bilinear(data: &[f32], side: usize, u: f32, v: f32) -> f32 {
    let c = bilinear_corners(side, u, v);
    c.combine(c.texels.map(|t| data[t[1] * side + t[0]]))
}

/// Which solver runs the terrain.
enum Engine {
    /// The CPU solver; its mips are uploaded row by row.
    Cpu(Box<CpuSolver>),
    /// The GPU solver on the editor's device; its texture is drawn directly.
    Gpu(Box<GpuEngine>),
}

/// The GPU solver and its stepping state.
struct GpuEngine {
    solver: GpuSolver,
    /// No sketch taken yet, or the sketch was replaced: the next start is cold.
    cold: bool,
    /// FCG iterations since the height solve met the normal tolerance (caps the idle refinement).
    polish_iters: u32,
    /// An edit was taken: the next frame starts warm from it.
    restart: bool,
    /// The finest mip is ready (after the first start).
    ready: bool,
    /// The picking copy (`Terrain::field`), refreshed when the terrain settles.
    pick: Option<HeightField>,
    /// Version of the heights the picking copy was read at.
    pick_version: u64,
    /// Traffic counters at the start of the frame.
    traffic_mark: (u64, u64),
    /// The constraint overlay's weights and the sketch they belong to.
    overlay: Option<(Sketch, Vec<f32>)>,
}

/// Largest side of the picking copy read back from the GPU (256^2 floats = 256 KB, read once the
/// terrain has settled, never while the pointer edits).
const PICK_MAX_SIDE: usize = 256;
/// FCG iterations of the idle refinement on the GPU (f32 round-off can stop short of 1e-6).
const GPU_POLISH_ITERS: u32 = 40;

/// The solver and what the renderer needs from it.
pub struct Terrain {
    /// The grid.
    pub grid: Grid,
    engine: Engine,
    /// Progress of the last step that ran.
    pub last: Progress,
    /// Work units of this frame's step (0 if none ran).
    pub frame_work_units: f64,
    /// The quadtree's bounds (from the solver's min/max pyramid), once a mip is ready.
    pub pyramid: Option<MinMaxPyramid>,
    /// Bumped whenever the published heights may have changed.
    pub version: u64,
    /// What the texture holds, per mip level (empty until first uploaded; CPU engine).
    shadow: Vec<Vec<f32>>,
    /// The solver's sketch has no stroke (its next solve is cold: restart it rather than warm-update).
    empty: bool,
    /// After convergence at the normal tolerance the solver keeps refining to `POLISH_TOLERANCE`
    /// while idle, so that two converged states of the same sketch (before an edit, after its undo)
    /// agree to round-off; true once that is done.
    polished: bool,
    /// An edit is waiting for the solver (edits are coalesced, see `update`; what changed is found by
    /// comparing with `applied`).
    pending: bool,
    /// The sketch the CPU solver last took (its edits are re-rasterised only where the strokes
    /// differ from it, see `diff_spans`).
    applied: Sketch,
    /// Height work done since the solver last took an edit.
    height_wu_since_update: f64,
    /// The solver's last step reported convergence (for the sketch it has).
    solver_done: bool,
    /// An edit arrived since the last step (the pointer is still moving).
    edited: bool,
    /// Why the GPU solver was given up this frame (taken by the frame loop to tell the user).
    pub fallback: Option<String>,
    /// The refined layer shown instead of the solver's heights (the solver keeps its own).
    refined: Option<Arc<Refined>>,
}

/// Height work (FMG levels and FCG iterations, level-0 units) per frame, and between two edits handed
/// to the solver, before it is given the next one.
const MIN_HEIGHT_WU: f64 = 3.0;

/// Tolerance of the idle refinement (see `Terrain::polished`).
const POLISH_TOLERANCE: f32 = 1e-6;

impl Terrain {
    /// A solver of side `n` for `sketch`, not yet stepped: on the GPU of `gpu` when given (its device
    /// must have [`GpuContext::required_limits`]), else on the CPU.
    pub fn new(sketch: &Sketch, n: usize, gpu: Option<&GpuContext>) -> Result<Terrain> {
        let grid = Grid::new(n, sketch.extent_m).context("cannot make the terrain grid")?;
        let engine = match gpu {
            Some(ctx) => {
                let solver = GpuSolver::new(ctx, grid, SolverParams::default())
                    .context("cannot set up the GPU solver")?;
                Engine::Gpu(Box::new(GpuEngine {
                    traffic_mark: solver.context().traffic(),
                    solver,
                    cold: true,
                    restart: false,
                    polish_iters: 0,
                    ready: false,
                    pick: None,
                    pick_version: u64::MAX,
                    overlay: None,
                }))
            }
            None => Engine::Cpu(Box::new(Self::cpu_solver(grid, sketch)?)),
        };
        Ok(Terrain {
            grid,
            engine,
            last: Progress {
                finest_ready_level: None,
                residual: f32::INFINITY,
                work_units: 0.0,
                field_work_units: 0.0,
                vcycles: 0,
                converged: false,
            },
            frame_work_units: 0.0,
            pyramid: None,
            version: 0,
            shadow: vec![Vec::new(); grid.mip_levels()],
            empty: sketch.strokes.is_empty(),
            polished: false,
            pending: false,
            applied: sketch.clone(),
            height_wu_since_update: 0.0,
            solver_done: false,
            edited: false,
            fallback: None,
            refined: None,
        })
    }

    fn cpu_solver(grid: Grid, sketch: &Sketch) -> Result<CpuSolver> {
        let mut solver = CpuSolver::new(grid, SolverParams::default())?;
        solver.set_sketch(sketch);
        Ok(solver)
    }

    /// A terrain of the same backend (and device) for another sketch of side `n`.
    pub fn rebuilt(&self, sketch: &Sketch, n: usize) -> Result<Terrain> {
        Terrain::new(sketch, n, self.gpu_context().as_ref())
    }

    /// The GPU context when the GPU solver runs the terrain.
    pub fn gpu_context(&self) -> Option<GpuContext> {
        match &self.engine {
            Engine::Gpu(g) => Some(g.solver.context().clone()),
            Engine::Cpu(_) => None,
        }
    }

    /// "gpu" or "cpu".
    pub fn backend_name(&self) -> &'static str {
        match self.engine {
            Engine::Gpu(_) => "gpu",
            Engine::Cpu(_) => "cpu",
        }
    }

    /// The GPU solver's height texture (R32Float, full mip chain) when the GPU runs the terrain.
    /// None while a refined layer is shown: it goes up to the renderer's own texture.
    pub fn gpu_texture(&self) -> Option<&wgpu::Texture> {
        if self.refined.is_some() {
            return None;
        }
        match &self.engine {
            Engine::Gpu(g) => Some(g.solver.texture()),
            Engine::Cpu(_) => None,
        }
    }

    /// Bytes the GPU solver sent to / read back from the device since the last call (0 on the CPU).
    pub fn take_traffic(&mut self) -> (u64, u64) {
        match &mut self.engine {
            Engine::Gpu(g) => {
                let now = g.solver.context().traffic();
                let d = (now.0 - g.traffic_mark.0, now.1 - g.traffic_mark.1);
                g.traffic_mark = now;
                d
            }
            Engine::Cpu(_) => (0, 0),
        }
    }

    /// Gives up the GPU solver (after an error, or when asked): the CPU solver takes the current
    /// sketch from scratch; `fallback` says why.
    pub fn fall_back_to_cpu(&mut self, sketch: &Sketch, why: String) {
        let solver = match Self::cpu_solver(self.grid, sketch) {
            Ok(s) => s,
            Err(e) => {
                self.fallback = Some(format!("{why}; the CPU solver failed too: {e:#}"));
                return;
            }
        };
        self.engine = Engine::Cpu(Box::new(solver));
        self.shadow = vec![Vec::new(); self.grid.mip_levels()];
        self.fallback = Some(why);
        self.set_sketch(sketch);
    }

    /// Replaces the whole sketch (cold solve).
    pub fn set_sketch(&mut self, sketch: &Sketch) {
        self.normal_tolerance();
        match &mut self.engine {
            Engine::Cpu(s) => s.set_sketch(sketch),
            Engine::Gpu(g) => {
                g.cold = true;
                g.polish_iters = 0;
            }
        }
        self.empty = sketch.strokes.is_empty();
        self.last.converged = false;
        self.pending = false;
        self.applied = sketch.clone();
        self.height_wu_since_update = 0.0;
        self.solver_done = false;
    }

    fn normal_tolerance(&mut self) {
        if let Engine::Cpu(s) = &mut self.engine
            && (self.polished || s.params().tolerance != SolverParams::default().tolerance)
        {
            s.set_params(SolverParams::default());
        }
        self.polished = false;
    }

    /// An edit touched level-0 rows `rows`: warm re-solve. Edits are coalesced: the solver takes the
    /// latest sketch once it has done `MIN_HEIGHT_WU` of height work on the previous edit (or
    /// converged), so that during a fast drag every other frame at worst shows the heights moving
    /// instead of the solver restarting its field solve every frame.
    pub fn update(&mut self, sketch: &Sketch, rows: Range<usize>) {
        if rows.is_empty() {
            return;
        }
        if self.empty {
            // From an empty sketch the solver restarts cold anyway; `set_sketch` also makes it publish
            // the coarse levels first instead of showing level 0 while FMG rebuilds it.
            return self.set_sketch(sketch);
        }
        self.edited = true;
        self.pending = true;
        self.last.converged = false;
    }

    fn apply_pending(&mut self, sketch: &Sketch) {
        let ready = self.solver_done || self.height_wu_since_update >= MIN_HEIGHT_WU;
        if !ready {
            return;
        }
        if std::mem::take(&mut self.pending) {
            self.normal_tolerance();
            match &mut self.engine {
                // Only the texels the changed strokes can touch, before and after.
                Engine::Cpu(s) => {
                    s.update_sketch_spans(sketch, &diff_spans(&self.grid, &self.applied, sketch))
                }
                Engine::Gpu(g) => {
                    // The GPU engine re-rasterises the whole sketch when it starts (see `step_gpu`).
                    g.polish_iters = 0;
                    g.restart = true;
                }
            }
            self.applied = sketch.clone();
            self.empty = sketch.strokes.is_empty();
            self.height_wu_since_update = 0.0;
            self.solver_done = false;
        }
    }

    /// Runs the solver on `sketch` (the document's current sketch) for up to `budget`; nothing if
    /// settled. An edit makes the solver redo the (warm) gradient-field solve first, which can use the
    /// whole budget; so that the heights follow the pen, small steps continue until `MIN_HEIGHT_WU` of
    /// height work is done this frame or `4 x budget` (at least 40 ms) has passed. In a frame without a
    /// new edit (the pointer stopped) the steps continue until converged or `25 x budget`, so the
    /// terrain settles right after the drag ends. Once converged the idle refinement runs one budget
    /// per frame. A GPU error makes the CPU solver take over (see `fallback`).
    pub fn step(&mut self, sketch: &Sketch, budget: Duration) {
        if let Engine::Gpu(_) = self.engine {
            if let Err(e) = self.step_gpu(sketch, budget) {
                let why = format!("GPU solver failed ({e}); the CPU solver took over");
                self.fall_back_to_cpu(sketch, why);
            }
            return;
        }
        self.step_cpu(sketch, budget);
    }

    fn step_cpu(&mut self, sketch: &Sketch, budget: Duration) {
        self.frame_work_units = 0.0;
        self.apply_pending(sketch);
        let Engine::Cpu(solver) = &mut self.engine else {
            return;
        };
        if self.last.converged {
            if self.polished || solver.finest_ready_level() != Some(0) {
                return;
            }
            let params = SolverParams {
                tolerance: POLISH_TOLERANCE,
                ..SolverParams::default()
            };
            if solver.params().tolerance != POLISH_TOLERANCE {
                solver.set_params(params);
            }
            let p = solver.step(Budget::Time(budget));
            self.frame_work_units = p.work_units + p.field_work_units;
            self.polished = p.converged;
            self.version += 1;
            self.refresh_pyramid();
            return;
        }
        let start = std::time::Instant::now();
        let settling = !std::mem::take(&mut self.edited);
        let cap = if settling {
            budget * 25
        } else {
            (budget * 4).max(Duration::from_millis(40))
        };
        let mut p = solver.step(Budget::Time(budget));
        let mut height_wu = p.work_units;
        self.frame_work_units = p.work_units + p.field_work_units;
        while !p.converged && (settling || height_wu < MIN_HEIGHT_WU) && start.elapsed() < cap {
            p = solver.step(Budget::WorkUnits(0.25));
            height_wu += p.work_units;
            self.frame_work_units += p.work_units + p.field_work_units;
        }
        self.height_wu_since_update += height_wu;
        self.solver_done = p.converged;
        self.last = p;
        self.last.converged = p.converged && !self.pending;
        self.version += 1;
        self.refresh_pyramid();
    }

    /// The GPU engine's frame: take the pending edit when due (re-rasterise, warm field solves, edge
    /// differences and operator on the GPU, FCG started), then FCG iterations under the same budget
    /// rules as the CPU, then the mip chain and the min/max pyramid (the only read-back besides FCG's
    /// 8-byte stop tests, the probes and, once settled, the picking copy).
    fn step_gpu(&mut self, sketch: &Sketch, budget: Duration) -> Result<(), GpuError> {
        self.frame_work_units = 0.0;
        self.apply_pending(sketch);
        let tolerance = SolverParams::default().tolerance;
        let start = std::time::Instant::now();
        let Engine::Gpu(g) = &mut self.engine else {
            return Ok(());
        };
        let mut height_wu = 0.0;
        let mut began = false;
        if g.cold || std::mem::take(&mut g.restart) {
            let cold = std::mem::take(&mut g.cold);
            let b = g.solver.begin(sketch, cold)?;
            g.ready = true;
            g.polish_iters = 0;
            height_wu += b.work_units;
            self.frame_work_units += b.work_units + b.field_work_units;
            self.empty = sketch.strokes.is_empty();
            self.height_wu_since_update = 0.0;
            self.solver_done = false;
            began = true;
        }
        if !g.ready {
            return Ok(());
        }
        let converged_before = self.last.converged;
        if converged_before && self.polished {
            return Ok(());
        }
        let settling = !std::mem::take(&mut self.edited);
        let cap = if converged_before {
            budget
        } else if settling {
            budget * 25
        } else {
            (budget * 4).max(Duration::from_millis(40))
        };
        let mut exhausted = false;
        let mut iters = 0u32;
        loop {
            let r = g.solver.residual();
            let target = if converged_before {
                POLISH_TOLERANCE
            } else {
                tolerance
            };
            if r <= target || exhausted {
                break;
            }
            if converged_before && g.polish_iters >= GPU_POLISH_ITERS {
                break;
            }
            let elapsed = start.elapsed();
            let want_more = settling || converged_before || height_wu < MIN_HEIGHT_WU;
            if elapsed >= cap || (elapsed >= budget && !want_more) {
                break;
            }
            match g.solver.iterate()? {
                Some(wu) => {
                    height_wu += wu;
                    self.frame_work_units += wu;
                    iters += 1;
                    if converged_before {
                        g.polish_iters += 1;
                    }
                }
                None => exhausted = true,
            }
        }
        let residual = g.solver.residual();
        let converged = residual <= tolerance || exhausted;
        if converged_before {
            self.polished =
                residual <= POLISH_TOLERANCE || exhausted || g.polish_iters >= GPU_POLISH_ITERS;
        }
        self.height_wu_since_update += height_wu;
        self.solver_done = converged;
        self.last = Progress {
            finest_ready_level: Some(0),
            residual,
            work_units: height_wu,
            field_work_units: self.frame_work_units - height_wu,
            vcycles: iters,
            converged: converged && !self.pending,
        };
        if began || iters > 0 {
            g.solver.publish()?;
            self.version += 1;
            let levels: Vec<(usize, Vec<[f32; 2]>)> = g
                .solver
                .min_max()?
                .into_iter()
                .map(|l| (l.side, l.cells))
                .collect();
            match MinMaxPyramid::from_levels(levels) {
                Ok(p) => self.pyramid = Some(p),
                Err(e) => eprintln!("terrasketch: warning: min/max pyramid refused: {e}"),
            }
        }
        // The picking copy: at the first heights, then each time the terrain settles again.
        let settled = self.last.converged && self.polished;
        if g.pick.is_none() || (settled && g.pick_version != self.version) {
            let k = self
                .grid
                .n
                .trailing_zeros()
                .saturating_sub(PICK_MAX_SIDE.trailing_zeros());
            let side = self.grid.side(k as usize);
            let data = g.solver.read_mip(k as usize)?;
            g.pick = Some(HeightField {
                side,
                extent_m: [self.grid.extent_m[0] as f32, self.grid.extent_m[1] as f32],
                data,
            });
            g.pick_version = self.version;
        }
        Ok(())
    }

    fn refresh_pyramid(&mut self) {
        let Engine::Cpu(solver) = &self.engine else {
            return;
        };
        let levels: Vec<(usize, Vec<[f32; 2]>)> = solver
            .minmax()
            .iter()
            .map(|l| (l.side, l.cells.clone()))
            .collect();
        if !levels.is_empty() {
            // The solver builds an exact pyramid; a refusal would be a bug there: keep the old one.
            match MinMaxPyramid::from_levels(levels) {
                Ok(p) => self.pyramid = Some(p),
                Err(e) => eprintln!("terrasketch: warning: min/max pyramid refused: {e}"),
            }
        }
    }

    /// Solves `sketch` to the tolerance now (export).
    pub fn finish(&mut self, sketch: &Sketch) {
        let mut guard = 0;
        while !self.settled() && guard < 10_000 {
            self.step(sketch, Duration::from_secs(3600));
            guard += 1;
        }
    }

    /// True when the heights meet the tolerance for the current sketch.
    pub fn converged(&self) -> bool {
        self.last.converged
    }

    /// True when, after converging, the idle refinement has finished too (nothing left to do).
    pub fn settled(&self) -> bool {
        self.last.converged
            && (self.polished
                || match &self.engine {
                    Engine::Cpu(s) => s.finest_ready_level() != Some(0),
                    Engine::Gpu(_) => false,
                })
    }

    /// Finest mip the solver has ready.
    pub fn finest_ready(&self) -> Option<u32> {
        if self.refined.is_some() {
            return Some(0);
        }
        match &self.engine {
            Engine::Cpu(s) => s.finest_ready_level(),
            Engine::Gpu(g) => g.ready.then_some(0),
        }
    }

    /// Mip `k` of the heights (row 0 south) of the CPU engine (empty on the GPU: nothing to upload).
    pub fn mip(&self, k: usize) -> &[f32] {
        if let Some(r) = &self.refined {
            return r.mips.get(k).map(|m| m.as_slice()).unwrap_or(&[]);
        }
        match &self.engine {
            Engine::Cpu(s) => s.mip(k),
            Engine::Gpu(_) => &[],
        }
    }

    /// Level-0 heights shown (the refined layer's when shown; else the solver's, read back in full
    /// from the GPU: snapshots, export and the start of a refinement only).
    pub fn heights(&self) -> Result<Vec<f32>> {
        if let Some(r) = &self.refined {
            return Ok(r.mips[0].clone());
        }
        self.solver_heights()
    }

    /// Level-0 heights of the solver (the diffusion terrain), whatever is shown.
    pub fn solver_heights(&self) -> Result<Vec<f32>> {
        match &self.engine {
            Engine::Cpu(s) => Ok(s.heights().to_vec()),
            Engine::Gpu(g) => Ok(g.solver.read_heights()?),
        }
    }

    /// Level-0 elevation-constraint weights of `sketch` (the constraint overlay). The GPU engine
    /// rasterises on the GPU and keeps nothing on the CPU: the overlay is rasterised here, on the CPU,
    /// only while it is shown (cached per sketch).
    pub fn constraint_weights(&mut self, sketch: &Sketch) -> &[f32] {
        match &mut self.engine {
            Engine::Cpu(s) => &s.constraints().elev_weight,
            Engine::Gpu(g) => {
                if g.overlay.as_ref().is_none_or(|(s, _)| s != sketch) {
                    g.overlay = Some((
                        sketch.clone(),
                        ConstraintMaps::rasterize(sketch, &self.grid).elev_weight,
                    ));
                }
                g.overlay.as_ref().map(|(_, w)| w.as_slice()).unwrap_or(&[])
            }
        }
    }

    /// Residual of the last step (None before level 0 exists).
    pub fn residual(&self) -> Option<f32> {
        self.last.residual.is_finite().then_some(self.last.residual)
    }

    /// A copy of the heights for picking and the frozen stroke plane (None before any): the finest
    /// ready mip on the CPU; on the GPU a copy of side <= 256 read when the terrain last settled.
    pub fn field(&self) -> Option<HeightField> {
        if let Some(r) = &self.refined {
            let k = match self.engine {
                Engine::Cpu(_) => 0,
                Engine::Gpu(_) => {
                    self.grid
                        .n
                        .trailing_zeros()
                        .saturating_sub(PICK_MAX_SIDE.trailing_zeros()) as usize
                }
            };
            return Some(HeightField {
                side: self.grid.side(k),
                extent_m: [self.grid.extent_m[0] as f32, self.grid.extent_m[1] as f32],
                data: r.mips.get(k)?.clone(),
            });
        }
        match &self.engine {
            Engine::Cpu(_) => {
                let k = self.finest_ready()? as usize;
                Some(HeightField {
                    side: self.grid.side(k),
                    extent_m: [self.grid.extent_m[0] as f32, self.grid.extent_m[1] as f32],
                    data: self.mip(k).to_vec(),
                })
            }
            Engine::Gpu(g) => g.pick.clone(),
        }
    }

    /// Displayed heights at world points: bilinear on the finest ready mip, exactly the vertex
    /// shader's `sample_height` (None before any mip, or for a non-finite point). On the GPU the four
    /// texels of each point are read back (16 bytes a probe).
    pub fn probe_heights(&self, points: &[[f64; 2]]) -> Result<Vec<Option<f32>>> {
        let Some(k) = self.finest_ready() else {
            return Ok(vec![None; points.len()]);
        };
        let k = k as usize;
        let side = self.grid.side(k);
        let uv = |p: &[f64; 2]| {
            [
                (p[0] / self.grid.extent_m[0]) as f32,
                (p[1] / self.grid.extent_m[1]) as f32,
            ]
        };
        let cpu_mip = match (&self.refined, &self.engine) {
            (Some(r), _) => r.mips.get(k).map(|m| m.as_slice()),
            (None, Engine::Cpu(s)) => Some(s.mip(k)),
            (None, Engine::Gpu(_)) => None,
        };
        if let Some(m) = cpu_mip {
            return Ok(points
                .iter()
                .map(|p| {
                    let [u, v] = uv(p);
                    (p[0].is_finite() && p[1].is_finite()).then(|| sample_bilinear(m, side, u, v))
                })
                .collect());
        }
        match &self.engine {
            Engine::Cpu(_) => Ok(vec![None; points.len()]),
            Engine::Gpu(g) => {
                let live: Vec<(usize, Corners)> = points
                    .iter()
                    .enumerate()
                    .filter(|(_, p)| p[0].is_finite() && p[1].is_finite())
                    .map(|(i, p)| {
                        let [u, v] = uv(p);
                        (i, bilinear_corners(side, u, v))
                    })
                    .collect();
                let texels: Vec<[u32; 2]> = live
                    .iter()
                    .flat_map(|(_, c)| c.texels.iter().map(|t| [t[0] as u32, t[1] as u32]))
                    .collect();
                let values = g.solver.read_texels(k as u32, &texels)?;
                let mut out = vec![None; points.len()];
                for ((i, c), h) in live.iter().zip(values.chunks_exact(4)) {
                    out[*i] = Some(c.combine([h[0], h[1], h[2], h[3]]));
                }
                Ok(out)
            }
        }
    }

    /// Lowest and highest height (from the pyramid), or `[0, 0]`.
    pub fn z_range(&self) -> [f32; 2] {
        self.shown_pyramid()
            .map(|p| p.total_bounds())
            .unwrap_or([0.0, 0.0])
    }

    /// Rows of mip `k` that differ from what the texture holds, updating the shadow copy; `None` if
    /// nothing changed (always on the GPU engine: its texture is drawn directly). The first call for a
    /// level returns all rows.
    pub fn take_changed_rows(&mut self, k: usize) -> Option<Range<usize>> {
        let data = match (&self.refined, &self.engine) {
            (Some(r), _) => r.mips.get(k)?.as_slice(),
            (None, Engine::Cpu(solver)) => solver.mip(k),
            (None, Engine::Gpu(_)) => return None,
        };
        let side = self.grid.side(k);
        let shadow = &mut self.shadow[k];
        if shadow.len() != data.len() {
            *shadow = data.to_vec();
            return Some(0..side);
        }
        let row_differs =
            |j: usize| data[j * side..(j + 1) * side] != shadow[j * side..(j + 1) * side];
        let first = (0..side).find(|&j| row_differs(j))?;
        let last = (first..side)
            .rev()
            .find(|&j| row_differs(j))
            .unwrap_or(first);
        shadow[first * side..(last + 1) * side]
            .copy_from_slice(&data[first * side..(last + 1) * side]);
        Some(first..last + 1)
    }

    /// Shows `r` instead of the solver's heights (None: the solver's again). The renderer's texture
    /// gets the rows that differ (`take_changed_rows`); the solver is untouched.
    pub fn show_refined(&mut self, r: Option<&Arc<Refined>>) {
        let same = match (&self.refined, r) {
            (None, None) => true,
            (Some(a), Some(b)) => Arc::ptr_eq(a, b),
            _ => false,
        };
        if !same {
            self.refined = r.cloned();
            self.version += 1;
        }
    }

    /// True while a refined layer is shown.
    pub fn refined_shown(&self) -> bool {
        self.refined.is_some()
    }

    /// The quadtree's bounds of what is shown: the refined layer's, else the solver's.
    pub fn shown_pyramid(&self) -> Option<&MinMaxPyramid> {
        match &self.refined {
            Some(r) => Some(&r.pyramid),
            None => self.pyramid.as_ref(),
        }
    }

    /// The solver's diffused roughness on level 2 (row 0 south), CPU solver only (solved now if the
    /// sketch changed since it was last asked for).
    pub fn roughness(&mut self) -> Option<Vec<f32>> {
        match &mut self.engine {
            Engine::Cpu(s) => Some(s.roughness().to_vec()),
            Engine::Gpu(_) => None,
        }
    }

    /// Level-0 rows a set of strokes can touch in two versions of a sketch: the union over strokes that
    /// differ between `a` and `b`.
    pub fn diff_rows(&self, a: &Sketch, b: &Sketch) -> Range<usize> {
        if a.extent_m != b.extent_m || a.base_elevation_m != b.base_elevation_m {
            return 0..self.grid.n;
        }
        let mut rows: Option<Range<usize>> = None;
        let mut add = |r: Range<usize>| {
            if r.is_empty() {
                return;
            }
            rows = Some(match rows.take() {
                None => r,
                Some(o) => o.start.min(r.start)..o.end.max(r.end),
            });
        };
        for i in 0..a.strokes.len().max(b.strokes.len()) {
            if a.strokes.get(i) != b.strokes.get(i) {
                add(ConstraintMaps::stroke_rows(a, i, &self.grid));
                add(ConstraintMaps::stroke_rows(b, i, &self.grid));
            }
        }
        rows.unwrap_or(0..0)
    }
}

/// The level-0 texels whose constraints can differ between sketches `a` and `b`: the spans of every
/// stroke that differs, in both sketches (every texel if the extent or base elevation differ).
fn diff_spans(grid: &Grid, a: &Sketch, b: &Sketch) -> Vec<(usize, Range<usize>)> {
    let n = grid.n;
    if a.extent_m != b.extent_m || a.base_elevation_m != b.base_elevation_m {
        return (0..n).map(|j| (j, 0..n)).collect();
    }
    let mut spans = Vec::new();
    for i in 0..a.strokes.len().max(b.strokes.len()) {
        if a.strokes.get(i) != b.strokes.get(i) {
            spans.extend(ConstraintMaps::stroke_spans(a, i, grid));
            spans.extend(ConstraintMaps::stroke_spans(b, i, grid));
        }
    }
    spans
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn diff_spans_hold_the_changed_strokes_only() {
        let a = terrasketch_sketch::benchmark_sketch();
        let grid = Grid::new(128, a.extent_m).unwrap();
        assert!(diff_spans(&grid, &a, &a).is_empty());
        let mut b = a.clone();
        for p in &mut b.strokes[2].points {
            p[0] += 300.0;
        }
        let mut want = ConstraintMaps::stroke_spans(&a, 2, &grid);
        want.extend(ConstraintMaps::stroke_spans(&b, 2, &grid));
        assert_eq!(diff_spans(&grid, &a, &b), want);
        b.base_elevation_m += 1.0;
        let all = diff_spans(&grid, &a, &b);
        assert_eq!(all.len(), 128);
        assert!(all.iter().all(|(_, c)| *c == (0..128)));
    }

    #[test]
    fn raycast_hits_a_flat_field() {
        let f = HeightField {
            side: 64,
            extent_m: [1000.0, 1000.0],
            data: vec![10.0; 64 * 64],
        };
        let ray = Ray {
            origin: Vec3::new(500.0, -100.0, 500.0),
            dir: Vec3::new(0.0, 1.0, -1.0).normalize(),
        };
        let p = f.raycast(&ray).unwrap();
        assert!(
            (p.z - 10.0).abs() < 0.01 && (p.y - 390.0).abs() < 0.1,
            "{p}"
        );
    }
}
