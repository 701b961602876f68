//! Errors (the sketch is refused) and warnings (the sketch is used, the user is told).

use std::fmt;
use std::path::PathBuf;

use crate::spec::{FORMAT_NAME, FORMAT_VERSION, MAX_POINTS, MAX_STROKES};

/// Why a sketch file or an in-memory sketch was refused.
///
/// Every variant carries enough context for a human message (its `Display`) and for an editor to
/// point at the culprit (stroke and point indices, JSON paths such as `strokes[2].width_m`).
#[derive(Debug, thiserror::Error)]
pub enum SketchError {
    /// The text is not valid JSON (serde_json's message, without its position suffix).
    #[error("malformed JSON at line {line}, column {column}: {message}")]
    Json {
        /// 1-based line of the error.
        line: usize,
        /// 1-based column of the error.
        column: usize,
        /// What the JSON parser expected or found.
        message: String,
    },
    /// A number literal overflows `f64` (e.g. `1e999`); it would be infinite.
    #[error(
        "number too large at line {line}, column {column}: it overflows to infinity; \
         every number in a sketch must be finite (|x| < 1.8e308)"
    )]
    NumberOutOfRange {
        /// 1-based line of the number.
        line: usize,
        /// 1-based column where the parser gave up on the number.
        column: usize,
    },
    /// The `format` field is missing or is not `"terrasketch-sketch"`.
    #[error("not a terrasketch sketch: {}, expected \"format\": \"{FORMAT_NAME}\"", describe_format(.found))]
    Format {
        /// What was found, e.g. `a string ("geojson")` (shortened if long), or `None` if missing.
        found: Option<String>,
    },
    /// The `version` is a number this build cannot read.
    #[error("unsupported sketch version {found}: this build reads version {FORMAT_VERSION}")]
    UnsupportedVersion {
        /// The JSON text of the `version` number found.
        found: String,
    },
    /// A required field is absent.
    #[error("missing field `{path}`")]
    MissingField {
        /// JSON path of the missing field, e.g. `strokes[3].points`.
        path: String,
    },
    /// A field has the wrong JSON type or shape.
    #[error("`{path}` must be {expected}, found {found}")]
    WrongType {
        /// JSON path of the field, e.g. `strokes[0].width_m`; `(document)` for the whole text.
        path: String,
        /// What the format wants there, e.g. `a number`.
        expected: &'static str,
        /// What was there, e.g. `a string`.
        found: String,
    },
    /// A stroke point is not an array of exactly three numbers.
    #[error(
        "stroke {stroke}, point {point} (`strokes[{stroke}].points[{point}]`) must be [x, y, z] (3 numbers), found {found}"
    )]
    BadPoint {
        /// Index of the stroke in `strokes`.
        stroke: usize,
        /// Index of the point in the stroke.
        point: usize,
        /// What was there, e.g. `an array of 2 values`.
        found: String,
    },
    /// A stroke point has a NaN or infinite coordinate.
    #[error(
        "stroke {stroke}, point {point}: coordinate {axis} is {value}, every coordinate must be finite"
    )]
    NonFinitePoint {
        /// Index of the stroke.
        stroke: usize,
        /// Index of the point in the stroke.
        point: usize,
        /// `x`, `y` or `z`.
        axis: &'static str,
        /// The offending value.
        value: f64,
    },
    /// A sketch-level number (currently `base_elevation_m`) is NaN or infinite.
    #[error("`{field}` is {value}, it must be finite")]
    NonFinite {
        /// Name of the field.
        field: &'static str,
        /// The offending value.
        value: f64,
    },
    /// A stroke has fewer than two points.
    #[error("stroke {stroke} has {count} point(s), a stroke needs at least 2")]
    TooFewPoints {
        /// Index of the stroke.
        stroke: usize,
        /// Number of points it has.
        count: usize,
    },
    /// A stroke's `kind` is not one of the known kinds.
    #[error(
        "stroke {stroke} has unknown kind \"{kind}\", allowed kinds: \"ridge\", \"valley\", \"plateau\""
    )]
    UnknownKind {
        /// Index of the stroke.
        stroke: usize,
        /// The kind found (shortened if long).
        kind: String,
    },
    /// A field that names one of a few choices (`curve`, `falloff`) names none of them.
    #[error("`{path}` is \"{found}\", allowed: {allowed}")]
    UnknownChoice {
        /// JSON path of the field, e.g. `strokes[2].curve`.
        path: String,
        /// The name found (shortened if long).
        found: String,
        /// The allowed names in words.
        allowed: &'static str,
    },
    /// A closed stroke has fewer than three distinct points (seen from above).
    #[error("stroke {stroke} is closed but has {count} distinct point(s), a loop needs at least 3")]
    LoopTooSmall {
        /// Index of the stroke.
        stroke: usize,
        /// Distinct points it has (consecutive repeats, and a last point on the first, not counted).
        count: usize,
    },
    /// `extent_m` is not two finite positive numbers from 1 m to 40,000 km.
    #[error(
        "extent_m is [{}, {}] m, both must be positive and finite, from 1 m to 40000000 m (40,000 km)",
        .extent_m[0], .extent_m[1]
    )]
    BadExtent {
        /// The extent found, metres.
        extent_m: [f64; 2],
    },
    /// An elevation (`base_elevation_m` or a point's z) is outside +-100 km.
    #[error("`{field}` is {value} m, allowed: -100000 to 100000 m (+-100 km)")]
    ElevationOutOfRange {
        /// Which number, e.g. `base_elevation_m` or `strokes[2].points[5] z`.
        field: String,
        /// The offending value, metres.
        value: f64,
    },
    /// A solve or export would have cells smaller than 1 cm.
    #[error(
        "cell size {cell_size_m} m (extent_m [{}, {}] m over {cells} cells per side, --size) is below \
         the 0.01 m (1 cm) minimum: use a smaller --size or a larger extent_m",
        .extent_m[0], .extent_m[1]
    )]
    CellTooSmall {
        /// The smaller side of the cell, metres.
        cell_size_m: f64,
        /// The sketch's extent, metres.
        extent_m: [f64; 2],
        /// Cells per side of the solve grid.
        cells: usize,
    },
    /// A stroke attribute is outside its allowed range (or NaN/infinite).
    #[error("stroke {stroke}: {attribute} is {value}, allowed: {allowed}")]
    AttributeOutOfRange {
        /// Index of the stroke.
        stroke: usize,
        /// Field name: `slope_left_deg`, `slope_right_deg`, `width_m`, `roughness` or
        /// `height_tolerance_m`.
        attribute: &'static str,
        /// The offending value.
        value: f64,
        /// The allowed range in words, e.g. `0 to 85 degrees`.
        allowed: &'static str,
    },
    /// More strokes than the format accepts (protects against hostile input).
    #[error("the sketch has {count} strokes, at most {MAX_STROKES} are accepted")]
    TooManyStrokes {
        /// Number of strokes found.
        count: usize,
    },
    /// More points in total than the format accepts (protects against hostile input).
    #[error("the sketch has {count} points in total, at most {MAX_POINTS} are accepted")]
    TooManyPoints {
        /// Total number of points found over all strokes.
        count: usize,
    },
    /// Reading or writing a file failed.
    #[error("I/O error on `{}`: {source}", .path.display())]
    Io {
        /// The file the operation was about (for a save: the target, not the temporary file).
        path: PathBuf,
        /// The operating system's error.
        source: std::io::Error,
    },
}

fn describe_format(found: &Option<String>) -> String {
    match found {
        Some(text) => format!("`format` is {text}"),
        None => "the `format` field is missing".to_owned(),
    }
}

/// Something odd about a sketch that does not stop it from being used.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub enum Warning {
    /// A field the format does not define; it was ignored.
    UnknownField {
        /// JSON path of the field, e.g. `strokes[2].colour`.
        path: String,
    },
    /// A stroke has a point outside `[0, extent]` in x or y; the solver clips it.
    StrokeLeavesExtent {
        /// Index of the stroke.
        stroke: usize,
    },
    /// A stroke has consecutive points at the same (x, y); they are kept, the rasteriser skips the
    /// zero-length segment.
    DuplicatePoints {
        /// Index of the stroke.
        stroke: usize,
    },
}

impl fmt::Display for Warning {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Warning::UnknownField { path } => write!(f, "unknown field `{path}` ignored"),
            Warning::StrokeLeavesExtent { stroke } => {
                write!(
                    f,
                    "stroke {stroke} leaves the terrain extent; the part outside is clipped"
                )
            }
            Warning::DuplicatePoints { stroke } => write!(
                f,
                "stroke {stroke} has consecutive points at the same position; the zero-length segments are skipped"
            ),
        }
    }
}
