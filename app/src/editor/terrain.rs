//! The terrain as the editor sees it: the GPU solver (on the editor's device, its texture drawn
//! directly) or the CPU solver, stepped within a frame budget; the min/max pyramid for the quadtree;
//! probes and picking on what is shown (`heightfield`); and, for the CPU solver, the
//! row-level change tracking that decides what is uploaded to the heightmap texture.

use std::ops::Range;
use std::sync::Arc;
use std::time::Duration;

use anyhow::{Context, Result};
use terrasketch_multigrid::gpu::{GpuContext, GpuCounters};
use terrasketch_multigrid::gpu_solver::GpuSolver;
use terrasketch_multigrid::{ConstraintMaps, Grid, Progress, SolverParams};
use terrasketch_quadtree::MinMaxPyramid;
use terrasketch_sketch::Sketch;

use super::budget::{FrameBudget, Meter};
use super::engine::{AfterStep, TerrainSolver};
use super::heightfield::{HeightField, sample_bilinear};
use super::refine::Refined;
use super::terrain_cpu::CpuEngine;
use super::terrain_detail::Detail;
use super::terrain_gpu::GpuEngine;

/// Which solver runs the terrain. What both do is reached through [`TerrainSolver`]; the variants
/// are matched only for what one backend alone has (the CPU's row uploads, the GPU's texture).
pub(super) enum Engine {
    /// The CPU solver (and its twin on large grids); its mips are uploaded row by row.
    Cpu(Box<CpuEngine>),
    /// The GPU solver on the editor's device; its texture is drawn directly.
    Gpu(Box<GpuEngine>),
}

impl Engine {
    fn solver(&self) -> &dyn TerrainSolver {
        match self {
            Engine::Cpu(c) => c.as_ref(),
            Engine::Gpu(g) => g.as_ref(),
        }
    }

    fn solver_mut(&mut self) -> &mut dyn TerrainSolver {
        match self {
            Engine::Cpu(c) => c.as_mut(),
            Engine::Gpu(g) => g.as_mut(),
        }
    }
}

/// The solver and what the renderer needs from it.
pub struct Terrain {
    /// The grid.
    pub grid: Grid,
    pub(super) engine: Engine,
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
    pub(super) refined: Option<Arc<Refined>>,
    /// The constraint overlay's weights rasterised on the CPU, and the sketch they belong to (the
    /// GPU engine keeps no maps on the CPU; the CPU engine's lag behind a drag on large grids).
    overlay: Option<(Sketch, Vec<f32>)>,
    /// The procedural detail shown on the solver's heights.
    pub(super) detail: Detail,
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
        self.engine.solver().name()
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
        self.engine.solver_mut().take_counters()
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
        self.engine.solver_mut().restart();
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
        let Err(e) = self.step_solver(sketch, budget) else {
            return;
        };
        match self.engine {
            Engine::Gpu(_) => {
                let why = format!("GPU solver failed ({e:#}); the CPU solver took over");
                self.fall_back_to_cpu(why);
            }
            // The CPU solver reports no errors today; keep the last display if it ever does.
            Engine::Cpu(_) => self.fallback = Some(format!("the CPU solver failed: {e:#}")),
        }
    }

    /// The one frame loop of both backends: the solver's step within the budget (`Meter`), its
    /// progress, the heights' version, the detail, and the min/max pyramid when new levels came
    /// (on the GPU the only read-back besides FCG's 8-byte stop tests, the probes and, once
    /// settled, the picking copy).
    fn step_solver(&mut self, sketch: &Sketch, budget: FrameBudget) -> Result<()> {
        let edited = std::mem::take(&mut self.edited);
        let mut meter = Meter::new(budget);
        let solver = self.engine.solver_mut();
        let before = (solver.settled_for(sketch), solver.shown_solver());
        let w = solver.step(sketch, &mut meter, edited)?;
        self.frame_work_units = meter.work();
        let converged = solver.converged_for(sketch);
        self.settled = solver.settled_for(sketch);
        self.last.converged = converged;
        if !solver.progress_ready() {
            return Ok(());
        }
        self.last = Progress {
            finest_ready_level: solver.finest_ready(),
            residual: solver.residual(),
            work_units: w.height_wu,
            field_work_units: w.field_wu,
            vcycles: w.vcycles,
            converged,
        };
        let changed = w.ran || before != (self.settled, solver.shown_solver());
        if changed {
            self.version += 1;
        }
        let levels = solver.min_max(changed, self.pyramid.is_none())?;
        solver.after_step(&AfterStep {
            settled: self.settled,
            pointer_held: self.pointer_held,
            version: self.version,
        })?;
        self.detail_after_step(sketch, w.ran, changed);
        if let Some(levels) = levels {
            self.detail.base_levels = levels.clone();
            self.rebuild_detail_pyramid();
            // The solver builds an exact pyramid; a refusal would be a bug there: keep the old one.
            match MinMaxPyramid::from_levels(levels) {
                Ok(p) => self.pyramid = Some(p),
                Err(e) => eprintln!("terrasketch: warning: min/max pyramid refused: {e}"),
            }
        }
        Ok(())
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
        self.engine.solver().finest_ready()
    }

    /// Mip `k` of the heights (row 0 south) of the CPU engine (empty on the GPU: nothing to upload).
    pub fn mip(&self, k: usize) -> &[f32] {
        if let Some(r) = &self.refined {
            return r.mips.get(k).map(|m| m.as_slice()).unwrap_or(&[]);
        }
        self.engine.solver().mip(k)
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
    /// Level-0 heights of the solver (the diffusion terrain), whatever is shown.
    pub fn solver_heights(&self) -> Result<Vec<f32>> {
        self.engine.solver().heights()
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
                Engine::Gpu(_) => GpuEngine::pick_level(&self.grid),
            };
            return Some(HeightField {
                side: self.grid.side(k),
                extent_m: [self.grid.extent_m[0] as f32, self.grid.extent_m[1] as f32],
                data: r.mips.get(k)?.clone(),
            });
        }
        if let Some(pick) = self.engine.solver().pick() {
            return Some(pick.clone());
        }
        if let Engine::Gpu(_) = self.engine {
            return None;
        }
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
        let uv: Vec<Option<[f32; 2]>> = points
            .iter()
            .map(|p| {
                (p[0].is_finite() && p[1].is_finite()).then(|| {
                    [
                        (p[0] / self.grid.extent_m[0]) as f32,
                        (p[1] / self.grid.extent_m[1]) as f32,
                    ]
                })
            })
            .collect();
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
            return Ok(uv
                .iter()
                .map(|p| p.map(|[u, v]| [sample_bilinear(m, side, u, v), self.detail_at(u, v, k)]))
                .collect());
        }
        match &self.engine {
            Engine::Cpu(_) => Ok(vec![None; points.len()]),
            Engine::Gpu(g) => g.probe(&self.grid, k, &uv, self.gpu_detail_for_probes(k)),
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_one_step_loop_settles_the_cpu_terrain_and_publishes_what_it_shows() {
        let mut sketch = terrasketch_sketch::benchmark_sketch();
        let mut t = Terrain::new(&sketch, 256, None).unwrap();
        assert_eq!(t.backend_name(), "cpu");
        let mut frames = 0;
        while !t.settled() && frames < 200 {
            t.step(&sketch, FrameBudget::Work(4.0));
            frames += 1;
        }
        assert!(t.settled() && t.converged(), "settled in {frames} frames");
        assert_eq!(t.finest_ready(), Some(0));
        assert!(t.residual().is_some_and(|r| r.is_finite()));
        let bounds = t
            .pyramid
            .as_ref()
            .expect("the min/max pyramid")
            .total_bounds();
        let heights = t.heights().unwrap();
        let lo = heights.iter().copied().fold(f32::INFINITY, f32::min);
        let hi = heights.iter().copied().fold(f32::NEG_INFINITY, f32::max);
        assert!(
            bounds[0] <= lo && hi <= bounds[1],
            "{bounds:?} holds {lo}..{hi}"
        );
        // An edit: the next frame runs (new version, work counted) and the terrain is no longer settled.
        let version = t.version;
        let before = sketch.clone();
        for p in &mut sketch.strokes[0].points {
            p[0] += 200.0;
        }
        t.update(t.diff_rows(&before, &sketch));
        t.step(&sketch, FrameBudget::Work(4.0));
        assert!(t.version > version);
        assert!(t.frame_work_units > 0.0);
        assert!(!t.settled());
    }
}
