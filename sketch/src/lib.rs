//! The terrasketch sketch document: strokes with heights and slopes, the versioned JSON file
//! format, validation, and the built-in benchmark sketch.
mod model;
pub use model::{Sketch, Stroke, StrokeKind};
