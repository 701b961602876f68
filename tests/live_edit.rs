//! The land follows the pen: replays of live edits in the real editor (Xvfb, software adapter) under
//! a work budget, so that every machine runs the same frames; checks read the frame log.
//!
//! `scripts/live_edit_protocol.py` runs the same checks over every kind of edit, size and solver.

use std::path::{Path, PathBuf};
use std::process::Command;

use serde_json::Value;

fn bin() -> PathBuf {
    PathBuf::from(env!("CARGO_BIN_EXE_terrasketch"))
}

/// Runs a session (as `tests/editor.rs` does) and returns its frame log.
fn replay(session: &str, dir: &Path) -> Vec<Value> {
    let path = dir.join("session.json");
    let log = dir.join("frames.jsonl");
    std::fs::write(&path, session).unwrap();
    let mut cmd = if std::env::var_os("DISPLAY").is_some() {
        Command::new(bin())
    } else {
        let mut c = Command::new("xvfb-run");
        c.args(["-a", "-s", "-screen 0 1280x800x24"]).arg(bin());
        c
    };
    cmd.arg("--replay")
        .arg(&path)
        .arg("--log")
        .arg(&log)
        .env("TERRASKETCH_RECOVERY_DIR", dir);
    if std::env::var_os("WGPU_BACKEND").is_none() {
        cmd.env("WGPU_BACKEND", "vulkan");
    }
    let o = cmd
        .output()
        .expect("the terrasketch binary (or xvfb-run) runs");
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "editor failed: {:?}\n{err}", o.status);
    assert!(!err.contains("panicked"), "editor panicked: {err}");
    std::fs::read_to_string(&log)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).expect("each log line is JSON"))
        .collect()
}

/// The work budget of the session (reference work units a frame).
const BUDGET_WU: f64 = 4.0;

/// A drag of the example scene's stroke 1 by its last handle at 1024^2: 16 moves of about 5 px, the
/// pointer held still for 12 frames, then released. Probes on the dragged end and along the stroke.
const HANDLE_DRAG_1024: &str = r#"{
  "format": "terrasketch-session", "version": 1,
  "sketch": "example", "size": 1024, "window_px": [960, 600],
  "solver_budget_wu": 4, "backend": "cpu", "lag": true,
  "probes_m": [[7600, 5200], [6000, 6000], [6500, 6300], [7000, 5500], [5600, 7300]],
  "events": [
    { "wait_converged": 2000 }, { "mark": "ready" }, { "wait": 1 },
    { "tool": "select" },
    { "press_handle": { "stroke": 1, "end": "last" } }, { "mark": "dragging" },
    { "drag_by": { "to": [80, 40], "frames": 16 } },
    { "mark": "stopped" }, { "wait": 12 },
    { "release": {} }, { "wait_converged": 600 }, { "mark": "settled" }, { "wait": 1 }
  ]
}"#;

fn probes(f: &Value) -> Vec<f64> {
    f["probe_heights_m"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().expect("every probe has a height"))
        .collect()
}

#[test]
fn the_land_follows_a_handle_drag_in_every_frame_at_1024_on_the_cpu_solver() {
    let dir = tempfile::tempdir().unwrap();
    let log = replay(HANDLE_DRAG_1024, dir.path());
    assert!(log.iter().all(|f| f["backend"] == "cpu"));
    let at = |i: usize| &log[i];
    let drag: Vec<usize> = (1..log.len())
        .filter(|&i| {
            at(i)["mark"] == "dragging" && at(i)["sketch_digest"] != at(i - 1)["sketch_digest"]
        })
        .collect();
    assert_eq!(drag.len(), 16, "one edit per drag frame");
    // The displayed heights move in every drag frame (by more than 1 mm at some probe).
    let frozen: Vec<u64> = drag
        .iter()
        .filter(|&&i| {
            let (a, b) = (probes(at(i - 1)), probes(at(i)));
            a.iter().zip(&b).all(|(x, y)| (x - y).abs() <= 1e-3)
        })
        .map(|&i| at(i)["frame"].as_u64().unwrap())
        .collect();
    assert!(frozen.len() <= 1, "frozen drag frames: {frozen:?}");
    // What is shown stays close to the converged land for the pen's position.
    let ready = probes(log.iter().rfind(|f| f["mark"] == "ready").unwrap());
    let settled = probes(log.iter().rfind(|f| f["mark"] == "settled").unwrap());
    let total = ready
        .iter()
        .zip(&settled)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    assert!(total > 100.0, "the drag moves the land: {total} m");
    for &i in &drag[3..] {
        let lag = at(i)["lag_m"].as_f64().expect("lag_m is logged");
        assert!(
            lag < 0.25 * total,
            "frame {}: lag {lag:.1} m of a {total:.1} m change",
            at(i)["frame"]
        );
    }
    // Each drag frame stays within the edit cap (4 budgets, plus the unit that crossed it).
    for &i in &drag {
        let wu = at(i)["work_units"].as_f64().unwrap();
        assert!(
            wu <= 4.0 * BUDGET_WU + 3.0,
            "frame {}: {wu} WU",
            at(i)["frame"]
        );
    }
    // The tolerance holds within 2 frames after the last move.
    let last = *drag.last().unwrap();
    let settle = (last + 1..log.len()).find(|&i| at(i)["converged"] == true);
    assert!(
        settle.is_some_and(|i| i - last <= 2),
        "converged {settle:?} frames after the stop"
    );
}
