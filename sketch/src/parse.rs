//! Reading the JSON file format: [`parse_sketch`] and [`load_sketch`].
//!
//! The text is parsed into a `serde_json::Value` first, then walked by hand, so that every type
//! error can name its JSON path and unknown fields can be reported instead of silently dropped.

use std::path::Path;

use serde_json::{Map, Value};

use crate::error::{SketchError, Warning};
use crate::model::{CurveKind, Falloff, Sketch, Stroke, StrokeKind};
use crate::spec::FORMAT_NAME;
use crate::validate::{check_counts, validate};

/// A sketch read from a file, with what was odd about it.
#[derive(Debug, Clone, PartialEq)]
pub struct Parsed {
    /// The sketch, already validated.
    pub sketch: Sketch,
    /// Unknown fields first (in key order per object, top level before strokes), then the
    /// warnings of [`validate`].
    pub warnings: Vec<Warning>,
}

const TOP_LEVEL_FIELDS: [&str; 6] = [
    "format",
    "version",
    "extent_m",
    "base_elevation_m",
    "seed",
    "strokes",
];
const STROKE_FIELDS: [&str; 10] = [
    "kind",
    "points",
    "slope_left_deg",
    "slope_right_deg",
    "width_m",
    "roughness",
    "curve",
    "closed",
    "falloff",
    "height_tolerance_m",
];
/// Longest quoted text (strings found in the input) repeated in an error message.
const MAX_QUOTED_CHARS: usize = 60;

/// Parses and validates a sketch file's text.
///
/// Order of checks: JSON syntax, a top-level object, `format`, `version`, the stroke and point
/// counts (before anything is converted), then every field's type and shape, then [`validate`].
/// Optional fields (`base_elevation_m`, `seed`, and per stroke `slope_left_deg`, `slope_right_deg`,
/// `width_m`, `roughness`, `curve`, `closed`, `falloff`, `height_tolerance_m`) take their defaults when absent; `null` is not absent and is refused.
pub fn parse_sketch(text: &str) -> Result<Parsed, SketchError> {
    let root: Value = serde_json::from_str(text).map_err(json_error)?;
    let Value::Object(root) = root else {
        return Err(wrong_type("(document)", "a JSON object", &root));
    };
    check_format(&root)?;
    check_version(&root)?;
    let mut warnings = Vec::new();
    warn_unknown(&root, &TOP_LEVEL_FIELDS, "", &mut warnings);

    let strokes = match required(&root, "strokes", "strokes")? {
        Value::Array(strokes) => strokes,
        other => return Err(wrong_type("strokes", "an array of strokes", other)),
    };
    let point_counts = strokes.iter().map(|stroke| match stroke.get("points") {
        Some(Value::Array(points)) => points.len(),
        _ => 0,
    });
    check_counts(strokes.len(), point_counts)?;

    let extent_m = read_extent(required(&root, "extent_m", "extent_m")?)?;
    let base_elevation_m = match root.get("base_elevation_m") {
        Some(value) => number(value, "base_elevation_m")?,
        None => 0.0,
    };
    let seed = match root.get("seed") {
        Some(value) => value
            .as_u64()
            .ok_or_else(|| wrong_type("seed", "a whole number from 0 to 2^64 - 1", value))?,
        None => 0,
    };
    let strokes = strokes
        .iter()
        .enumerate()
        .map(|(index, value)| read_stroke(index, value, &mut warnings))
        .collect::<Result<Vec<_>, _>>()?;

    let sketch = Sketch {
        extent_m,
        base_elevation_m,
        seed,
        strokes,
    };
    warnings.extend(validate(&sketch)?);
    Ok(Parsed { sketch, warnings })
}

/// Reads the file at `path` (UTF-8) and [`parse_sketch`]es it; a read failure is
/// [`SketchError::Io`] naming `path`.
pub fn load_sketch(path: &Path) -> Result<Parsed, SketchError> {
    let text = std::fs::read_to_string(path).map_err(|source| SketchError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    parse_sketch(&text)
}

fn json_error(error: serde_json::Error) -> SketchError {
    let (line, column) = (error.line(), error.column());
    let full = error.to_string();
    let position = format!(" at line {line} column {column}");
    let message = full.strip_suffix(&position).unwrap_or(&full).to_owned();
    if message.starts_with("number out of range") {
        SketchError::NumberOutOfRange { line, column }
    } else {
        SketchError::Json {
            line,
            column,
            message,
        }
    }
}

fn check_format(root: &Map<String, Value>) -> Result<(), SketchError> {
    match root.get("format") {
        Some(Value::String(name)) if name == FORMAT_NAME => Ok(()),
        Some(other) => Err(SketchError::Format {
            found: Some(describe(other)),
        }),
        None => Err(SketchError::Format { found: None }),
    }
}

fn check_version(root: &Map<String, Value>) -> Result<(), SketchError> {
    match required(root, "version", "version")? {
        // `1` and `1.0` are both version 1.
        Value::Number(n) if n.as_f64() == Some(1.0) => Ok(()),
        Value::Number(n) => Err(SketchError::UnsupportedVersion {
            found: n.to_string(),
        }),
        other => Err(wrong_type("version", "a number", other)),
    }
}

fn read_extent(value: &Value) -> Result<[f64; 2], SketchError> {
    const EXPECTED: &str = "an array of two numbers [width, height] in metres";
    match value {
        Value::Array(items) if items.len() == 2 => match (items[0].as_f64(), items[1].as_f64()) {
            (Some(width), Some(height)) => Ok([width, height]),
            _ => Err(SketchError::WrongType {
                path: "extent_m".to_owned(),
                expected: EXPECTED,
                found: format!("[{}, {}]", describe(&items[0]), describe(&items[1])),
            }),
        },
        other => Err(wrong_type("extent_m", EXPECTED, other)),
    }
}

fn read_stroke(
    index: usize,
    value: &Value,
    warnings: &mut Vec<Warning>,
) -> Result<Stroke, SketchError> {
    let path = |field: &str| format!("strokes[{index}].{field}");
    let Value::Object(fields) = value else {
        return Err(wrong_type(
            &format!("strokes[{index}]"),
            "a stroke object",
            value,
        ));
    };
    warn_unknown(
        fields,
        &STROKE_FIELDS,
        &format!("strokes[{index}]."),
        warnings,
    );

    let kind = match required(fields, "kind", &path("kind"))? {
        Value::String(name) => StrokeKind::parse(name).ok_or_else(|| SketchError::UnknownKind {
            stroke: index,
            kind: shorten(name),
        })?,
        other => {
            return Err(wrong_type(
                &path("kind"),
                "a string (\"ridge\", \"valley\" or \"plateau\")",
                other,
            ));
        }
    };
    let points = match required(fields, "points", &path("points"))? {
        Value::Array(points) => points
            .iter()
            .enumerate()
            .map(|(point, value)| read_point(index, point, value))
            .collect::<Result<Vec<_>, _>>()?,
        other => {
            return Err(wrong_type(
                &path("points"),
                "an array of [x, y, z] points",
                other,
            ));
        }
    };

    let mut stroke = Stroke::new(kind, points);
    let attributes = [
        ("slope_left_deg", &mut stroke.slope_left_deg),
        ("slope_right_deg", &mut stroke.slope_right_deg),
        ("width_m", &mut stroke.width_m),
        ("roughness", &mut stroke.roughness),
        ("height_tolerance_m", &mut stroke.height_tolerance_m),
    ];
    for (name, slot) in attributes {
        if let Some(value) = fields.get(name) {
            *slot = number(value, &path(name))?;
        }
    }
    read_shape(fields, index, &mut stroke)?;
    Ok(stroke)
}

/// The optional `curve`, `closed` and `falloff` fields of stroke `index` into `stroke`.
fn read_shape(
    fields: &Map<String, Value>,
    index: usize,
    stroke: &mut Stroke,
) -> Result<(), SketchError> {
    let path = |field: &str| format!("strokes[{index}].{field}");
    if let Some(value) = fields.get("curve") {
        const ALLOWED: &str = "\"smooth\" or \"polyline\"";
        stroke.curve = choice(value, &path("curve"), ALLOWED, CurveKind::parse)?;
    }
    if let Some(value) = fields.get("closed") {
        stroke.closed = match value {
            Value::Bool(b) => *b,
            other => return Err(wrong_type(&path("closed"), "a boolean", other)),
        };
    }
    if let Some(value) = fields.get("falloff") {
        const ALLOWED: &str = "\"foot\", \"sigmoid\" or \"none\"";
        stroke.falloff = choice(value, &path("falloff"), ALLOWED, Falloff::parse)?;
    }
    Ok(())
}

/// A string field that must be one of a few names.
fn choice<T>(
    value: &Value,
    path: &str,
    allowed: &'static str,
    parse: impl Fn(&str) -> Option<T>,
) -> Result<T, SketchError> {
    match value {
        Value::String(name) => parse(name).ok_or_else(|| SketchError::UnknownChoice {
            path: path.to_owned(),
            found: shorten(name),
            allowed,
        }),
        other => Err(SketchError::WrongType {
            path: path.to_owned(),
            expected: "a string",
            found: describe(other),
        }),
    }
}

fn read_point(stroke: usize, point: usize, value: &Value) -> Result<[f64; 3], SketchError> {
    let bad = |found| SketchError::BadPoint {
        stroke,
        point,
        found,
    };
    let Value::Array(coords) = value else {
        return Err(bad(describe(value)));
    };
    if coords.len() != 3 {
        return Err(bad(describe(value)));
    }
    let mut out = [0.0; 3];
    for (axis, (slot, coord)) in out.iter_mut().zip(coords).enumerate() {
        *slot = coord.as_f64().ok_or_else(|| {
            bad(format!(
                "an array whose element {axis} is {}",
                describe(coord)
            ))
        })?;
    }
    Ok(out)
}

fn required<'a>(
    fields: &'a Map<String, Value>,
    name: &str,
    path: &str,
) -> Result<&'a Value, SketchError> {
    fields.get(name).ok_or_else(|| SketchError::MissingField {
        path: path.to_owned(),
    })
}

fn number(value: &Value, path: &str) -> Result<f64, SketchError> {
    value
        .as_f64()
        .ok_or_else(|| wrong_type(path, "a number", value))
}

fn warn_unknown(
    fields: &Map<String, Value>,
    known: &[&str],
    prefix: &str,
    warnings: &mut Vec<Warning>,
) {
    for key in fields.keys().filter(|key| !known.contains(&key.as_str())) {
        warnings.push(Warning::UnknownField {
            path: format!("{prefix}{}", shorten(key)),
        });
    }
}

fn wrong_type(path: &str, expected: &'static str, found: &Value) -> SketchError {
    SketchError::WrongType {
        path: path.to_owned(),
        expected,
        found: describe(found),
    }
}

/// A short human description of a JSON value's type (and, for scalars, its value).
fn describe(value: &Value) -> String {
    match value {
        Value::Null => "null".to_owned(),
        Value::Bool(b) => format!("a boolean ({b})"),
        Value::Number(n) => format!("a number ({n})"),
        Value::String(s) => format!("a string ({})", Value::String(shorten(s))),
        Value::Array(items) if items.len() == 1 => "an array of 1 value".to_owned(),
        Value::Array(items) => format!("an array of {} values", items.len()),
        Value::Object(_) => "an object".to_owned(),
    }
}

/// `text` cut to [`MAX_QUOTED_CHARS`] characters (with `...` appended when cut), so hostile input
/// cannot make error messages huge.
fn shorten(text: &str) -> String {
    match text.char_indices().nth(MAX_QUOTED_CHARS) {
        Some((cut, _)) => format!("{}...", &text[..cut]),
        None => text.to_owned(),
    }
}
