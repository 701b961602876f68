//! The document being edited: the sketch, its file, unsaved state, selection and undo history.
//!
//! Strokes are vectors, so every edit is stored as the whole previous sketch (a few KB); undo swaps
//! sketches and the solver re-solves warm from the rows that differ.

use std::path::PathBuf;
use std::sync::Arc;

use terrasketch_sketch::Sketch;

use super::refine::Refined;

/// One undo step: the sketch, the selection and the refined layer shown with it.
type Step = (Sketch, Option<usize>, Option<Arc<Refined>>);

/// Undo steps kept.
const MAX_UNDO: usize = 200;

/// The edited document.
pub struct Document {
    /// The sketch.
    pub sketch: Sketch,
    /// Where it was opened from / saved to.
    pub path: Option<PathBuf>,
    /// Unsaved changes.
    pub dirty: bool,
    /// Selected stroke.
    pub selected: Option<usize>,
    /// The refined terrain (realism pass) shown for this sketch; dropped by any stroke edit.
    pub refined: Option<Arc<Refined>>,
    /// The sketch before a live attribute edit (a slider being dragged): committed as one undo
    /// step when it is let go.
    live_edit: Option<Sketch>,
    undo: Vec<Step>,
    redo: Vec<Step>,
}

impl Document {
    /// A document for `sketch`.
    pub fn new(sketch: Sketch, path: Option<PathBuf>) -> Document {
        Document {
            sketch,
            path,
            dirty: false,
            selected: None,
            refined: None,
            live_edit: None,
            undo: Vec::new(),
            redo: Vec::new(),
        }
    }

    /// Records an edit: `before` is the sketch as it was before it (the current sketch is the result).
    /// Does nothing if the sketch did not change. A stroke edit drops the refined layer (undo brings
    /// it back with the sketch it belongs to).
    pub fn commit(&mut self, before: Sketch) {
        if before == self.sketch {
            return;
        }
        let refined = self.refined.take();
        self.push_undo((before, self.selected, refined));
        self.dirty = true;
    }

    /// A live attribute edit goes on: the sketch before its first change is kept for the undo step.
    pub fn begin_live_edit(&mut self) {
        if self.live_edit.is_none() {
            self.live_edit = Some(self.sketch.clone());
        }
    }

    /// True while a live attribute edit is pending.
    pub fn live_edit_pending(&self) -> bool {
        self.live_edit.is_some()
    }

    /// Commits a pending live attribute edit as one undo step.
    pub fn commit_live_edit(&mut self) {
        if let Some(before) = self.live_edit.take() {
            self.commit(before);
        }
    }

    /// Forgets a pending live attribute edit (the document is replaced).
    pub fn drop_live_edit(&mut self) {
        self.live_edit = None;
    }

    fn push_undo(&mut self, step: Step) {
        self.undo.push(step);
        if self.undo.len() > MAX_UNDO {
            self.undo.remove(0);
        }
        self.redo.clear();
    }

    /// Shows a refined layer for the current sketch, as one undoable step (the sketch is
    /// unchanged; the layer's record is saved with it, so the document has unsaved changes).
    pub fn apply_refined(&mut self, r: Arc<Refined>) {
        let before = (self.sketch.clone(), self.selected, self.refined.take());
        self.push_undo(before);
        self.refined = Some(r);
        self.dirty = true;
    }

    /// The refined layer when it belongs to the current sketch (during a stroke edit it does not).
    pub fn shown_refined(&self) -> Option<&Arc<Refined>> {
        self.refined.as_ref().filter(|r| r.sketch == self.sketch)
    }

    /// Steps back; returns the sketch that was current (to diff rows against) or `None`.
    pub fn undo(&mut self) -> Option<Sketch> {
        let (prev, sel, refined) = self.undo.pop()?;
        let cur = std::mem::replace(&mut self.sketch, prev);
        let cur_refined = std::mem::replace(&mut self.refined, refined);
        self.dirty |= cur != self.sketch || !same_layer(&cur_refined, &self.refined);
        self.redo.push((cur.clone(), self.selected, cur_refined));
        self.selected = sel.filter(|&i| i < self.sketch.strokes.len());
        Some(cur)
    }

    /// Steps forward; returns the sketch that was current or `None`.
    pub fn redo(&mut self) -> Option<Sketch> {
        let (next, sel, refined) = self.redo.pop()?;
        let cur = std::mem::replace(&mut self.sketch, next);
        let cur_refined = std::mem::replace(&mut self.refined, refined);
        self.dirty |= cur != self.sketch || !same_layer(&cur_refined, &self.refined);
        self.undo.push((cur.clone(), self.selected, cur_refined));
        self.selected = sel.filter(|&i| i < self.sketch.strokes.len());
        Some(cur)
    }

    /// Undo steps available.
    pub fn undo_depth(&self) -> usize {
        self.undo.len()
    }

    /// Redo steps available.
    pub fn redo_depth(&self) -> usize {
        self.redo.len()
    }

    /// Display name (file name or "untitled").
    pub fn title(&self) -> String {
        let name = self
            .path
            .as_ref()
            .and_then(|p| p.file_name())
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_else(|| "untitled".to_string());
        if self.dirty {
            format!("{name} *")
        } else {
            name
        }
    }
}

/// True when both hold the same refined layer (or none): what a save writes is unchanged.
fn same_layer(a: &Option<Arc<Refined>>, b: &Option<Arc<Refined>>) -> bool {
    match (a, b) {
        (Some(a), Some(b)) => Arc::ptr_eq(a, b),
        (None, None) => true,
        _ => false,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use terrasketch_sketch::{Stroke, StrokeKind};

    #[test]
    fn undo_redo_round_trip() {
        let mut d = Document::new(Sketch::empty([100.0, 100.0], 0.0), None);
        let before = d.sketch.clone();
        d.sketch.strokes.push(Stroke::new(
            StrokeKind::Ridge,
            vec![[0.0, 0.0, 1.0], [10.0, 0.0, 1.0]],
        ));
        d.commit(before.clone());
        let after = d.sketch.clone();
        assert!(d.undo().is_some());
        assert_eq!(d.sketch, before);
        assert!(d.redo().is_some());
        assert_eq!(d.sketch, after);
        assert!(d.redo().is_none());
    }

    fn layer(sketch: &Sketch) -> Arc<Refined> {
        let h = vec![1.0f32; 16];
        Arc::new(Refined {
            sketch: sketch.clone(),
            pyramid: terrasketch_quadtree::MinMaxPyramid::from_heights(4, &h, 4).unwrap(),
            mips: vec![h],
            patches: 1,
            max_error_m: 0.0,
            made: None,
        })
    }

    #[test]
    fn refined_layer_is_undoable_and_dropped_by_stroke_edits() {
        let mut d = Document::new(Sketch::empty([100.0, 100.0], 0.0), None);
        let r = layer(&d.sketch);
        d.apply_refined(r.clone());
        assert!(d.shown_refined().is_some_and(|s| Arc::ptr_eq(s, &r)));
        assert_eq!(d.undo_depth(), 1);
        // The layer is saved with the sketch: applying it is an unsaved change.
        assert!(d.dirty);
        d.dirty = false;
        // Undo: the diffusion terrain (no layer), same sketch; redo: the layer again. Each
        // changes what a save writes.
        d.undo().unwrap();
        assert!(d.shown_refined().is_none());
        assert!(d.dirty, "the saved refined record changes");
        d.redo().unwrap();
        assert!(d.shown_refined().is_some_and(|s| Arc::ptr_eq(s, &r)));
        // While a stroke is being drawn the layer no longer belongs to the sketch.
        let before = d.sketch.clone();
        d.sketch.strokes.push(Stroke::new(
            StrokeKind::Valley,
            vec![[0.0, 0.0, 1.0], [10.0, 0.0, 1.0]],
        ));
        assert!(d.shown_refined().is_none());
        d.commit(before);
        assert!(d.refined.is_none(), "a stroke edit drops the layer");
        assert_eq!(d.undo_depth(), 2);
        // Undoing the edit brings the layer back with its sketch.
        d.undo().unwrap();
        assert!(d.shown_refined().is_some_and(|s| Arc::ptr_eq(s, &r)));
        d.redo().unwrap();
        assert!(d.shown_refined().is_none());
    }
}
