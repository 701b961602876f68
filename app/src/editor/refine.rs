//! The realism pass ("Refine") in the editor: the synthesis crate's `refine` run in a background
//! thread on the converged diffusion terrain, with the sketch's elevation constraints as hard
//! constraints, its roughness field and the shipped exemplar library (features cached on disk).
//!
//! The target is a cold CPU solve of the sketch at the editor's grid size (as `terrasketch refine`
//! does), not the live solver's heights, so the same sketch, size, exemplars and parameters give
//! the same bits: a saved refinement can be made again on reopen (`persist.rs`).
//!
//! The result is a [`Refined`] layer: level-0 heights, their display mips (same downsampling as
//! the solver's) and min/max pyramid. The document keeps it in its undo history; the terrain shows
//! it while the sketch is the one it was made for.

use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;

use terrasketch_multigrid::pyramid::{HardSummary, MINMAX_MAX_SIDE, display_downsample};
use terrasketch_multigrid::{ConstraintMaps, CpuSolver, Grid, SolverParams};
use terrasketch_quadtree::MinMaxPyramid;
use terrasketch_sketch::Sketch;
use terrasketch_synthesis::refine::field::{Field, upsample_smooth};
use terrasketch_synthesis::refine::{
    LevelView, RefineError, RefineParams, prepare_exemplars, refine_levels,
};
use terrasketch_synthesis::{load_exemplar_dir, shipped_exemplar_dir};

use super::persist::Provenance;
use crate::refine::{flip_rows, sketch_refine_input, square_cell_m};

/// A refined terrain for one sketch.
#[derive(Debug)]
pub struct Refined {
    /// The sketch it was made for (shown only while the document holds this sketch).
    pub sketch: Sketch,
    /// Display mips, `mips[0]` = level-0 heights, row 0 = south.
    pub mips: Vec<Vec<f32>>,
    /// Min/max pyramid of the refined heights (the quadtree's bounds).
    pub pyramid: MinMaxPyramid,
    /// Patches placed (feature + fill).
    pub patches: usize,
    /// Largest deviation from the hard elevation constraints, metres.
    pub max_error_m: f64,
    /// What made it (None for the coarse levels shown while a refinement runs).
    pub made: Option<Provenance>,
}

/// What the background thread needs.
pub struct RefineRequest {
    /// The sketch the heights belong to.
    pub sketch: Sketch,
    /// The grid.
    pub grid: Grid,
    /// The parameters (seed included).
    pub params: RefineParams,
    /// Only these exemplars of the shipped library, in this order (a saved refinement made
    /// again); None: all of them.
    pub exemplars: Option<Vec<String>>,
    /// Feature cache folder (None: no cache).
    pub cache_dir: Option<PathBuf>,
}

/// How a finished job ended.
pub enum JobEnd {
    /// A refined layer.
    Done(Box<Refined>),
    /// The cancel flag was raised.
    Cancelled,
    /// An error (message for the user).
    Failed(String),
}

/// A refinement running in a background thread.
pub struct RefineJob {
    /// The sketch it refines.
    pub sketch: Sketch,
    /// The opened file's record this job makes again (None: a new refinement).
    pub restore: Option<terrasketch_sketch::RefinedRecord>,
    cancel: Arc<AtomicBool>,
    progress: Arc<Mutex<(f32, String)>>,
    /// The latest finished pyramid level not yet picked up (display-ready).
    level: Arc<Mutex<Option<Arc<Refined>>>>,
    /// The latest level picked up.
    shown: Option<Arc<Refined>>,
    handle: Option<JoinHandle<JobEnd>>,
}

impl RefineJob {
    /// Starts `req` in a new thread.
    pub fn start(req: RefineRequest) -> std::io::Result<RefineJob> {
        let cancel = Arc::new(AtomicBool::new(false));
        let progress = Arc::new(Mutex::new((0.0, "starting".to_string())));
        let level = Arc::new(Mutex::new(None));
        let sketch = req.sketch.clone();
        let (c, p, l) = (cancel.clone(), progress.clone(), level.clone());
        let handle = std::thread::Builder::new()
            .name("terrasketch-refine".into())
            .spawn(move || run(req, &c, &p, &l))?;
        Ok(RefineJob {
            sketch,
            restore: None,
            cancel,
            progress,
            level,
            shown: None,
            handle: Some(handle),
        })
    }

    /// Asks the thread to stop (it ends at its next check).
    pub fn cancel(&self) {
        self.cancel.store(true, Ordering::Relaxed);
    }

    /// True once cancel was asked.
    pub fn cancelling(&self) -> bool {
        self.cancel.load(Ordering::Relaxed)
    }

    /// Fraction done (0..1) and the stage.
    pub fn progress(&self) -> (f32, String) {
        self.progress
            .lock()
            .map(|g| g.clone())
            .unwrap_or_else(|e| e.into_inner().clone())
    }

    /// The result once the thread has ended (None while it runs).
    /// The latest finished pyramid level (the editor shows it while the finer ones run).
    pub fn latest_level(&mut self) -> Option<Arc<Refined>> {
        if let Some(new) = self.level.lock().ok().and_then(|mut g| g.take()) {
            self.shown = Some(new);
        }
        self.shown.clone()
    }

    pub fn poll(&mut self) -> Option<JobEnd> {
        if !self.handle.as_ref()?.is_finished() {
            return None;
        }
        let h = self.handle.take()?;
        Some(match h.join() {
            Ok(end) => end,
            Err(_) => JobEnd::Failed("the refinement thread panicked".into()),
        })
    }
}

impl Drop for RefineJob {
    fn drop(&mut self) {
        // A job left running (editor closing): stop it; the thread is detached.
        self.cancel();
    }
}

fn run(
    req: RefineRequest,
    cancel: &AtomicBool,
    progress: &Mutex<(f32, String)>,
    level: &Mutex<Option<Arc<Refined>>>,
) -> JobEnd {
    let set = |f: f32, what: &str| {
        if let Ok(mut g) = progress.lock() {
            *g = (f.clamp(0.0, 1.0), what.to_string());
        }
    };
    let shown = |r: Refined| {
        if let Ok(mut g) = level.lock() {
            *g = Some(Arc::new(r));
        }
    };
    match work(&req, cancel, &set, &shown) {
        Ok(r) => JobEnd::Done(Box::new(r)),
        Err(RefineError::Cancelled) => JobEnd::Cancelled,
        Err(e) => JobEnd::Failed(format!("refinement failed: {e}")),
    }
}

fn work(
    req: &RefineRequest,
    cancel: &AtomicBool,
    set: &(dyn Fn(f32, &str) + Sync),
    shown: &dyn Fn(Refined),
) -> Result<Refined, RefineError> {
    let g = req.grid;
    let n = g.n;
    let cx = square_cell_m(&req.sketch, &g).map_err(RefineError::BadInput)?;
    set(0.0, "loading exemplars");
    let (mut dems, failures) = load_exemplar_dir(&shipped_exemplar_dir());
    for (f, e) in failures {
        eprintln!(
            "terrasketch: warning: exemplar {} skipped: {e}",
            f.display()
        );
    }
    if let Some(names) = &req.exemplars {
        let mut picked = Vec::with_capacity(names.len());
        for name in names {
            let i = dems.iter().position(|d| &d.name == name).ok_or_else(|| {
                RefineError::BadInput(format!(
                    "exemplar {name:?} of the saved refinement is not in the library"
                ))
            })?;
            picked.push(dems.swap_remove(i));
        }
        dems = picked;
    }
    let names: Vec<String> = dems.iter().map(|d| d.name.clone()).collect();
    if cancel.load(Ordering::Relaxed) {
        return Err(RefineError::Cancelled);
    }
    let prog = |f: f32, what: &str| set(0.2 * f, what);
    let prepared = prepare_exemplars(&dems, cx, req.cache_dir.as_deref(), &prog)?;
    for e in &prepared {
        if let Some(w) = &e.cache_warning {
            eprintln!("terrasketch: warning: {}: {w}", e.name);
        }
    }
    if cancel.load(Ordering::Relaxed) {
        return Err(RefineError::Cancelled);
    }
    // The target: a cold CPU solve (deterministic), heights and roughness.
    set(0.2, "diffusion solve");
    let mut s = CpuSolver::new(g, SolverParams::default())
        .map_err(|e| RefineError::BadInput(format!("diffusion solve: {e}")))?;
    s.set_sketch(&req.sketch);
    s.solve();
    if cancel.load(Ordering::Relaxed) {
        return Err(RefineError::Cancelled);
    }
    // The synthesis crate's rasters are row 0 = north; the solver's row 0 = south.
    let maps = ConstraintMaps::rasterize(&req.sketch, &g);
    let roughness = s.roughness().to_vec();
    let input = sketch_refine_input(&req.sketch, &g, &maps, s.heights(), Some(&roughness))
        .map_err(RefineError::BadInput)?;
    drop(s);
    let params = req.params.clone();
    let prog = |f: f32, what: &str| set(0.2 + 0.75 * f, what);
    // Every level but the finest is brought up to the grid (cubic B-spline) and shown.
    let on_level = |l: &LevelView| {
        let side = l.level.side;
        if side >= n || side == 0 || !n.is_multiple_of(side) {
            return;
        }
        let up = upsample_smooth(&Field::new(side, side, l.heights.to_vec()), n / side, n, n);
        let mips = display_mips(&g, &maps, flip_rows(&up.v, n));
        if let Ok(pyramid) = MinMaxPyramid::from_heights(n, &mips[0], MINMAX_MAX_SIDE.min(n)) {
            shown(Refined {
                sketch: req.sketch.clone(),
                mips,
                pyramid,
                patches: 0,
                max_error_m: f64::NAN,
                made: None,
            });
        }
    };
    let out = refine_levels(&input, &prepared, &params, &prog, &on_level, cancel)?;
    set(0.96, "display mips");
    let h0 = flip_rows(&out.heights.data, n);
    let mips = display_mips(&g, &maps, h0);
    let pyramid = MinMaxPyramid::from_heights(n, &mips[0], MINMAX_MAX_SIDE.min(n))
        .map_err(|e| RefineError::BadInput(format!("min/max pyramid: {e}")))?;
    set(1.0, "done");
    Ok(Refined {
        sketch: req.sketch.clone(),
        mips,
        pyramid,
        patches: out.stats.patches_feature + out.stats.patches_fill,
        max_error_m: out.stats.constraint_max_error_m,
        made: Some(Provenance {
            exemplars: names,
            params,
        }),
    })
}

/// The display mip chain of level-0 heights `h0` (row 0 south): the solver's downsampling (cells
/// holding a hard constraint show its mean, see `multigrid::pyramid`).
pub fn display_mips(g: &Grid, maps: &ConstraintMaps, h0: Vec<f32>) -> Vec<Vec<f32>> {
    let summary = HardSummary::new(g.n, &maps.elev_weight, &maps.elev_value);
    let mut mips = vec![h0];
    for k in 1..g.mip_levels() {
        let fine = &mips[k - 1];
        let side = g.side(k);
        let next = match summary.levels.get(k - 1).filter(|l| l.len() == side * side) {
            Some(s) => display_downsample(fine, s),
            None => {
                let nf = 2 * side;
                (0..side * side)
                    .map(|c| {
                        let b = 2 * (c / side) * nf + 2 * (c % side);
                        0.25 * (fine[b] + fine[b + 1] + fine[b + nf] + fine[b + nf + 1])
                    })
                    .collect()
            }
        };
        mips.push(next);
    }
    mips
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn display_mips_average_unconstrained_cells() {
        let g = Grid::new(64, [800.0, 800.0]).expect("grid");
        let maps = ConstraintMaps::rasterize(&Sketch::empty([800.0, 800.0], 0.0), &g);
        let h0: Vec<f32> = (0..64 * 64).map(|i| (i % 97) as f32).collect();
        let m = display_mips(&g, &maps, h0.clone());
        assert_eq!(m.len(), g.mip_levels());
        assert_eq!(m[1].len(), 32 * 32);
        assert_eq!(m.last().map(|l| l.len()), Some(1));
        // Cell (3, 2) of level 1 averages texels (6, 4), (7, 4), (6, 5), (7, 5).
        let want = 0.25 * (h0[4 * 64 + 6] + h0[4 * 64 + 7] + h0[5 * 64 + 6] + h0[5 * 64 + 7]);
        assert_eq!(m[1][2 * 32 + 3], want);
    }

    #[test]
    fn flip_rows_is_an_involution() {
        let v: Vec<f32> = (0..16).map(|i| i as f32).collect();
        let f = flip_rows(&v, 4);
        assert_eq!(&f[0..4], &[12.0, 13.0, 14.0, 15.0]);
        assert_eq!(flip_rows(&f, 4), v);
    }
}
