//! The terrain as the editor sees it: the GPU solver (on the editor's device, its texture drawn
//! directly) or the CPU solver, stepped within a frame budget; the min/max pyramid for the quadtree;
//! probes and picking on what is shown (`heightfield`); and, for the CPU solver, the
//! row-level change tracking that decides what is uploaded to the heightmap texture.

use std::ops::Range;
use std::sync::Arc;
use std::time::Duration;

use anyhow::{Context, Result};
use terrasketch_multigrid::gpu::{GpuContext, GpuCounters, TexelSet};
use terrasketch_multigrid::gpu_solver::GpuSolver;
use terrasketch_multigrid::{ConstraintMaps, Grid, Progress, SolverParams};
use terrasketch_quadtree::MinMaxPyramid;
use terrasketch_sketch::Sketch;

use super::budget::{FrameBudget, Meter};
use super::heightfield::{Corners, HeightField, bilinear_corners, sample_bilinear};
use super::refine::Refined;
use super::render::SceneRenderer;
use super::terrain_cpu::CpuEngine;
use super::terrain_gpu::GpuEngine;

/// Which solver runs the terrain.
enum Engine {
    /// The CPU solver (and its twin on large grids); its mips are uploaded row by row.
    Cpu(Box<CpuEngine>),
    /// The GPU solver on the editor's device; its texture is drawn directly.
    Gpu(Box<GpuEngine>),
}

/// Largest side of the picking copy read back from the GPU (256^2 floats = 256 KB, read once the
/// terrain has settled, never while the pointer edits).
const PICK_MAX_SIDE: usize = 256;

/// The solver and what the renderer needs from it.
pub struct Terrain {
    /// The grid.
    pub grid: Grid,
    engine: Engine,
    /// Progress of the last step that ran.
    pub last: Progress,
    /// Work units of this frame's step in reference units (see `budget::REFERENCE_CELLS`; 0 if none
    /// ran).
    pub frame_work_units: f64,
    /// The quadtree's bounds (from the solver's min/max pyramid), once a mip is ready.
    pub pyramid: Option<MinMaxPyramid>,
    /// Bumped whenever the published heights may have changed.
    pub version: u64,
    /// What the texture holds, per mip level (empty until first uploaded; CPU engine).
    shadow: Vec<Vec<f32>>,
    /// An edit arrived since the last step (the pointer is still moving).
    edited: bool,
    /// The tool button is held (an edit may follow): nothing large is read back meanwhile.
    pointer_held: bool,
    /// Converged, and the idle refinement done, for the sketch of the last step.
    settled: bool,
    /// Why the GPU solver was given up this frame (taken by the frame loop to tell the user).
    pub fallback: Option<String>,
    /// The refined layer shown instead of the solver's heights (the solver keeps its own).
    refined: Option<Arc<Refined>>,
    /// The constraint overlay's weights rasterised on the CPU, and the sketch they belong to (the
    /// GPU engine keeps no maps on the CPU; the CPU engine's lag behind a drag on large grids).
    overlay: Option<(Sketch, Vec<f32>)>,
    /// The procedural detail shown on the solver's heights.
    detail: Detail,
}

/// The procedural detail (`terrasketch_detail`) as the editor shows it: the octave sums per mip
/// (made once per grid and seed) and the level-2 amplitude, which follows every edit (the CPU
/// solver's roughness is solved incrementally in each frame that changed the heights).
#[derive(Default)]
struct Detail {
    /// Shown (the view toggle).
    on: bool,
    /// The sketch seed the noise belongs to.
    seed: u64,
    /// Octave sums per mip (None until first needed, or after a seed change).
    noise: Option<Vec<Vec<f32>>>,
    /// The noise in the renderer's texture is current.
    noise_uploaded: bool,
    /// Amplitude (side n / 4; empty before the first).
    amp: Vec<f32>,
    /// The amplitude in the renderer's texture is current.
    amp_uploaded: bool,
    /// The solver's min/max levels, kept to widen them by the detail.
    base_levels: Vec<(usize, Vec<[f32; 2]>)>,
    /// The quadtree's bounds with the detail's reach added.
    pyramid: Option<MinMaxPyramid>,
    /// GPU engine: the amplitude pass, the heights version it last ran for, and the bound of the
    /// amplitude it can write (the law at the steepest slope and the sketch's largest roughness:
    /// the amplitude stays on the device, so the bounds take this uniform reach).
    gpu_pass: Option<super::detail_gpu::AmplitudePass>,
    /// The texture the pass writes (the renderer's; the probes read it).
    gpu_texture: Option<wgpu::Texture>,
    gpu_version: u64,
    gpu_bound: Option<f32>,
}
impl Terrain {
    /// A solver of side `n` for `sketch`, not yet stepped: on the GPU of `gpu` when given (its device
    /// must have [`GpuContext::required_limits`]), else on the CPU.
    pub fn new(sketch: &Sketch, n: usize, gpu: Option<&GpuContext>) -> Result<Terrain> {
        let grid = Grid::new(n, sketch.extent_m).context("cannot make the terrain grid")?;
        let engine = match gpu {
            Some(ctx) => {
                let solver = GpuSolver::new(ctx, grid, SolverParams::default())
                    .context("cannot set up the GPU solver")?;
                Engine::Gpu(Box::new(GpuEngine::new(solver)))
            }
            None => Engine::Cpu(Box::new(CpuEngine::new(grid)?)),
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
            edited: false,
            pointer_held: false,
            settled: false,
            fallback: None,
            refined: None,
            overlay: None,
            detail: Detail::default(),
        })
    }

    /// A terrain of the same backend (and device) for another sketch of side `n`.
    pub fn rebuilt(&self, sketch: &Sketch, n: usize) -> Result<Terrain> {
        Terrain::new(sketch, n, self.gpu_context().as_ref())
    }

    /// The GPU context when the GPU solver runs the terrain.
    pub fn gpu_context(&self) -> Option<GpuContext> {
        match &self.engine {
            Engine::Gpu(g) => Some(g.solver().context().clone()),
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
            Engine::Gpu(g) => Some(g.solver().texture()),
            Engine::Cpu(_) => None,
        }
    }

    /// What the GPU solver did with the device since the last call (bytes sent and read back,
    /// dispatches, submits, blocking waits; all 0 on the CPU).
    pub fn take_counters(&mut self) -> GpuCounters {
        match &mut self.engine {
            Engine::Gpu(g) => {
                let now = g.solver().context().counters();
                let d = now.since(&g.counters_mark);
                g.counters_mark = now;
                d
            }
            Engine::Cpu(_) => GpuCounters::default(),
        }
    }

    /// Gives up the GPU solver (after an error, or when asked): the CPU solver takes the document's
    /// sketch from scratch at the next step; `fallback` says why.
    pub fn fall_back_to_cpu(&mut self, why: String) {
        let engine = match CpuEngine::new(self.grid) {
            Ok(s) => s,
            Err(e) => {
                self.fallback = Some(format!("{why}; the CPU solver failed too: {e:#}"));
                return;
            }
        };
        self.engine = Engine::Cpu(Box::new(engine));
        self.detail.gpu_bound = None;
        self.detail.amp.clear();
        self.shadow = vec![Vec::new(); self.grid.mip_levels()];
        self.fallback = Some(why);
        self.restart();
    }

    /// The whole sketch was replaced: the solver takes the document's sketch cold at the next step.
    pub fn restart(&mut self) {
        match &mut self.engine {
            Engine::Cpu(c) => c.restart(),
            Engine::Gpu(g) => g.live.restart(),
        }
        self.settled = false;
        self.last.converged = false;
    }

    /// Whether the tool button is held (the GPU's picking copy is not read back meanwhile).
    pub fn set_pointer_held(&mut self, held: bool) {
        self.pointer_held = held;
    }

    /// An edit touched level-0 rows `rows`: the solvers take the new sketch at the next steps (what
    /// changed is found by comparing with the sketch each solver has).
    pub fn update(&mut self, rows: Range<usize>) {
        if rows.is_empty() {
            return;
        }
        self.edited = true;
        self.settled = false;
        self.last.converged = false;
    }

    /// Runs the solver on `sketch` (the document's current sketch) for one frame's `budget`.
    /// While edits arrive, each frame ends only once what is shown had a global correction for the
    /// newest sketch the solver took (within `4 x budget`, at least 40 ms of time); on larger grids
    /// than `terrain_cpu::LIVE_SIDE` the CPU solver's twin follows the pen, coarse first. In a
    /// frame without an edit (the pointer stopped) the steps continue until converged or `25 x
    /// budget`. Once converged the idle refinement runs one budget per frame. A GPU error makes the
    /// CPU solver take over (see `fallback`).
    pub fn step(&mut self, sketch: &Sketch, budget: FrameBudget) {
        if let Engine::Gpu(_) = self.engine {
            if let Err(e) = self.step_gpu(sketch, budget) {
                let why = format!("GPU solver failed ({e:#}); the CPU solver took over");
                self.fall_back_to_cpu(why);
            }
            return;
        }
        self.step_cpu(sketch, budget);
    }

    fn step_cpu(&mut self, sketch: &Sketch, budget: FrameBudget) {
        let Engine::Cpu(c) = &mut self.engine else {
            return;
        };
        let edited = std::mem::take(&mut self.edited);
        let mut meter = Meter::new(budget);
        let before = (c.settled_for(sketch), c.showing_live);
        let w = match c.step(sketch, &mut meter, edited) {
            Ok(w) => w,
            Err(e) => {
                // The CPU solver reports no errors today; keep the last display if it ever does.
                self.fallback = Some(format!("the CPU solver failed: {e:#}"));
                return;
            }
        };
        self.frame_work_units = meter.work();
        self.settled = c.settled_for(sketch);
        let shown = c.shown();
        self.last = Progress {
            finest_ready_level: c.finest_ready(),
            residual: shown.residual(),
            work_units: w.height_wu,
            field_work_units: w.field_wu,
            vcycles: w.vcycles,
            converged: c.converged_for(sketch),
        };
        let changed = w.ran || before != (self.settled, c.showing_live);
        if changed {
            self.version += 1;
            self.refresh_pyramid();
        }
        if self.detail.on && (changed || self.detail.amp.is_empty()) {
            self.refresh_detail_cpu();
        }
    }

    /// Shows the detail or not, for sketch seed `seed` (a new seed makes new octave sums).
    pub fn set_detail(&mut self, on: bool, seed: u64) {
        if seed != self.detail.seed {
            self.detail.seed = seed;
            self.detail.noise = None;
            self.detail.noise_uploaded = false;
        }
        if on && !self.detail.on {
            // The amplitude may be stale: recompute it at the next CPU step.
            self.detail.amp.clear();
        }
        self.detail.on = on;
    }

    /// True when the detail is shown (the toggle is on and no refined layer replaces it).
    pub fn detail_shown(&self) -> bool {
        self.detail.on && self.refined.is_none()
    }

    /// The CPU solver's detail amplitude from its current heights and roughness (the roughness solve
    /// is incremental: only the rows the edits changed are reassembled, then FCG from the last
    /// solution). Kept while the twin is shown on large grids (its grid is not the terrain's).
    fn refresh_detail_cpu(&mut self) {
        let Engine::Cpu(c) = &mut self.engine else {
            return;
        };
        if c.showing_live || c.finest_ready().is_none_or(|k| k > 2) {
            return;
        }
        self.detail.amp = crate::detail::amplitude_cpu(&mut c.full.solver.solver);
        self.detail.amp_uploaded = false;
        self.rebuild_detail_pyramid();
    }

    /// The quadtree's bounds widened by the largest detail each cell can show.
    fn rebuild_detail_pyramid(&mut self) {
        let m = self.grid.n / 4;
        let sides: Vec<usize> = self.detail.base_levels.iter().map(|l| l.0).collect();
        let maxes = match self.detail.gpu_bound {
            Some(a) => sides.iter().map(|s| vec![a; s * s]).collect(),
            None if self.detail.amp.len() == m * m => {
                terrasketch_detail::max_pyramid(m, &self.detail.amp, &sides)
            }
            None => Vec::new(),
        };
        if self.detail.base_levels.is_empty() || maxes.is_empty() {
            self.detail.pyramid = None;
            return;
        }
        let reach = terrasketch_detail::fbm_bound(terrasketch_detail::cell_min_wavelength_m(
            self.grid.n,
            self.grid.extent_m,
        ));
        let levels = self
            .detail
            .base_levels
            .iter()
            .zip(&maxes)
            .map(|((side, cells), mx)| {
                let cells = cells
                    .iter()
                    .zip(mx)
                    .map(|(c, a)| [c[0] - a * reach, c[1] + a * reach])
                    .collect();
                (*side, cells)
            })
            .collect();
        self.detail.pyramid = MinMaxPyramid::from_levels(levels).ok();
    }

    /// GPU engine: writes the amplitude of the heights just published into `out` (the renderer's
    /// amplitude texture), once per heights version. A GPU error makes the CPU solver take over.
    pub fn run_detail_gpu(&mut self, out: &wgpu::Texture) {
        if !self.detail.on || self.detail.gpu_version == self.version {
            return;
        }
        let Engine::Gpu(g) = &self.engine else {
            return;
        };
        if !g.live.started() {
            return;
        }
        let solver = g.solver();
        let pass = self
            .detail
            .gpu_pass
            .get_or_insert_with(|| super::detail_gpu::AmplitudePass::new(&solver.context().device));
        if let Err(e) = pass.run(solver, out) {
            let why = format!("GPU detail failed ({e}); the CPU solver took over");
            self.fall_back_to_cpu(why);
            return;
        }
        self.detail.gpu_version = self.version;
        self.detail.gpu_texture = Some(out.clone());
    }

    /// Sends what the detail needs to the renderer: the octave sums once per grid and seed (made
    /// here the first time), the amplitude when it changed. Nothing while the detail is off.
    /// Returns bytes sent.
    pub fn upload_detail(&mut self, scene: &SceneRenderer, queue: &wgpu::Queue) -> u64 {
        if !self.detail.on {
            return 0;
        }
        let mut bytes = 0;
        if !self.detail.noise_uploaded {
            let noise = self.detail.noise.get_or_insert_with(|| {
                terrasketch_detail::noise_mips(self.grid.n, self.grid.extent_m, self.detail.seed)
            });
            for (k, level) in noise.iter().enumerate() {
                bytes += scene.upload_noise(queue, k as u32, level);
            }
            self.detail.noise_uploaded = true;
        }
        if !self.detail.amp_uploaded && !self.detail.amp.is_empty() {
            bytes += scene.upload_amplitude(queue, &self.detail.amp);
            self.detail.amp_uploaded = true;
        }
        bytes
    }

    /// The detail at world-fraction `(u, v)` on mip `k` as the vertex shader adds it (0 when not
    /// shown or not ready).
    fn detail_at(&self, u: f32, v: f32, k: usize) -> f32 {
        let m = self.grid.n / 4;
        let (Some(noise), true) = (
            self.detail.noise.as_ref().and_then(|n| n.get(k)),
            self.detail_shown() && self.detail.amp.len() == m * m,
        ) else {
            return 0.0;
        };
        let a = terrasketch_detail::sample_bilinear(&self.detail.amp, m, u, v);
        if a > 0.0 {
            a * sample_bilinear(noise, self.grid.side(k), u, v)
        } else {
            0.0
        }
    }

    /// The GPU engine's frame (`GpuEngine::step`), then the min/max pyramid when the heights changed
    /// (the only read-back besides FCG's 8-byte stop tests, the probes and, once settled, the
    /// picking copy).
    fn step_gpu(&mut self, sketch: &Sketch, budget: FrameBudget) -> Result<()> {
        let Engine::Gpu(g) = &mut self.engine else {
            return Ok(());
        };
        let edited = std::mem::take(&mut self.edited);
        let mut meter = Meter::new(budget);
        let w = g.step(sketch, &mut meter, edited)?;
        self.frame_work_units = meter.work();
        let converged = g.live.converged_for(sketch);
        self.settled = converged && g.live.polished();
        self.last.converged = converged;
        if !g.live.started() {
            return Ok(());
        }
        self.last = Progress {
            finest_ready_level: Some(0),
            residual: g.solver().residual(),
            work_units: w.height_wu,
            field_work_units: w.field_wu,
            vcycles: w.vcycles,
            converged,
        };
        if w.ran {
            self.version += 1;
            let rmax = sketch
                .strokes
                .iter()
                .map(|s| s.roughness as f32)
                .fold(0.0f32, f32::max);
            self.detail.gpu_bound = Some(terrasketch_detail::amplitude::amplitude_law(
                terrasketch_detail::calibration::SLOPE_TAN_MAX,
                rmax,
            ));
        }
        // The pyramid of an earlier publish, when the device has delivered it (never waited for;
        // the first one is, so that the quadtree has bounds at all).
        let levels = match (g.try_min_max()?, &self.pyramid) {
            (Some(l), _) => Some(l),
            (None, None) => Some(g.solver().min_max()?),
            (None, Some(_)) => None,
        };
        let new_levels = levels.is_some();
        if let Some(levels) = levels {
            let levels: Vec<(usize, Vec<[f32; 2]>)> =
                levels.into_iter().map(|l| (l.side, l.cells)).collect();
            self.detail.base_levels = levels.clone();
            match MinMaxPyramid::from_levels(levels) {
                Ok(p) => self.pyramid = Some(p),
                Err(e) => eprintln!("terrasketch: warning: min/max pyramid refused: {e}"),
            }
        }
        // The picking copy: at the first heights, then each time the terrain settles again while
        // no button is held.
        let refresh = self.settled && !self.pointer_held && g.pick_version != self.version;
        if g.pick.is_none() || refresh {
            let k = self
                .grid
                .n
                .trailing_zeros()
                .saturating_sub(PICK_MAX_SIDE.trailing_zeros());
            let side = self.grid.side(k as usize);
            let data = g.solver().read_mip(k as usize)?;
            g.pick = Some(HeightField {
                side,
                extent_m: [self.grid.extent_m[0] as f32, self.grid.extent_m[1] as f32],
                data,
            });
            g.pick_version = self.version;
        }
        if new_levels {
            self.rebuild_detail_pyramid();
        }
        Ok(())
    }

    fn refresh_pyramid(&mut self) {
        let Engine::Cpu(c) = &self.engine else {
            return;
        };
        let levels: Vec<(usize, Vec<[f32; 2]>)> = c
            .shown()
            .minmax()
            .iter()
            .map(|l| (l.side, l.cells.clone()))
            .collect();
        if !levels.is_empty() {
            self.detail.base_levels = levels.clone();
            self.rebuild_detail_pyramid();
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
            self.step(sketch, FrameBudget::Time(Duration::from_secs(3600)));
            guard += 1;
        }
    }

    /// True when the heights meet the tolerance for the current sketch.
    pub fn converged(&self) -> bool {
        self.last.converged
    }

    /// True when, after converging, the idle refinement has finished too (nothing left to do).
    pub fn settled(&self) -> bool {
        self.settled
    }

    /// Finest mip the solver has ready.
    pub fn finest_ready(&self) -> Option<u32> {
        if self.refined.is_some() {
            return Some(0);
        }
        match &self.engine {
            Engine::Cpu(c) => c.finest_ready(),
            Engine::Gpu(g) => g.live.started().then_some(0),
        }
    }

    /// Mip `k` of the heights (row 0 south) of the CPU engine (empty on the GPU: nothing to upload).
    pub fn mip(&self, k: usize) -> &[f32] {
        if let Some(r) = &self.refined {
            return r.mips.get(k).map(|m| m.as_slice()).unwrap_or(&[]);
        }
        match &self.engine {
            Engine::Cpu(c) => c.mip(k),
            Engine::Gpu(_) => &[],
        }
    }

    /// Level-0 heights shown (the refined layer's when shown; else the solver's, read back in full
    /// from the GPU: snapshots and export only).
    pub fn heights(&self) -> Result<Vec<f32>> {
        if let Some(r) = &self.refined {
            return Ok(r.mips[0].clone());
        }
        self.solver_heights()
    }

    /// Level-0 heights as exported: what is shown at the heightmap's own resolution (the refined
    /// layer, or the solver's heights with the detail when it is shown).
    pub fn export_heights(&mut self, sketch: &Sketch) -> Result<Vec<f32>> {
        let mut h = self.heights()?;
        if !self.detail_shown() {
            return Ok(h);
        }
        let amp = match &mut self.engine {
            Engine::Cpu(c) => crate::detail::amplitude_cpu(&mut c.full.solver.solver),
            Engine::Gpu(g) => {
                let s = g.solver();
                let weights = ConstraintMaps::rasterize(sketch, &self.grid).elev_weight;
                crate::detail::amplitude_from(
                    &self.grid,
                    &s.read_mip(2)?,
                    &s.read_roughness()?,
                    &weights,
                )
            }
        };
        terrasketch_detail::add_detail(&mut h, self.grid.n, self.grid.extent_m, &amp, sketch.seed);
        Ok(h)
    }

    /// Level-0 heights of the solver (the diffusion terrain), whatever is shown.
    pub fn solver_heights(&self) -> Result<Vec<f32>> {
        match &self.engine {
            Engine::Cpu(c) => Ok(c.full.solver.solver.heights().to_vec()),
            Engine::Gpu(g) => Ok(g.solver().read_heights()?),
        }
    }

    /// Level-0 elevation-constraint weights of `sketch` (the constraint overlay). The GPU engine
    /// rasterises on the GPU and keeps nothing on the CPU: the overlay is rasterised here, on the CPU,
    /// only while it is shown (cached per sketch).
    pub fn constraint_weights(&mut self, sketch: &Sketch) -> &[f32] {
        // The CPU solver's own maps when it has taken `sketch` (during a drag on a grid with a twin
        // it takes the sketch only once the pointer rests).
        let cpu_current = matches!(&self.engine, Engine::Cpu(c) if c.full.has_taken(sketch));
        if cpu_current && let Engine::Cpu(c) = &self.engine {
            return &c.full.solver.solver.constraints().elev_weight;
        }
        if self.overlay.as_ref().is_none_or(|(s, _)| s != sketch) {
            self.overlay = Some((
                sketch.clone(),
                ConstraintMaps::rasterize(sketch, &self.grid).elev_weight,
            ));
        }
        self.overlay
            .as_ref()
            .map(|(_, w)| w.as_slice())
            .unwrap_or(&[])
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
                let side = self.grid.side(k);
                let mut data = self.mip(k).to_vec();
                // What is shown: the detail at the mip's texel centres.
                if self.detail_shown() {
                    for (t, h) in data.iter_mut().enumerate() {
                        let (i, j) = (t % side, t / side);
                        let (u, v) = (
                            (i as f32 + 0.5) / side as f32,
                            (j as f32 + 0.5) / side as f32,
                        );
                        *h += self.detail_at(u, v, k);
                    }
                }
                Some(HeightField {
                    side,
                    extent_m: [self.grid.extent_m[0] as f32, self.grid.extent_m[1] as f32],
                    data,
                })
            }
            Engine::Gpu(g) => g.pick.clone(),
        }
    }

    /// Displayed heights at world points as `[diffusion, detail]` (the shown height is their sum):
    /// bilinear on the finest ready mip, exactly the vertex shader's `sample_height`, and the detail
    /// as drawn (0 when not shown). None before any mip, or for a non-finite point. On the GPU the
    /// four texels of each point are read back (16 bytes a probe, and 16 of amplitude).
    pub fn probe_heights(&self, points: &[[f64; 2]]) -> Result<Vec<Option<[f32; 2]>>> {
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
            // What the texture holds (the display keeps the last coherent state, see
            // `display_held`).
            (None, Engine::Cpu(c)) => Some(match self.shadow.get(k) {
                Some(m) if m.len() == side * side => m.as_slice(),
                _ => c.mip(k),
            }),
            (None, Engine::Gpu(_)) => None,
        };
        if let Some(m) = cpu_mip {
            return Ok(points
                .iter()
                .map(|p| {
                    let [u, v] = uv(p);
                    (p[0].is_finite() && p[1].is_finite())
                        .then(|| [sample_bilinear(m, side, u, v), self.detail_at(u, v, k)])
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
                // The detail as drawn: the amplitude's four texels, read with the heights' (one
                // wait), and the noise here.
                let m = self.grid.n / 4;
                let noise = self.detail.noise.as_ref().and_then(|n| n.get(k));
                let detail = match (self.detail_shown(), &self.detail.gpu_texture, noise) {
                    (true, Some(tex), Some(noise)) => Some((tex, noise)),
                    _ => None,
                };
                let amp_corners: Vec<Corners> = live
                    .iter()
                    .map(|(i, _)| {
                        let [u, v] = uv(&points[*i]);
                        bilinear_corners(m, u, v)
                    })
                    .collect();
                let amp_texels: Vec<[u32; 2]> = amp_corners
                    .iter()
                    .flat_map(|c| c.texels.iter().map(|t| [t[0] as u32, t[1] as u32]))
                    .collect();
                let other = detail.map(|(tex, _)| TexelSet {
                    texture: tex,
                    level: 0,
                    texels: &amp_texels,
                });
                let read = g.solver().read_texels_with(k as u32, &texels, other)?;
                let mut out = vec![None; points.len()];
                for ((i, c), h) in live.iter().zip(read[0].chunks_exact(4)) {
                    out[*i] = Some([c.combine([h[0], h[1], h[2], h[3]]), 0.0]);
                }
                if let (Some((_, noise)), Some(amps)) = (detail, read.get(1)) {
                    for (((i, _), c), a) in live.iter().zip(&amp_corners).zip(amps.chunks_exact(4))
                    {
                        let a = c.combine([a[0], a[1], a[2], a[3]]);
                        let [u, v] = uv(&points[*i]);
                        if let (Some(h), true) = (out[*i].as_mut(), a > 0.0) {
                            h[1] = a * sample_bilinear(noise, side, u, v);
                        }
                    }
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

    /// True while the display keeps the last coherent heights: the CPU solver's current state is
    /// only the local relaxation around an edit's changed constraints (a frame's cap ended before
    /// the global correction). Uploads wait until it is coherent.
    pub fn display_held(&self) -> bool {
        match (&self.refined, &self.engine) {
            (None, Engine::Cpu(c)) => !c.shown_coherent(),
            _ => false,
        }
    }

    /// Rows of mip `k` that differ from what the texture holds, updating the shadow copy; `None` if
    /// nothing changed (always on the GPU engine: its texture is drawn directly). The first call for a
    /// level returns all rows.
    pub fn take_changed_rows(&mut self, k: usize) -> Option<Range<usize>> {
        let data = match (&self.refined, &self.engine) {
            (Some(r), _) => r.mips.get(k)?.as_slice(),
            (None, Engine::Cpu(c)) => c.mip(k),
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
            None if self.detail_shown() && self.detail.pyramid.is_some() => {
                self.detail.pyramid.as_ref()
            }
            None => self.pyramid.as_ref(),
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
