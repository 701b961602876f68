//! Helpers shared by the command-line test targets (`cli`, `export`): each uses a subset.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

pub fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_terrasketch"))
}

pub fn run(args: &[&str]) -> Output {
    bin()
        .args(args)
        .output()
        .expect("the terrasketch binary runs")
}

pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

pub fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

/// A valid sketch with one stroke of each kind.
pub const GOOD: &str = r#"{ "format": "terrasketch-sketch", "version": 1,
  "extent_m": [6400.0, 6400.0], "base_elevation_m": 100.0,
  "strokes": [
    { "kind": "ridge", "points": [[800, 3200, 900], [5600, 3300, 1100]], "slope_left_deg": 25, "slope_right_deg": 20, "width_m": 1200, "roughness": 0.5 },
    { "kind": "valley", "points": [[3000, 600, 300], [3100, 2400, 250]] },
    { "kind": "plateau", "points": [[1000, 5200, 600], [2000, 5400, 600]] } ] }"#;

/// Asserts a failed run: non-zero exit, no panic, and the message contains `needle`.
pub fn assert_fails_with(o: &Output, needle: &str) {
    let e = stderr(o);
    assert!(
        !o.status.success(),
        "expected failure, got success; stderr: {e}"
    );
    assert!(!e.contains("panicked"), "panicked: {e}");
    assert!(
        e.to_lowercase().contains(&needle.to_lowercase()),
        "message {e:?} lacks {needle:?}"
    );
}

/// Asserts a refused input: exit status 2, one line of error naming `field`, no output.
pub fn assert_refused(o: &Output, field: &str) {
    assert_fails_with(o, field);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(o));
    let errors: Vec<_> = stderr(o)
        .lines()
        .filter(|l| !l.starts_with("terrasketch: warning"))
        .map(str::to_owned)
        .collect();
    assert_eq!(errors.len(), 1, "one line of error: {}", stderr(o));
    assert!(errors[0].contains(field), "{errors:?} lacks {field:?}");
}

/// Heights of `examples/range.json` solved at `size` samples per side.
pub fn solve_example(dir: &Path, size: usize, ext: &str) -> terrasketch_raster::Heightmap {
    solve_example_with(dir, size, ext, &[])
}

/// [`solve_example`] with more arguments (e.g. `--detail off`).
pub fn solve_example_with(
    dir: &Path,
    size: usize,
    ext: &str,
    extra: &[&str],
) -> terrasketch_raster::Heightmap {
    let out = dir.join(format!("range{size}.{ext}"));
    let size = size.to_string();
    let mut args = vec![
        "solve",
        concat!(env!("CARGO_MANIFEST_DIR"), "/../examples/range.json"),
        "--size",
        &size,
        "-o",
        out.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    let o = run(&args);
    assert!(o.status.success(), "{size}: {}", stderr(&o));
    terrasketch_raster::read_heightmap(&out).unwrap()
}
