//! The GPU solver as the editor steps it, on the editor's device (its height texture is drawn
//! directly), under the same follow rule as the CPU solver (`follow`; [`GpuLive`] is the GPU side of
//! it).

use anyhow::Result;
use terrasketch_multigrid::gpu::{GpuCounters, TexelSet};
use terrasketch_multigrid::gpu_solver::GpuSolver;
use terrasketch_multigrid::{Grid, Solver, SolverParams};
use terrasketch_sketch::Sketch;

use super::budget::Meter;
use super::engine::{AfterStep, MinMaxLevel, TerrainSolver, min_max_levels};
use super::follow::{Follower, FrameWork, LiveSolver, Took, Unit};
use super::heightfield::{Corners, HeightField, bilinear_corners, sample_bilinear};
use super::terrain_cpu::POLISH_TOLERANCE;

/// Largest side of the picking copy read back from the GPU (256^2 floats = 256 KB, read once the
/// terrain has settled, never while the pointer edits).
pub const PICK_MAX_SIDE: usize = 256;

/// FCG iterations of the idle refinement on the GPU (f32 round-off can stop short of 1e-6).
const GPU_POLISH_ITERS: u32 = 40;

/// FCG iterations the GPU queues in one frame at most. Nothing waits for them: the device runs
/// them after the frame's encoding, and their residual arrives with a later frame, so queuing
/// more would only run past convergence. Two keep what is shown coherent (one global correction
/// after each take) and converge a drag's small edits within a frame or two.
const GPU_ITERATIONS_PER_FRAME: u32 = 2;

/// The GPU solver under the follow rule: a take is `GpuSolver::take_queued` (rasterisation, field
/// solves, assembly, local relaxation, FCG start, queued without waiting for their reports), a
/// unit of work one queued FCG iteration. Residuals arrive a frame or so late (`GpuSolver::poll`);
/// a frame does not wait for the device (unless it is two takes behind, or every stroke lies
/// outside the map).
pub struct GpuLive {
    /// The solver.
    pub solver: GpuSolver,
    /// The idle refinement runs (its tolerance is `POLISH_TOLERANCE`).
    polishing: bool,
    /// FCG iterations of the idle refinement so far.
    polish_iters: u32,
    /// A warm take still owes its global correction (one FCG iteration, whatever the residual).
    owes_iteration: bool,
    /// The sketch last taken and whether cold (taken again when a field solve fell short).
    taken: Option<(Sketch, bool)>,
    /// Iterations queued in the current frame.
    queued_this_frame: u32,
}

impl GpuLive {
    fn target(&self) -> f32 {
        if self.polishing {
            POLISH_TOLERANCE
        } else {
            SolverParams::default().tolerance
        }
    }

    /// A new frame: iterations may be queued again.
    pub fn new_frame(&mut self) {
        self.queued_this_frame = 0;
    }
}

impl LiveSolver for GpuLive {
    fn cells(&self) -> usize {
        let n = self.solver.grid().n;
        n * n
    }

    fn take(&mut self, sketch: &Sketch, from: Option<&Sketch>) -> Result<(Took, Unit)> {
        let cold = from.is_none() || sketch.strokes.is_empty();
        let b = self.solver.take_queued(sketch, cold)?;
        self.owes_iteration = !cold;
        self.taken = Some((sketch.clone(), cold));
        let unit = Unit {
            height_wu: b.work_units,
            field_wu: b.field_work_units,
            ..Unit::default()
        };
        Ok((if cold { Took::Cold } else { Took::Warm }, unit))
    }

    fn advance(&mut self) -> Result<Unit> {
        let mut unit = Unit::default();
        let status = self.solver.poll()?;
        unit.field_wu = status.late_field_work_units;
        unit.height_wu = status.late_work_units - status.late_field_work_units;
        if status.retake
            && let Some((sketch, cold)) = self.taken.clone()
        {
            // A field solve needed more iterations than the take queued: the take again, with
            // them (the guess was raised).
            let b = self.solver.take_queued(&sketch, cold)?;
            unit.height_wu += b.work_units;
            unit.field_wu += b.field_work_units;
            self.owes_iteration = !cold;
        }
        if self.queued_this_frame >= GPU_ITERATIONS_PER_FRAME {
            unit.frame_full = true;
            return Ok(unit);
        }
        if self.polishing && self.polish_iters >= GPU_POLISH_ITERS {
            unit.converged = true;
            return Ok(unit);
        }
        if self.solver.residual() > self.target() || std::mem::take(&mut self.owes_iteration) {
            unit.height_wu += self.solver.queue_iterations(1)?;
            unit.vcycles = 1;
            unit.coherent = true;
            self.queued_this_frame += 1;
            self.polish_iters += self.polishing as u32;
        }
        unit.converged = self.solver.residual() <= self.target();
        Ok(unit)
    }

    fn converged(&self) -> bool {
        !self.owes_iteration && self.solver.residual() <= self.target()
    }

    fn level0_ready(&self) -> bool {
        true
    }

    fn begin_polish(&mut self) -> bool {
        self.polishing = true;
        self.polish_iters = 0;
        true
    }

    fn end_polish(&mut self) {
        self.polishing = false;
    }

    fn publish(&mut self) -> Result<()> {
        Ok(self.solver.publish_and_request_min_max()?)
    }
}

/// The GPU solver, its follow state and what the editor reads back from it.
pub struct GpuEngine {
    /// The solver under the follow rule.
    pub live: Follower<GpuLive>,
    /// The picking copy (`Terrain::field`), refreshed when the terrain settles.
    pub pick: Option<HeightField>,
    /// Version of the heights the picking copy was read at.
    pub pick_version: u64,
    /// The device counters at the start of the frame.
    pub counters_mark: GpuCounters,
}

impl GpuEngine {
    /// The engine around `solver` (nothing taken yet).
    pub fn new(solver: GpuSolver) -> GpuEngine {
        GpuEngine {
            counters_mark: solver.context().counters(),
            live: Follower::new(GpuLive {
                solver,
                polishing: false,
                polish_iters: 0,
                owes_iteration: false,
                taken: None,
                queued_this_frame: 0,
            }),
            pick: None,
            pick_version: u64::MAX,
        }
    }

    /// The solver.
    pub fn solver(&self) -> &GpuSolver {
        &self.live.solver.solver
    }

    /// Mip level of the picking copy (side <= `PICK_MAX_SIDE`).
    pub fn pick_level(grid: &Grid) -> usize {
        grid.n
            .trailing_zeros()
            .saturating_sub(PICK_MAX_SIDE.trailing_zeros()) as usize
    }

    /// Displayed heights at world-fraction points `uv` (None: skipped) on mip `k` as
    /// `[diffusion, detail]`, reading back the four texels of each (one wait); with `detail` (the
    /// amplitude texture and the noise of mip `k`) the amplitude's four texels are read too.
    pub fn probe(
        &self,
        grid: &Grid,
        k: usize,
        uv: &[Option<[f32; 2]>],
        detail: Option<(&wgpu::Texture, &[f32])>,
    ) -> Result<Vec<Option<[f32; 2]>>> {
        let side = grid.side(k);
        let live: Vec<(usize, [f32; 2], Corners)> = uv
            .iter()
            .enumerate()
            .filter_map(|(i, p)| p.map(|[u, v]| (i, [u, v], bilinear_corners(side, u, v))))
            .collect();
        let texels: Vec<[u32; 2]> = live
            .iter()
            .flat_map(|(_, _, c)| c.texels.iter().map(|t| [t[0] as u32, t[1] as u32]))
            .collect();
        // The amplitude as drawn, read with the heights (one wait).
        let amp_side = terrasketch_detail::amplitude_side(grid.n);
        let amp_corners: Vec<Corners> = live
            .iter()
            .map(|(_, [u, v], _)| bilinear_corners(amp_side, *u, *v))
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
        let read = self.solver().read_texels_with(k as u32, &texels, other)?;
        let mut out = vec![None; uv.len()];
        for ((i, _, c), h) in live.iter().zip(read[0].chunks_exact(4)) {
            out[*i] = Some([c.combine([h[0], h[1], h[2], h[3]]), 0.0]);
        }
        if let (Some((_, noise)), Some(amps)) = (detail, read.get(1)) {
            for (((i, [u, v], _), c), a) in live.iter().zip(&amp_corners).zip(amps.chunks_exact(4))
            {
                let a = c.combine([a[0], a[1], a[2], a[3]]);
                if let (Some(h), true) = (out[*i].as_mut(), a > 0.0) {
                    h[1] = a * sample_bilinear(noise, side, *u, *v);
                }
            }
        }
        Ok(out)
    }
}

impl TerrainSolver for GpuEngine {
    fn full_solver(&self) -> &dyn Solver {
        self.solver()
    }

    fn shown(&self) -> &dyn Solver {
        self.solver()
    }

    fn step(&mut self, sketch: &Sketch, meter: &mut Meter, edited: bool) -> Result<FrameWork> {
        self.live.solver.new_frame();
        if self.live.converged_for(sketch) {
            self.live.polish(meter)
        } else {
            self.live.follow(sketch, meter, !edited)
        }
    }

    fn restart(&mut self) {
        self.live.restart();
    }

    fn progress_ready(&self) -> bool {
        self.live.started()
    }

    fn converged_for(&self, sketch: &Sketch) -> bool {
        self.live.converged_for(sketch)
    }

    fn settled_for(&self, sketch: &Sketch) -> bool {
        self.live.converged_for(sketch) && self.live.polished()
    }

    fn shown_solver(&self) -> usize {
        0
    }

    fn finest_ready(&self) -> Option<u32> {
        self.live.started().then_some(0)
    }

    fn mip(&self, _k: usize) -> &[f32] {
        &[]
    }

    /// The pyramid of an earlier publish, when the device has delivered it (never waited for; the
    /// first one is, so that the quadtree has bounds at all).
    fn min_max(&mut self, _changed: bool, wanted: bool) -> Result<Option<Vec<MinMaxLevel>>> {
        let levels = match (self.solver().try_min_max()?, wanted) {
            (Some(l), _) => l,
            (None, true) => Solver::min_max(self.solver())?,
            (None, false) => return Ok(None),
        };
        Ok(Some(min_max_levels(levels)))
    }

    /// The picking copy: at the first heights, then each time the terrain settles again while no
    /// button is held.
    fn after_step(&mut self, end: &AfterStep) -> Result<()> {
        let refresh = end.settled && !end.pointer_held && self.pick_version != end.version;
        if self.pick.is_some() && !refresh {
            return Ok(());
        }
        let grid = *self.solver().grid();
        let k = GpuEngine::pick_level(&grid);
        let data = self.solver().read_mip(k)?;
        self.pick = Some(HeightField {
            side: grid.side(k),
            extent_m: [grid.extent_m[0] as f32, grid.extent_m[1] as f32],
            data,
        });
        self.pick_version = end.version;
        Ok(())
    }

    fn pick(&self) -> Option<&HeightField> {
        self.pick.as_ref()
    }

    fn take_counters(&mut self) -> GpuCounters {
        let now = self.solver().context().counters();
        let d = now.since(&self.counters_mark);
        self.counters_mark = now;
        d
    }
}

/// The editor's GPU engine without a window or a renderer, for `terrasketch bench drag`: a frame
/// is the solver's part of an editor frame (the follow rule's take and queued iterations, the
/// publish, the min/max request), run by the same code as the editor's.
pub struct HeadlessFrames {
    engine: GpuEngine,
}

impl HeadlessFrames {
    /// The engine around `solver`; its first frame takes cold.
    pub fn new(solver: GpuSolver) -> HeadlessFrames {
        HeadlessFrames {
            engine: GpuEngine::new(solver),
        }
    }

    /// One frame on `sketch` (`edited`: the sketch changed since the last frame) under a work
    /// budget too large to end a frame: on a real GPU encoding does not spend the frame's time
    /// budget, so the frame ends when its iterations are queued, and so it does here on any
    /// machine.
    pub fn frame(&mut self, sketch: &Sketch, edited: bool) -> Result<()> {
        let mut meter = Meter::new(super::budget::FrameBudget::Work(1e9));
        self.engine.step(sketch, &mut meter, edited)?;
        self.engine.min_max(true, false)?;
        Ok(())
    }

    /// True once converged on `sketch` at the normal tolerance.
    pub fn converged_for(&self, sketch: &Sketch) -> bool {
        self.engine.converged_for(sketch)
    }

    /// The solver.
    pub fn solver(&self) -> &GpuSolver {
        self.engine.solver()
    }

    /// The solver, taken out of the engine.
    pub fn into_solver(self) -> GpuSolver {
        self.engine.live.solver.solver
    }
}
