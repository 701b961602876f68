//! The optional `refined` record of a sketch file: how the editor's refined terrain (the realism
//! pass) of this sketch was made, so that reopening the file shows it again.
//!
//! The record holds the inputs of the pass (seed, solve size, exemplar names, parameters), the
//! digest of the sketch it was made for and, when the heights were saved beside the sketch, the
//! digest of those heights. The sketch crate only checks the record's shape and bounds; what the
//! parameter names mean is the editor's business.

use std::fmt::Write as _;

use serde_json::{Map, Value};

use crate::error::SketchError;

/// Smallest solve size a record may name.
pub const MIN_REFINED_SIZE: usize = 64;
/// Largest solve size a record may name (the solver's largest grid).
pub const MAX_REFINED_SIZE: usize = 16384;
/// Most exemplar names in a record.
pub const MAX_REFINED_EXEMPLARS: usize = 256;
/// Most parameters in a record.
pub const MAX_REFINED_PARAMS: usize = 64;
/// Longest exemplar or parameter name, characters.
pub const MAX_REFINED_NAME_CHARS: usize = 128;

const FIELDS: [&str; 6] = [
    "seed",
    "size",
    "exemplars",
    "params",
    "sketch_digest",
    "heights_digest",
];

/// How a refined terrain was made (the `refined` object of a sketch file).
#[derive(Debug, Clone, PartialEq)]
pub struct RefinedRecord {
    /// Seed of the synthesis.
    pub seed: u64,
    /// Side of the power-of-two solve grid it was made at (64 to 16384).
    pub size: usize,
    /// Names of the exemplar DEMs used (the shipped library's files), in the order used.
    pub exemplars: Vec<String>,
    /// Refinement parameters by name, sorted by name (numbers; the editor knows the names).
    pub params: Vec<(String, f64)>,
    /// [`sketch_digest`](crate::sketch_digest) of the sketch the terrain was made for.
    pub sketch_digest: String,
    /// [`heights_digest`] of the heights file saved beside the sketch; `None` when none was saved.
    pub heights_digest: Option<String>,
}

/// FNV-1a 64 of `bytes`, as 16 lowercase hex digits.
pub(crate) fn fnv1a(bytes: impl IntoIterator<Item = u8>) -> String {
    let mut h: u64 = 0xcbf29ce484222325;
    for b in bytes {
        h ^= u64::from(b);
        h = h.wrapping_mul(0x100000001b3);
    }
    format!("{h:016x}")
}

/// Fingerprint of a heights raster: FNV-1a 64 of its samples' little-endian `f32` bits.
pub fn heights_digest(heights: &[f32]) -> String {
    fnv1a(heights.iter().flat_map(|h| h.to_bits().to_le_bytes()))
}

fn bad(path: &str, reason: impl Into<String>) -> SketchError {
    SketchError::BadRefined {
        path: path.to_owned(),
        reason: reason.into(),
    }
}

fn digest_field(fields: &Map<String, Value>, name: &str) -> Result<Option<String>, SketchError> {
    let path = format!("refined.{name}");
    match fields.get(name) {
        None => Ok(None),
        Some(Value::String(s))
            if s.len() == 16
                && s.bytes()
                    .all(|b| b.is_ascii_hexdigit() && !b.is_ascii_uppercase()) =>
        {
            Ok(Some(s.clone()))
        }
        Some(_) => Err(bad(&path, "must be 16 lowercase hex digits")),
    }
}

fn name_ok(name: &str) -> bool {
    !name.is_empty()
        && name.chars().count() <= MAX_REFINED_NAME_CHARS
        && !name.chars().any(|c| c.is_control())
}

/// Reads the `refined` object; every problem names its field (`refined.size`).
pub fn parse_refined(value: &Value) -> Result<RefinedRecord, SketchError> {
    let Value::Object(fields) = value else {
        return Err(bad("refined", "must be an object"));
    };
    if let Some(key) = fields.keys().find(|k| !FIELDS.contains(&k.as_str())) {
        let key: String = key.chars().take(60).collect();
        return Err(bad(
            &format!("refined.{key}"),
            format!("unknown field (known: {})", FIELDS.join(", ")),
        ));
    }
    let required = |name: &str| {
        fields.get(name).ok_or_else(|| SketchError::MissingField {
            path: format!("refined.{name}"),
        })
    };
    let seed = required("seed")?
        .as_u64()
        .ok_or_else(|| bad("refined.seed", "must be a whole number from 0 to 2^64 - 1"))?;
    let size = required("size")?
        .as_u64()
        .and_then(|s| usize::try_from(s).ok())
        .filter(|s| s.is_power_of_two() && (MIN_REFINED_SIZE..=MAX_REFINED_SIZE).contains(s))
        .ok_or_else(|| {
            bad(
                "refined.size",
                format!("must be a power of two from {MIN_REFINED_SIZE} to {MAX_REFINED_SIZE}"),
            )
        })?;
    let exemplars = match required("exemplars")? {
        Value::Array(items) if !items.is_empty() && items.len() <= MAX_REFINED_EXEMPLARS => items
            .iter()
            .map(|v| match v {
                Value::String(s) if name_ok(s) => Ok(s.clone()),
                _ => Err(bad(
                    "refined.exemplars",
                    format!("names must be strings of 1 to {MAX_REFINED_NAME_CHARS} characters"),
                )),
            })
            .collect::<Result<Vec<_>, _>>()?,
        _ => {
            return Err(bad(
                "refined.exemplars",
                format!("must be an array of 1 to {MAX_REFINED_EXEMPLARS} names"),
            ));
        }
    };
    let params = match fields.get("params") {
        None => Vec::new(),
        Some(Value::Object(map)) if map.len() <= MAX_REFINED_PARAMS => {
            let mut out = Vec::with_capacity(map.len());
            for (k, v) in map {
                let path = format!("refined.params.{}", k.chars().take(60).collect::<String>());
                if !name_ok(k) {
                    return Err(bad(&path, "bad parameter name"));
                }
                let x = v
                    .as_f64()
                    .filter(|x| x.is_finite())
                    .ok_or_else(|| bad(&path, "must be a number"))?;
                out.push((k.clone(), x));
            }
            out.sort_by(|a, b| a.0.cmp(&b.0));
            out
        }
        Some(_) => {
            return Err(bad(
                "refined.params",
                format!("must be an object of at most {MAX_REFINED_PARAMS} numbers"),
            ));
        }
    };
    let sketch_digest =
        digest_field(fields, "sketch_digest")?.ok_or_else(|| SketchError::MissingField {
            path: "refined.sketch_digest".to_owned(),
        })?;
    let heights_digest = digest_field(fields, "heights_digest")?;
    Ok(RefinedRecord {
        seed,
        size,
        exemplars,
        params,
        sketch_digest,
        heights_digest,
    })
}

/// Appends the record as the `"refined"` member of the top-level object (two-space indent, no
/// trailing comma or newline).
pub(crate) fn write_refined(out: &mut String, r: &RefinedRecord) {
    let quote = |s: &str| Value::String(s.to_owned()).to_string();
    let _ = write!(
        out,
        "  \"refined\": {{\n    \"seed\": {},\n    \"size\": {},\n    \"exemplars\": [",
        r.seed, r.size
    );
    for (i, name) in r.exemplars.iter().enumerate() {
        let sep = if i == 0 { "" } else { ", " };
        let _ = write!(out, "{sep}{}", quote(name));
    }
    out.push_str("],\n    \"params\": {");
    for (i, (k, v)) in r.params.iter().enumerate() {
        let sep = if i == 0 { "" } else { "," };
        let value = serde_json::Number::from_f64(*v)
            .map(|n| n.to_string())
            .unwrap_or_else(|| "null".to_owned());
        let _ = write!(out, "{sep}\n      {}: {value}", quote(k));
    }
    out.push_str(if r.params.is_empty() {
        "},\n"
    } else {
        "\n    },\n"
    });
    let _ = write!(out, "    \"sketch_digest\": {}", quote(&r.sketch_digest));
    if let Some(h) = &r.heights_digest {
        let _ = write!(out, ",\n    \"heights_digest\": {}", quote(h));
    }
    out.push_str("\n  }");
}
