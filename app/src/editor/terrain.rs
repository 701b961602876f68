//! The terrain as the editor sees it: the CPU solver stepped within a frame budget, the min/max pyramid
//! for the quadtree, CPU height sampling (probes, picking) that matches the vertex shader, and the
//! row-level change tracking that decides what is uploaded to the heightmap texture.

use std::ops::Range;
use std::time::Duration;

use anyhow::{Context, Result};
use glam::Vec3;
use terrasketch_multigrid::{Budget, ConstraintMaps, CpuSolver, Grid, Progress, SolverParams};
use terrasketch_quadtree::MinMaxPyramid;
use terrasketch_sketch::Sketch;

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

/// Bilinear sample of a `side x side` grid at `(u, v)` in extent fractions, clamped at the borders.
pub fn sample_bilinear(data: &[f32], side: usize, u: f32, v: f32) -> f32 {
    let s = side as f32;
    let px = (u * s - 0.5).clamp(0.0, s - 1.0);
    let py = (v * s - 0.5).clamp(0.0, s - 1.0);
    let (x0, y0) = (px.floor() as usize, py.floor() as usize);
    let (x1, y1) = ((x0 + 1).min(side - 1), (y0 + 1).min(side - 1));
    let (fx, fy) = (px - x0 as f32, py - y0 as f32);
    let h = |x: usize, y: usize| data[y * side + x];
    let south = h(x0, y0) * (1.0 - fx) + h(x1, y0) * fx;
    let north = h(x0, y1) * (1.0 - fx) + h(x1, y1) * fx;
    south * (1.0 - fy) + north * fy
}

/// The solver and what the renderer needs from it.
pub struct Terrain {
    /// The grid.
    pub grid: Grid,
    solver: CpuSolver,
    /// Progress of the last step that ran.
    pub last: Progress,
    /// Work units of this frame's step (0 if none ran).
    pub frame_work_units: f64,
    /// The quadtree's bounds (from the solver's min/max pyramid), once a mip is ready.
    pub pyramid: Option<MinMaxPyramid>,
    /// Bumped whenever the published heights may have changed.
    pub version: u64,
    /// What the texture holds, per mip level (empty until first uploaded).
    shadow: Vec<Vec<f32>>,
    /// The solver's sketch has no stroke (its next solve is cold: restart it rather than warm-update).
    empty: bool,
    /// After convergence at the normal tolerance the solver keeps refining to `POLISH_TOLERANCE`
    /// while idle, so that two converged states of the same sketch (before an edit, after its undo)
    /// agree to round-off; true once that is done.
    polished: bool,
    /// Rows edited since the solver last took the sketch (edits are coalesced, see `update`).
    pending: Option<Range<usize>>,
    /// Height work done since the solver last took an edit.
    height_wu_since_update: f64,
    /// The solver's last step reported convergence (for the sketch it has).
    solver_done: bool,
    /// An edit arrived since the last step (the pointer is still moving).
    edited: bool,
}

/// Height work (FMG levels and FCG iterations, level-0 units) per frame, and between two edits handed
/// to the solver, before it is given the next one.
const MIN_HEIGHT_WU: f64 = 3.0;

/// Tolerance of the idle refinement (see `Terrain::polished`).
const POLISH_TOLERANCE: f32 = 1e-6;

impl Terrain {
    /// A solver of side `n` for `sketch`, not yet stepped.
    pub fn new(sketch: &Sketch, n: usize) -> Result<Terrain> {
        let grid = Grid::new(n, sketch.extent_m).context("cannot make the terrain grid")?;
        let mut solver = CpuSolver::new(grid, SolverParams::default())?;
        solver.set_sketch(sketch);
        Ok(Terrain {
            grid,
            solver,
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
            pending: None,
            height_wu_since_update: 0.0,
            solver_done: false,
            edited: false,
        })
    }

    /// Replaces the whole sketch (cold solve).
    pub fn set_sketch(&mut self, sketch: &Sketch) {
        self.normal_tolerance();
        self.solver.set_sketch(sketch);
        self.empty = sketch.strokes.is_empty();
        self.last.converged = false;
        self.pending = None;
        self.height_wu_since_update = 0.0;
        self.solver_done = false;
    }

    fn normal_tolerance(&mut self) {
        if self.polished || self.solver.params().tolerance != SolverParams::default().tolerance {
            self.solver.set_params(SolverParams::default());
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
        self.pending = Some(match self.pending.take() {
            Some(o) => o.start.min(rows.start)..o.end.max(rows.end),
            None => rows,
        });
        self.last.converged = false;
    }

    fn apply_pending(&mut self, sketch: &Sketch) {
        let ready = self.solver_done || self.height_wu_since_update >= MIN_HEIGHT_WU;
        if !ready {
            return;
        }
        if let Some(rows) = self.pending.take() {
            self.normal_tolerance();
            self.solver.update_sketch(sketch, rows);
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
    /// per frame.
    pub fn step(&mut self, sketch: &Sketch, budget: Duration) {
        self.frame_work_units = 0.0;
        self.apply_pending(sketch);
        if self.last.converged {
            if self.polished || self.solver.finest_ready_level() != Some(0) {
                return;
            }
            let params = SolverParams {
                tolerance: POLISH_TOLERANCE,
                ..SolverParams::default()
            };
            if self.solver.params().tolerance != POLISH_TOLERANCE {
                self.solver.set_params(params);
            }
            let p = self.solver.step(Budget::Time(budget));
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
        let mut p = self.solver.step(Budget::Time(budget));
        let mut height_wu = p.work_units;
        self.frame_work_units = p.work_units + p.field_work_units;
        while !p.converged && (settling || height_wu < MIN_HEIGHT_WU) && start.elapsed() < cap {
            p = self.solver.step(Budget::WorkUnits(0.25));
            height_wu += p.work_units;
            self.frame_work_units += p.work_units + p.field_work_units;
        }
        self.height_wu_since_update += height_wu;
        self.solver_done = p.converged;
        self.last = p;
        self.last.converged = p.converged && self.pending.is_none();
        self.version += 1;
        self.refresh_pyramid();
    }

    fn refresh_pyramid(&mut self) {
        let levels: Vec<(usize, Vec<[f32; 2]>)> = self
            .solver
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
        while !self.settled() {
            self.step(sketch, Duration::from_secs(3600));
        }
    }

    /// True when the heights meet the tolerance for the current sketch.
    pub fn converged(&self) -> bool {
        self.last.converged
    }

    /// True when, after converging, the idle refinement has finished too (nothing left to do).
    pub fn settled(&self) -> bool {
        self.last.converged && (self.polished || self.solver.finest_ready_level() != Some(0))
    }

    /// Finest mip the solver has ready.
    pub fn finest_ready(&self) -> Option<u32> {
        self.solver.finest_ready_level()
    }

    /// Mip `k` of the heights (row 0 south).
    pub fn mip(&self, k: usize) -> &[f32] {
        self.solver.mip(k)
    }

    /// Level-0 heights.
    pub fn heights(&self) -> &[f32] {
        self.solver.heights()
    }

    /// Level-0 elevation-constraint weights (the constraint overlay).
    pub fn constraint_weights(&self) -> &[f32] {
        &self.solver.constraints().elev_weight
    }

    /// Residual of the last step (None before level 0 exists).
    pub fn residual(&self) -> Option<f32> {
        self.last.residual.is_finite().then_some(self.last.residual)
    }

    /// A copy of the finest ready mip (None before any).
    pub fn field(&self) -> Option<HeightField> {
        let k = self.finest_ready()? as usize;
        Some(HeightField {
            side: self.grid.side(k),
            extent_m: [self.grid.extent_m[0] as f32, self.grid.extent_m[1] as f32],
            data: self.mip(k).to_vec(),
        })
    }

    /// Displayed height at world `(x, y)`: bilinear on the finest ready mip (None before any).
    pub fn height_at(&self, x_m: f64, y_m: f64) -> Option<f32> {
        let k = self.finest_ready()? as usize;
        let u = (x_m / self.grid.extent_m[0]) as f32;
        let v = (y_m / self.grid.extent_m[1]) as f32;
        Some(sample_bilinear(self.mip(k), self.grid.side(k), u, v))
    }

    /// Lowest and highest height (from the pyramid), or `[0, 0]`.
    pub fn z_range(&self) -> [f32; 2] {
        self.pyramid
            .as_ref()
            .map(|p| p.total_bounds())
            .unwrap_or([0.0, 0.0])
    }

    /// Rows of mip `k` that differ from what the texture holds, updating the shadow copy; `None` if
    /// nothing changed. The first call for a level returns all rows.
    pub fn take_changed_rows(&mut self, k: usize) -> Option<Range<usize>> {
        let side = self.grid.side(k);
        let data = self.solver.mip(k);
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
