//! The realism pass as the editor runs it: a background job on the current sketch, its progress
//! for the interface and the log, its result as an undoable refined layer, and the refined layer
//! saved beside a sketch (loaded, or made again from its record, when the sketch is opened).

use std::path::Path;
use std::sync::Arc;

use super::refine::{RefineJob, Refined};
use super::session::RefineStatus;
use super::state::Editor;
use super::tools::Gesture;

/// The realism pass's job and what the editor shows of it.
#[derive(Default)]
pub struct Refinement {
    /// The job running in the background.
    pub job: Option<RefineJob>,
    /// Its state for the log and the interface.
    pub status: RefineStatus,
    /// Where the shown refined layer came from: `refined` (this session), `loaded` (the heights
    /// file saved beside the sketch), `recomputing` / `recomputed` (from the sketch's record).
    pub origin: Option<&'static str>,
}

impl Refinement {
    /// A new document: a running job is of no use any more (dropping it cancels it).
    pub fn reset(&mut self) {
        *self = Refinement::default();
    }

    /// True while a job runs.
    pub fn running(&self) -> bool {
        self.job.is_some()
    }
}

impl Editor {
    /// Makes the terrain show the document's refined layer if it belongs to the current sketch.
    pub fn sync_refined(&mut self) {
        // While a refinement runs, its latest finished level is shown (if the sketch is still
        // the one being refined).
        let level = self.refine.job.as_mut().and_then(|j| j.latest_level());
        match level.filter(|l| l.sketch == self.doc.sketch) {
            Some(l) => self.terrain.show_refined(Some(&l)),
            None => self.terrain.show_refined(self.doc.shown_refined()),
        }
    }

    /// Starts the realism pass on the current sketch (default parameters, the whole library).
    pub(super) fn start_refine(&mut self, seed: u64, fine_detail: f32) {
        let params = terrasketch_synthesis::refine::RefineParams {
            seed,
            fine_detail: if fine_detail.is_finite() {
                fine_detail.clamp(0.0, terrasketch_synthesis::refine::MAX_FINE_DETAIL)
            } else {
                0.0
            },
            ..Default::default()
        };
        self.start_refine_job(params, None, None);
    }

    /// Starts a refinement of the current sketch in the background; `restore`: the opened file's
    /// record it makes again (shown without an undo step).
    fn start_refine_job(
        &mut self,
        params: terrasketch_synthesis::refine::RefineParams,
        exemplars: Option<Vec<String>>,
        restore: Option<terrasketch_sketch::RefinedRecord>,
    ) {
        if self.refine.job.is_some() {
            self.ui.notice = "a refinement is already running".into();
            return;
        }
        if !matches!(self.gesture, Gesture::Idle) {
            self.ui.notice = "finish the stroke edit first".into();
            return;
        }
        self.commit_attributes();
        // The thread solves the sketch itself (a cold CPU solve: the same bits every time).
        let req = super::refine::RefineRequest {
            sketch: self.doc.sketch.clone(),
            grid: self.terrain.grid,
            params,
            exemplars,
            cache_dir: crate::refine::default_cache_dir(),
        };
        match RefineJob::start(req) {
            Ok(mut job) => {
                job.restore = restore;
                self.refine.job = Some(job);
                self.refine.status = RefineStatus {
                    state: "running",
                    stage: "starting".into(),
                    ..Default::default()
                };
                self.ui.notice = "refining…".into();
            }
            Err(e) => self.error(format!("cannot start the refinement thread: {e}")),
        }
    }

    /// Picks up the realism pass's progress or result (once per frame).
    pub fn poll_refine(&mut self) {
        use super::refine::JobEnd;
        let Some(job) = self.refine.job.as_mut() else {
            return;
        };
        let Some(end) = job.poll() else {
            let (f, stage) = job.progress();
            self.refine.status.state = "running";
            self.refine.status.progress = f;
            self.refine.status.stage = if job.cancelling() {
                "cancelling".into()
            } else {
                stage
            };
            return;
        };
        let (job_sketch, restore) = match self.refine.job.take() {
            Some(mut j) => (Some(j.sketch.clone()), j.restore.take()),
            None => (None, None),
        };
        let st = &mut self.refine.status;
        st.progress = 1.0;
        match end {
            JobEnd::Done(r)
                if restore.is_some() && job_sketch.as_ref() == Some(&self.doc.sketch) =>
            {
                st.state = "done";
                st.stage = "done".into();
                st.patches = Some(r.patches);
                st.max_error_m = Some(r.max_error_m);
                self.ui.notice = format!(
                    "refined terrain recomputed from the saved record (seed {})",
                    r.made.as_ref().map_or(0, |m| m.params.seed)
                );
                // The opened document's layer: no undo step, nothing unsaved.
                self.doc.refined = Some(Arc::from(r));
                self.refine.origin = Some("recomputed");
            }
            JobEnd::Done(r) if job_sketch.as_ref() == Some(&self.doc.sketch) => {
                self.refine.origin = Some("refined");
                st.state = "done";
                st.stage = "done".into();
                st.patches = Some(r.patches);
                st.max_error_m = Some(r.max_error_m);
                self.ui.notice = format!(
                    "refined ({} patches, max constraint error {:.3} m)",
                    r.patches, r.max_error_m
                );
                self.doc.apply_refined(Arc::from(r));
            }
            JobEnd::Done(_) => {
                st.state = "discarded";
                st.stage = "discarded".into();
                self.ui.notice =
                    "refinement discarded: the sketch changed while it ran (refine again)".into();
            }
            JobEnd::Cancelled => {
                st.state = "cancelled";
                st.stage = "cancelled".into();
                self.ui.notice = "refinement cancelled".into();
            }
            JobEnd::Failed(msg) => {
                st.state = "failed";
                st.stage = "failed".into();
                self.error(msg);
            }
        }
        if self.refine.origin == Some("recomputing") {
            self.refine.origin = None;
        }
    }

    /// Shows the refined layer recorded in an opened sketch: the saved heights file when it
    /// matches the record and the sketch, else a background recomputation from the record.
    pub(super) fn restore_refined(
        &mut self,
        record: terrasketch_sketch::RefinedRecord,
        path: &Path,
    ) {
        use super::persist;
        let params = match persist::params_from_record(record.seed, &record.params) {
            Ok(p) => p,
            Err(e) => {
                return self.warn(format!(
                    "the refined-terrain record is ignored ({e}); the sketch opens without it"
                ));
            }
        };
        let g = self.terrain.grid;
        let file = persist::heights_path(path);
        match persist::load_heights(&file, &record, &self.doc.sketch, &g) {
            Ok(h0) => {
                let maps = terrasketch_multigrid::ConstraintMaps::rasterize(&self.doc.sketch, &g);
                let mips = super::refine::display_mips(&g, &maps, h0);
                let pyramid = match terrasketch_quadtree::MinMaxPyramid::from_heights(
                    g.n,
                    &mips[0],
                    terrasketch_multigrid::pyramid::MINMAX_MAX_SIDE.min(g.n),
                ) {
                    Ok(p) => p,
                    Err(e) => return self.warn(format!("refined heights not shown: {e}")),
                };
                self.doc.refined = Some(Arc::new(Refined {
                    sketch: self.doc.sketch.clone(),
                    mips,
                    pyramid,
                    patches: 0,
                    max_error_m: f64::NAN,
                    made: Some(persist::Provenance {
                        exemplars: record.exemplars,
                        params,
                    }),
                }));
                self.refine.origin = Some("loaded");
                self.ui.notice = format!("refined terrain loaded from {}", file.display());
            }
            Err(why) => {
                let seed = record.seed;
                self.start_refine_job(params, Some(record.exemplars.clone()), Some(record));
                if self.refine.job.is_some() {
                    self.refine.origin = Some("recomputing");
                    self.ui.notice = format!(
                        "refined terrain not loaded ({why}): recomputing it from the saved record (seed {seed})"
                    );
                }
            }
        }
    }
}
