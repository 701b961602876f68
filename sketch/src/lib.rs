//! The terrasketch sketch document: strokes with heights and slopes, the versioned JSON file
//! format, validation, and the built-in benchmark sketch.
//!
//! # How it works
//!
//! - [`Sketch`], [`Stroke`] and [`StrokeKind`] (in `model.rs`) are the document: plain data in
//!   world metres (x east, y north, origin at the south-west corner, z up). The editor edits them
//!   directly; nothing here knows about grids or GPUs.
//! - [`validate`] holds every rule a sketch must obey (positive extent, finite numbers, at least
//!   two points per stroke, attribute ranges, size limits against hostile input) and returns
//!   [`Warning`]s for what is odd but usable (a stroke leaving the extent, repeated points).
//! - [`parse_sketch`] reads the JSON file format (reference: the crate's `README.md`) into a
//!   `serde_json::Value`, checks `format` and `version`, refuses oversized input before converting
//!   it, walks the tree by hand so each type error names its JSON path (`strokes[2].width_m`),
//!   reports unknown fields as warnings, fills in the per-kind defaults, then runs [`validate`].
//!   [`load_sketch`] adds reading the file.
//! - [`to_json`] writes every field explicitly, numbers as their shortest exact decimal, so a
//!   valid sketch loads back bit for bit. [`save_sketch_atomic`] writes through a temporary file,
//!   `fsync` and `rename`, so the target is either the old file or the complete new one.
//! - [`stroke_curve`] (in `curve.rs`) turns a stroke's control points into the fine polyline every
//!   rasteriser and the editor use; [`simplify`] reduces freehand samples to control points.
//! - [`benchmark_sketch`] and [`example_sketch`] are built from sines, deterministic.
//!
//! Problems are [`SketchError`] values (thiserror) with human messages; nothing reachable from
//! input panics.
#![warn(missing_docs)]

mod bench;
mod curve;
mod error;
mod format;
mod model;
mod parse;
mod spec;
mod validate;

pub use bench::{BENCHMARK_EXTENT_M, EXAMPLE_EXTENT_M, benchmark_sketch, example_sketch};
pub use curve::{Curve, MAX_CURVE_SEGMENTS, MAX_TURN_RAD, simplify, stroke_curve, stroke_curves};
pub use error::{SketchError, Warning};
pub use format::{save_sketch_atomic, to_json};
pub use model::{
    CurveKind, DEFAULT_HEIGHT_TOLERANCE_M, Falloff, MAX_HEIGHT_TOLERANCE_M, Sketch, Stroke,
    StrokeKind,
};
pub use parse::{Parsed, load_sketch, parse_sketch};
pub use spec::{FORMAT_NAME, FORMAT_VERSION, MAX_POINTS, MAX_STROKES};
pub use validate::{
    MAX_ABS_ELEVATION_M, MAX_EXTENT_M, MAX_SLOPE_DEG, MIN_CELL_SIZE_M, MIN_EXTENT_M,
    check_cell_size, validate,
};
