//! What the interface's actions (and their shortcuts) do to the editor: tools, undo and redo, files
//! (open, save, export), stroke attributes, the solver backend, the realism pass.

use std::path::Path;

use super::doc::Document;
use super::files;
use super::state::{Editor, stroke_z_range};
use super::terrain::Terrain;
use super::tools::{self, Gesture};
use super::ui::{Action, PathKind};

impl Editor {
    /// Does what the interface (or a shortcut) asked.
    pub fn act(&mut self, action: Action) {
        let busy = !matches!(self.gesture, Gesture::Idle);
        match action {
            Action::Tool(t) => self.tool = t,
            Action::Undo | Action::Redo if busy => {}
            Action::Undo | Action::Redo => {
                self.commit_attributes();
                let old = if matches!(action, Action::Undo) {
                    self.doc.undo()
                } else {
                    self.doc.redo()
                };
                if let Some(old) = old {
                    let rows = self.terrain.diff_rows(&old, &self.doc.sketch);
                    self.resolve(rows);
                }
            }
            Action::Open(p) => self.open(&p),
            Action::Save => match self.doc.path.clone() {
                Some(p) => self.save_to(&p),
                None => self.ui.path_dialog = Some((PathKind::SaveAs, String::new())),
            },
            Action::SaveAs(p) => self.save_to(&p),
            Action::Export(p) => self.export(&p),
            Action::FrameAll => self
                .view
                .camera
                .frame_all(self.doc.sketch.extent_m, self.terrain.z_range()),
            Action::TopView => self.view.camera.top_view(),
            Action::Fly => self.view.camera.fly = !self.view.camera.fly,
            Action::Select(i) => {
                self.doc.selected = i.filter(|&i| i < self.doc.sketch.strokes.len())
            }
            Action::Delete(i) if !busy => {
                self.commit_attributes();
                let rows = tools::delete_stroke(&mut self.doc, &self.terrain, i);
                self.resolve(rows);
            }
            Action::Delete(_) => {}
            Action::Attributes(i, v) if !busy && i < self.doc.sketch.strokes.len() => {
                self.doc.begin_live_edit();
                let before = self.doc.sketch.clone();
                let s = &mut self.doc.sketch.strokes[i];
                s.slope_left_deg = v[0].clamp(0.0, 85.0);
                s.slope_right_deg = v[1].clamp(0.0, 85.0);
                s.width_m = v[2].max(1e-3);
                s.roughness = v[3].clamp(0.0, 1.0);
                s.height_tolerance_m = v[4].clamp(0.0, terrasketch_sketch::MAX_HEIGHT_TOLERANCE_M);
                let rows = self.terrain.diff_rows(&before, &self.doc.sketch);
                self.resolve(rows);
            }
            Action::Attributes(..) => {}
            Action::Shape(i, shape) if !busy => {
                self.commit_attributes();
                let rows = tools::set_shape(&mut self.doc, &self.terrain, i, shape);
                self.resolve(rows);
            }
            Action::Shape(..) => {}
            Action::Quit => self.done = true,
            Action::SaveAndQuit => {
                match self.doc.path.clone() {
                    Some(p) => self.save_to(&p),
                    None => self.ui.path_dialog = Some((PathKind::SaveAs, String::new())),
                }
                if !self.doc.dirty {
                    self.done = true;
                }
            }
            Action::Recover(p) => {
                self.open(&p);
                self.doc.path = None;
                self.doc.dirty = true;
            }
            Action::DiscardRecovery(p) => {
                let _ = std::fs::remove_file(p);
            }
            Action::Refine(seed, fine) => self.start_refine(seed, fine),
            Action::CancelRefine => match &self.refine.job {
                Some(job) => {
                    job.cancel();
                    self.ui.notice = "cancelling the refinement…".into();
                }
                None => self.ui.notice = "no refinement is running".into(),
            },
            Action::SolverGpu => match self.gfx.gpu.solver_context() {
                None => self.error(format!(
                    "the GPU solver cannot run on {}",
                    self.gfx.gpu.adapter_name
                )),
                Some(ctx) => {
                    match Terrain::new(&self.doc.sketch, self.terrain.grid.n, Some(&ctx)) {
                        Ok(t) => {
                            self.terrain = t;
                            self.overlay_rows = Some(0..self.terrain.grid.n);
                            self.ui.notice = "switched to the GPU solver".into();
                        }
                        Err(e) => self.error(format!("{e:#}; keeping the CPU solver")),
                    }
                }
            },
            Action::SolverCpu => {
                self.terrain.fall_back_to_cpu(String::new());
                // Asked for: a notice, not an error (`fallback` reports GPU failures).
                match self.terrain.fallback.take().filter(|m| !m.is_empty()) {
                    Some(why) => self.error(why),
                    None => self.ui.notice = "switched to the CPU solver".into(),
                }
            }
        }
    }

    /// Commits a pending live attribute edit as one undo step.
    pub fn commit_attributes(&mut self) {
        self.doc.commit_live_edit();
    }

    /// Re-solves warm after an edit of `rows`.
    pub fn resolve(&mut self, rows: std::ops::Range<usize>) {
        if rows.is_empty() {
            return;
        }
        self.overlay_rows = Some(match self.overlay_rows.take() {
            Some(o) => o.start.min(rows.start)..o.end.max(rows.end),
            None => rows.clone(),
        });
        self.terrain.update(rows);
    }

    /// Opens a sketch; on any error the current scene is left untouched.
    pub fn open(&mut self, path: &Path) {
        let files::Opened {
            sketch,
            refined: record,
            warnings,
        } = match files::open_sketch(path) {
            Ok(s) => s,
            Err(e) => return self.error(format!("{e:#}")),
        };
        if sketch.extent_m != self.doc.sketch.extent_m {
            match self.terrain.rebuilt(&sketch, self.terrain.grid.n) {
                Ok(t) => {
                    self.terrain = t;
                    self.gfx
                        .scene
                        .use_heightmap(&self.gfx.gpu.device, self.terrain.gpu_texture());
                }
                Err(e) => return self.error(format!("{e:#}")),
            }
            self.gfx.set_extent(sketch.extent_m);
        } else {
            self.terrain.restart();
        }
        self.gesture = Gesture::Idle;
        self.doc.drop_live_edit();
        let z = stroke_z_range(&sketch);
        self.view.camera.frame_all(sketch.extent_m, z);
        self.doc = Document::new(sketch, Some(path.to_path_buf()));
        self.overlay_rows = Some(0..self.terrain.grid.n);
        self.ui.notice = format!("opened {}", path.display());
        // A refinement of the previous document is of no use any more (dropping it cancels it).
        self.refine.reset();
        for w in warnings {
            self.warn(w);
        }
        if let Some(record) = record {
            self.restore_refined(record, path);
        }
    }

    /// Saves the sketch and, when a refined layer is shown, its heights beside it
    /// (`persist.rs`) and its record in the sketch. A failed heights write still saves the
    /// sketch, with a record to recompute from.
    pub(super) fn save_to(&mut self, path: &Path) {
        self.commit_attributes();
        let g = self.terrain.grid;
        let heights_file = super::persist::heights_path(path);
        let mut heights_warning = None;
        let record = match self.doc.shown_refined() {
            Some(r) => r.made.as_ref().map(|made| {
                let digest = match super::persist::write_heights(&heights_file, &g, &r.mips[0]) {
                    Ok(d) => Some(d),
                    Err(e) => {
                        heights_warning = Some(e);
                        None
                    }
                };
                super::persist::record(made, &self.doc.sketch, g.n, digest)
            }),
            // A refinement being made again from the opened file's record keeps that record.
            None => self
                .refine
                .job
                .as_ref()
                .filter(|j| j.sketch == self.doc.sketch)
                .and_then(|j| j.restore.clone())
                .map(|r| terrasketch_sketch::RefinedRecord {
                    heights_digest: None,
                    ..r
                }),
        };
        match files::save(&self.doc.sketch, record.as_ref(), path) {
            Ok(()) => {
                self.doc.path = Some(path.to_path_buf());
                self.doc.dirty = false;
                self.autosave.clear();
                let with_heights = record.as_ref().is_some_and(|r| r.heights_digest.is_some());
                self.ui.notice = match (&record, with_heights) {
                    (Some(_), true) => format!(
                        "saved {} with the refined terrain ({})",
                        path.display(),
                        heights_file.display()
                    ),
                    (Some(_), false) => {
                        format!("saved {} with its refinement record", path.display())
                    }
                    (None, _) => format!("saved {}", path.display()),
                };
                if record.is_none() {
                    // No refined layer: a heights file left by an earlier save is stale.
                    let _ = std::fs::remove_file(&heights_file);
                }
                if let Some(w) = heights_warning {
                    self.warn(format!(
                        "{w}; the sketch was saved with its refinement record (reopening recomputes it)"
                    ));
                }
            }
            Err(e) => self.error(format!("{e:#}")),
        }
    }

    /// Exports what is shown (the refined layer when it is) at the heightmap's resolution.
    pub(super) fn export(&mut self, path: &Path) {
        self.terrain.finish(&self.doc.sketch);
        // What is shown is exported: the refined layer when it is.
        self.sync_refined();
        let g = self.terrain.grid;
        let heights = match self.terrain.export_heights(&self.doc.sketch) {
            Ok(h) => h,
            Err(e) => return self.error(format!("cannot read the heights back: {e:#}")),
        };
        match files::export(path, g.n, &heights, g.cell_size_m()) {
            Ok(msg) => self.ui.notice = msg,
            Err(e) => self.error(format!("{e:#}")),
        }
    }
}
