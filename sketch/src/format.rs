//! Writing the JSON file format: [`to_json`] and [`save_sketch_atomic`].
//!
//! Reading lives in `parse.rs`; both follow the reference in the crate's README.

use std::fmt::Write as _;
use std::fs;
use std::io::{self, Write as _};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use crate::error::SketchError;
use crate::model::Sketch;
use crate::spec::{FORMAT_NAME, FORMAT_VERSION};

/// Serialises `sketch` to the file format: pretty-printed, `format` and `version` first, one point
/// per line, every attribute written explicitly (defaults included), ending with a newline.
///
/// Numbers are written as the shortest text that reads back to the same `f64`, so
/// `parse_sketch(&to_json(&s))` gives back `s` bit for bit when `s` is valid. Non-finite numbers
/// (which [`validate`](crate::validate) refuses) are written as `null`, so such a file will not load.
pub fn to_json(sketch: &Sketch) -> String {
    let point_count: usize = sketch.strokes.iter().map(|s| s.points.len()).sum();
    let mut out = String::with_capacity(256 + 200 * sketch.strokes.len() + 64 * point_count);
    // `write!` to a `String` cannot fail; the results are ignored on purpose.
    let _ = write!(
        out,
        "{{\n  \"format\": \"{FORMAT_NAME}\",\n  \"version\": {FORMAT_VERSION},\n  \
         \"extent_m\": [{}, {}],\n  \"base_elevation_m\": {},\n",
        number(sketch.extent_m[0]),
        number(sketch.extent_m[1]),
        number(sketch.base_elevation_m),
    );
    // The detail seed only when set, so that files without one are written as before.
    if sketch.seed != 0 {
        let _ = writeln!(out, "  \"seed\": {},", sketch.seed);
    }
    out.push_str("  \"strokes\": [");
    for (index, stroke) in sketch.strokes.iter().enumerate() {
        out.push_str(if index == 0 { "\n" } else { ",\n" });
        let _ = write!(
            out,
            "    {{\n      \"kind\": \"{}\",\n      \"slope_left_deg\": {},\n      \
             \"slope_right_deg\": {},\n      \"width_m\": {},\n      \"roughness\": {},\n      \
             \"curve\": \"{}\",\n      \"closed\": {},\n      \"falloff\": \"{}\",\n      \
             \"height_tolerance_m\": {},\n      \"points\": [",
            stroke.kind.as_str(),
            number(stroke.slope_left_deg),
            number(stroke.slope_right_deg),
            number(stroke.width_m),
            number(stroke.roughness),
            stroke.curve.as_str(),
            stroke.closed,
            stroke.falloff.as_str(),
            number(stroke.height_tolerance_m),
        );
        for (point, &[x, y, z]) in stroke.points.iter().enumerate() {
            out.push_str(if point == 0 { "\n" } else { ",\n" });
            let _ = write!(out, "        [{}, {}, {}]", number(x), number(y), number(z));
        }
        out.push_str(if stroke.points.is_empty() {
            "]\n    }"
        } else {
            "\n      ]\n    }"
        });
    }
    out.push_str(if sketch.strokes.is_empty() {
        "]\n}\n"
    } else {
        "\n  ]\n}\n"
    });
    out
}

/// The shortest decimal text that parses back to exactly `value` (serde_json's float printer);
/// `null` for NaN and infinities, which JSON cannot represent.
fn number(value: f64) -> String {
    match serde_json::Number::from_f64(value) {
        Some(number) => number.to_string(),
        None => "null".to_owned(),
    }
}

/// Saves `sketch` to `path` so that a crash or an error never leaves a half-written file.
///
/// Writes [`to_json`] to a new temporary file in the same directory (`.<name>.<pid>.<n>.tmp`),
/// gives it the permissions of the file it replaces (if any), flushes it to disk (`fsync`) and
/// renames it over `path`, which is atomic on the same file system. On any error the old file is
/// untouched, the temporary file is removed and [`SketchError::Io`] names `path`. After the rename
/// the directory is synced too (best effort: the save has already happened, so a failure there is
/// not reported). The sketch is not validated here.
pub fn save_sketch_atomic(sketch: &Sketch, path: &Path) -> Result<(), SketchError> {
    let io_error = |source| SketchError::Io {
        path: path.to_path_buf(),
        source,
    };
    let temp_path = temp_path_for(path).map_err(io_error)?;
    let text = to_json(sketch);
    match write_and_rename(&text, &temp_path, path) {
        Ok(()) => {
            sync_parent_dir(path);
            Ok(())
        }
        Err(source) => {
            // The temporary file may not exist (e.g. creation failed); nothing else to do then.
            let _ = fs::remove_file(&temp_path);
            Err(io_error(source))
        }
    }
}

/// A fresh temporary file name next to `path`.
fn temp_path_for(path: &Path) -> io::Result<PathBuf> {
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let file_name = path.file_name().ok_or_else(|| {
        io::Error::new(io::ErrorKind::InvalidInput, "the path does not name a file")
    })?;
    let n = COUNTER.fetch_add(1, Ordering::Relaxed);
    let mut temp_name = std::ffi::OsString::from(".");
    temp_name.push(file_name);
    temp_name.push(format!(".{}.{n}.tmp", std::process::id()));
    Ok(path.with_file_name(temp_name))
}

fn write_and_rename(text: &str, temp_path: &Path, path: &Path) -> io::Result<()> {
    // `create_new` never follows or clobbers an existing file at the temporary name.
    let mut file = fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(temp_path)?;
    file.write_all(text.as_bytes())?;
    if let Ok(old) = fs::metadata(path) {
        file.set_permissions(old.permissions())?;
    }
    file.sync_all()?;
    drop(file);
    fs::rename(temp_path, path)
}

fn sync_parent_dir(path: &Path) {
    #[cfg(unix)]
    {
        let dir = match path.parent() {
            Some(parent) if !parent.as_os_str().is_empty() => parent,
            _ => Path::new("."),
        };
        if let Ok(dir) = fs::File::open(dir) {
            let _ = dir.sync_all();
        }
    }
    #[cfg(not(unix))]
    let _ = path;
}
