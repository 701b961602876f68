//! End-to-end tests of the editor: the real binary, a real window (Xvfb) on the software adapter,
//! driven by replay sessions; checks read the frame log, the screenshots and the saved files.
//!
//! Needs a display: `DISPLAY` set (e.g. `Xvfb :99 &` + `DISPLAY=:99`) or `xvfb-run` on the PATH. A
//! missing display or adapter fails the test with the editor's message; it is never skipped.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use serde_json::Value;

fn bin() -> PathBuf {
    PathBuf::from(env!("CARGO_BIN_EXE_terrasketch"))
}

/// Runs the binary with a display (the current one, or a fresh Xvfb via xvfb-run).
fn run_editor(args: &[&str], recovery_dir: &Path) -> Output {
    let mut cmd = if std::env::var_os("DISPLAY").is_some() {
        Command::new(bin())
    } else {
        let mut c = Command::new("xvfb-run");
        c.args(["-a", "-s", "-screen 0 1280x800x24"]).arg(bin());
        c
    };
    cmd.args(args).env("TERRASKETCH_RECOVERY_DIR", recovery_dir);
    if std::env::var_os("WGPU_BACKEND").is_none() {
        cmd.env("WGPU_BACKEND", "vulkan");
    }
    cmd.output()
        .expect("the terrasketch binary (or xvfb-run) runs")
}

fn read_log(path: &Path) -> Vec<Value> {
    let text = std::fs::read_to_string(path)
        .unwrap_or_else(|e| panic!("frame log {}: {e}", path.display()));
    text.lines()
        .map(|l| serde_json::from_str(l).expect("each log line is JSON"))
        .collect()
}

fn probe(frame: &Value, i: usize) -> Option<f64> {
    frame["probe_heights_m"][i].as_f64()
}

fn with_mark<'a>(log: &'a [Value], mark: &str) -> Vec<&'a Value> {
    log.iter().filter(|f| f["mark"] == mark).collect()
}

fn assert_ran(o: &Output) {
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "editor failed: {:?}\n{err}", o.status);
    assert!(!err.contains("panicked"), "editor panicked: {err}");
}

const SESSION: &str = r#"{
  "format": "terrasketch-session", "version": 1,
  "sketch": "empty", "size": 256, "window_px": [640, 400], "solver_budget_wu": 4,
  "probes_px": [[457, 250], [457, 290]],
  "events": [
    { "wait_converged": 50 }, { "mark": "flat" }, { "snapshot": "flat" }, { "screenshot": "flat.png" },
    { "tool": "ridge" },
    { "move": [307, 250] }, { "press": { "at": [307, 250] } }, { "mark": "drawing" },
    { "drag_to": { "to": [457, 150], "frames": 10 } },
    { "drag_to": { "to": [607, 250], "frames": 10 } }, { "wait": 3 },
    { "release": { "at": [607, 250] } }, { "mark": "released" },
    { "wait_converged": 300 }, { "snapshot": "ridge" }, { "screenshot": "ridge.png" }, { "mark": "ridge" }, { "wait": 1 },
    { "tool": "select" },
    { "press_handle": { "stroke": -1, "end": "last" } }, { "mark": "dragging" },
    { "drag_to": { "to": [607, 330], "frames": 8 } }, { "wait": 2 },
    { "release": { "at": [607, 330] } }, { "mark": "dragged" },
    { "wait_converged": 300 }, { "mark": "dragged_converged" }, { "wait": 1 },
    { "key": "ctrl+z" }, { "mark": "undone" },
    { "wait_converged": 300 }, { "compare": "ridge" }, { "mark": "undone_converged" }, { "wait": 1 },
    { "save": "saved.json" }, { "mark": "saved" }, { "wait": 1 },
    { "key": "ctrl+y" }, { "wait": 2 }, { "wait_converged": 300 }, { "compare": "ridge" },
    { "mark": "redone_converged" }, { "wait": 1 },
    { "open": "saved.json" }, { "mark": "reopened" }, { "wait": 2 },
    { "wait_converged": 400 }, { "compare": "ridge" }, { "mark": "reopened_converged" }, { "wait": 1 },
    { "open": "bad.json" }, { "mark": "bad_open" }, { "wait": 2 },
    { "resize": [0, 0] }, { "mark": "minimised" }, { "wait": 3 },
    { "resize": [640, 400] }, { "mark": "restored" }, { "wait": 2 }
  ]
}"#;

/// Kilobytes the editor may read back per frame while the pointer edits (the paper's coupling: the
/// min/max pyramid, FCG's stop tests and the probes; never the heightmap).
const MAX_BYTES_DOWN_EDITING: u64 = 64 * 1024;

#[test]
fn draw_drag_undo_save_reopen_via_replay_gpu_solver() {
    let log = draw_drag_undo_save_reopen("gpu");
    assert!(
        log.iter().all(|f| f["backend"] == "gpu"),
        "the GPU solver ran every frame (no fallback)"
    );
    let editing: Vec<u64> = log
        .iter()
        .filter(|f| f["pointer_down"] == true)
        .map(|f| f["bytes_down"].as_u64().unwrap())
        .collect();
    assert!(editing.len() >= 25);
    let worst = editing.iter().max().copied().unwrap_or(0);
    assert!(
        worst <= MAX_BYTES_DOWN_EDITING,
        "a frame read back {worst} bytes while editing"
    );
    // The min/max pyramid really comes back from the GPU while the terrain changes; the heightmap is
    // never uploaded (bytes_up stays far below one 256^2 mip, 256 KB, on frames without an edit).
    assert!(editing.iter().any(|b| *b > 1024));
    let idle_up = log
        .iter()
        .filter(|f| f["mark"] == "ridge")
        .map(|f| f["bytes_up"].as_u64().unwrap())
        .max()
        .unwrap();
    assert!(idle_up < 64 * 1024, "idle frames sent {idle_up} bytes");
    // A frame waits for the device only for this replay's probe texels (and when it is two takes
    // behind): the reliefs are computed on the GPU, and FCG's stop tests, the solves' reports and
    // the min/max pyramid arrive without waiting (the blocking path waited 8 times a frame).
    let mut waits: Vec<u64> = log
        .iter()
        .filter(|f| f["pointer_down"] == true)
        .map(|f| f["gpu_blocking_waits"].as_u64().unwrap())
        .collect();
    assert!(waits.iter().any(|w| *w >= 1), "{waits:?}");
    assert!(
        waits.iter().all(|w| *w <= 3),
        "waits per editing frame: {waits:?}"
    );
    waits.sort_unstable();
    assert!(
        waits[waits.len() / 2] <= 1,
        "median waits per editing frame: {waits:?}"
    );
    // Frames that ran solver passes log their estimated bytes and the paper model's time.
    let worked: Vec<&Value> = log
        .iter()
        .filter(|f| f["gpu_dispatches"].as_u64().unwrap() > 0)
        .collect();
    assert!(!worked.is_empty());
    for f in worked {
        assert!(f["gpu_bytes_moved_estimate"].as_u64().unwrap() > 0, "{f}");
        assert!(f["gpu_paper_model_ms"].as_f64().unwrap() > 0.0, "{f}");
    }
    assert!(
        log.iter()
            .filter(|f| f["gpu_dispatches"] == 0 && f["gpu_blocking_waits"] == 0)
            .all(|f| f["gpu_paper_model_ms"] == 0.0)
    );
}

#[test]
fn draw_drag_undo_save_reopen_via_replay_cpu_solver() {
    let log = draw_drag_undo_save_reopen("cpu");
    assert!(log.iter().all(|f| f["backend"] == "cpu"));
    assert!(
        log.iter().all(|f| f["bytes_down"] == 0),
        "the CPU solver reads nothing back"
    );
}

/// Runs `SESSION` on the given solver backend and checks what both backends must do; returns the log.
fn draw_drag_undo_save_reopen(backend: &str) -> Vec<Value> {
    let dir = tempfile::tempdir().unwrap();
    let session = dir.path().join("session.json");
    let text = SESSION.replace(
        r#""solver_budget_wu": 4,"#,
        &format!(r#""solver_budget_wu": 4, "backend": "{backend}","#),
    );
    assert_ne!(text, SESSION);
    std::fs::write(&session, text).unwrap();
    // Valid JSON, wrong version: opening it must change nothing.
    std::fs::write(
        dir.path().join("bad.json"),
        r#"{"format": "terrasketch-sketch", "version": 7, "extent_m": [1, 1], "strokes": []}"#,
    )
    .unwrap();
    let shots = dir.path().join("shots");
    let log_path = dir.path().join("frames.jsonl");
    let o = run_editor(
        &[
            "--replay",
            session.to_str().unwrap(),
            "--screenshots",
            shots.to_str().unwrap(),
            "--log",
            log_path.to_str().unwrap(),
        ],
        dir.path(),
    );
    assert_ran(&o);
    let log = read_log(&log_path);
    for key in [
        "frame",
        "ms",
        "tool",
        "solver_finest_level",
        "solver_residual",
        "work_units",
        "patches",
        "bytes_up",
        "bytes_down",
        "strokes",
        "probe_heights_m",
    ] {
        assert!(log[0].get(key).is_some(), "frame log lacks {key}");
    }
    assert!(
        log.iter().any(|f| f["patches"].as_u64().unwrap_or(0) > 0),
        "no patch drawn"
    );

    // 1. The height under the stroke rises during the stroke, before the release.
    let flat = probe(with_mark(&log, "flat").last().unwrap(), 0).expect("probe 0 on the terrain");
    let ridge_frame = *with_mark(&log, "ridge").first().unwrap();
    let ridge = probe(ridge_frame, 0).unwrap();
    assert!(
        ridge > flat + 100.0,
        "the ridge did not rise: flat {flat} m, converged {ridge} m"
    );
    let during: Vec<f64> = log
        .iter()
        .filter(|f| f["pointer_down"] == true && f["mark"] == "drawing")
        .filter_map(|f| probe(f, 0))
        .collect();
    assert!(
        during.len() >= 15,
        "expected the drawing frames in the log, got {}",
        during.len()
    );
    let best_during = during.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
    assert!(
        best_during > flat + 0.3 * (ridge - flat),
        "height under the stroke rose only after release: flat {flat}, best while drawing {best_during}, converged {ridge}"
    );
    assert_eq!(ridge_frame["strokes"], 1);

    // 2. Dragging the end handle moves the ridge: probe 0 (old crest) falls, probe 1 (toward the new end) rises.
    let dragged = *with_mark(&log, "dragged_converged").first().unwrap();
    let (p0, p1) = (probe(dragged, 0).unwrap(), probe(dragged, 1).unwrap());
    let p1_before = probe(ridge_frame, 1).unwrap();
    assert!(
        p0 < ridge - 50.0,
        "old crest did not fall after the drag: {ridge} -> {p0}"
    );
    assert!(
        p1 > p1_before + 50.0,
        "terrain toward the new end did not rise: {p1_before} -> {p1}"
    );
    let moving: Vec<f64> = with_mark(&log, "dragging")
        .iter()
        .filter_map(|f| probe(f, 1))
        .collect();
    assert!(
        moving.iter().any(|h| *h > p1_before + 10.0),
        "the terrain did not follow the handle during the drag: {moving:?}"
    );

    // 3. Undo restores the document exactly and the heights to the solver tolerance.
    let undone = *with_mark(&log, "undone_converged").first().unwrap();
    assert_eq!(
        undone["sketch_digest"], ridge_frame["sketch_digest"],
        "undo did not restore the sketch"
    );
    let diff = undone["compare_max_abs_m"]
        .as_f64()
        .expect("compare logged");
    let relief = ridge - flat;
    assert!(
        diff <= 2e-3 * relief,
        "undo: heights differ by {diff} m (relief {relief} m)"
    );

    // 4. Save, reopen, compare.
    let saved = dir.path().join("saved.json");
    let text = std::fs::read_to_string(&saved).expect("saved file");
    let v: Value = serde_json::from_str(&text).unwrap();
    assert_eq!(v["strokes"].as_array().map(|a| a.len()), Some(1));
    // Before opening, redo brings the dragged ridge back, so the scene that `open` replaces differs
    // from the saved one: the comparison below can only pass if the file really was loaded and solved.
    let redone = *with_mark(&log, "redone_converged").first().unwrap();
    let redone_diff = redone["compare_max_abs_m"]
        .as_f64()
        .expect("compare logged");
    assert!(
        redone_diff > 0.05 * relief,
        "redo did not bring the dragged ridge back: heights differ from the saved scene by only \
         {redone_diff} m (relief {relief} m)"
    );
    let reopened = *with_mark(&log, "reopened_converged").first().unwrap();
    assert_eq!(
        reopened["sketch_digest"], ridge_frame["sketch_digest"],
        "reopened sketch differs"
    );
    assert_eq!(reopened["dirty"], false);
    let diff = reopened["compare_max_abs_m"]
        .as_f64()
        .expect("compare logged");
    assert!(
        diff <= 2e-3 * relief,
        "reopen: heights differ by {diff} m (relief {relief} m)"
    );

    // 5. A bad file shows an error and leaves the scene untouched.
    let bad = with_mark(&log, "bad_open");
    assert!(
        bad.iter()
            .any(|f| f["errors"].as_array().is_some_and(|e| !e.is_empty())),
        "no error reported"
    );
    assert!(
        bad.iter()
            .all(|f| f["sketch_digest"] == ridge_frame["sketch_digest"]),
        "bad open changed the scene"
    );

    // 6. Minimised (zero-size surface) frames keep running.
    let min = with_mark(&log, "minimised");
    assert!(
        !min.is_empty()
            && min
                .iter()
                .all(|f| f["surface_px"] == serde_json::json!([0, 0]))
    );
    assert!(!with_mark(&log, "restored").is_empty());

    // 7. The screenshot shows terrain, not a blank image.
    for name in ["flat.png", "ridge.png"] {
        let img = image::open(shots.join(name))
            .unwrap_or_else(|e| panic!("{name}: {e}"))
            .to_rgb8();
        assert_eq!(img.dimensions(), (640, 400));
        let mut colours = std::collections::HashSet::new();
        let (mut sum, mut sum2, mut n) = (0.0f64, 0.0f64, 0.0f64);
        for p in img.pixels() {
            colours.insert(p.0);
            let l = (p.0[0] as f64 + p.0[1] as f64 + p.0[2] as f64) / 3.0;
            sum += l;
            sum2 += l * l;
            n += 1.0;
        }
        let var = sum2 / n - (sum / n).powi(2);
        assert!(colours.len() > 50, "{name}: only {} colours", colours.len());
        assert!(var > 50.0, "{name}: luminance variance {var}");
    }
    // The ridge changes the picture.
    let a = image::open(shots.join("flat.png")).unwrap().to_rgb8();
    let b = image::open(shots.join("ridge.png")).unwrap().to_rgb8();
    let changed = a.pixels().zip(b.pixels()).filter(|(x, y)| x != y).count();
    assert!(changed > 2000, "the ridge changed only {changed} pixels");
    log
}

#[test]
fn switching_from_the_gpu_to_the_cpu_solver_keeps_the_scene() {
    let dir = tempfile::tempdir().unwrap();
    let session = dir.path().join("s.json");
    std::fs::write(
        &session,
        r#"{ "format": "terrasketch-session", "version": 1, "sketch": "example", "size": 128,
             "backend": "gpu", "window_px": [480, 300], "probes_m": [[7600, 5200], [6000, 6000]],
             "events": [ { "wait_converged": 60 }, { "mark": "gpu" }, { "snapshot": "gpu" }, { "wait": 1 },
               { "solver": "cpu" }, { "mark": "switched" }, { "wait": 1 },
               { "wait_converged": 100 }, { "compare": "gpu" }, { "mark": "cpu" }, { "wait": 1 } ] }"#,
    )
    .unwrap();
    let log_path = dir.path().join("f.jsonl");
    let o = run_editor(
        &[
            "--replay",
            session.to_str().unwrap(),
            "--log",
            log_path.to_str().unwrap(),
        ],
        dir.path(),
    );
    assert_ran(&o);
    let log = read_log(&log_path);
    let gpu = *with_mark(&log, "gpu").first().unwrap();
    assert_eq!(gpu["backend"], "gpu");
    assert_eq!(gpu["settled"], true);
    let switched = with_mark(&log, "switched");
    assert!(switched.iter().all(|f| f["backend"] == "cpu"));
    assert!(
        switched
            .iter()
            .all(|f| f["errors"].as_array().is_some_and(|e| e.is_empty())),
        "a switch asked for is not an error"
    );
    let cpu = *with_mark(&log, "cpu").first().unwrap();
    assert_eq!(cpu["converged"], true);
    assert!(cpu["patches"].as_u64().unwrap() > 0, "the CPU path draws");
    assert_eq!(cpu["bytes_down"], 0);
    // Both solvers give the same terrain (to the solver tolerance; relief about 1200 m).
    let d = cpu["compare_max_abs_m"].as_f64().expect("compare logged");
    assert!(d < 2.0, "GPU and CPU terrains differ by {d} m");
    for i in 0..2 {
        let (a, b) = (probe(gpu, i).unwrap(), probe(cpu, i).unwrap());
        assert!((a - b).abs() < 1.0, "probe {i}: GPU {a} m, CPU {b} m");
    }
}

#[test]
fn lost_device_falls_back_then_keeps_the_work_and_ends_with_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let session = dir.path().join("s.json");
    std::fs::write(
        &session,
        r#"{ "format": "terrasketch-session", "version": 1, "sketch": "example", "size": 64, "backend": "gpu",
             "window_px": [320, 240], "autosave_s": 1000,
             "events": [ { "wait": 3 }, { "select": 0 }, { "set": { "width_m": 900 } }, { "wait": 2 },
               { "destroy_device": true }, { "wait": 5 } ] }"#,
    )
    .unwrap();
    let log_path = dir.path().join("f.jsonl");
    let o = run_editor(
        &[
            "--replay",
            session.to_str().unwrap(),
            "--log",
            log_path.to_str().unwrap(),
        ],
        dir.path(),
    );
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success(),
        "a lost device ends the editor with an error"
    );
    assert!(!err.contains("panicked"), "{err}");
    assert!(err.contains("the GPU device was lost"), "{err}");
    let log = read_log(&log_path);
    let last = log.last().unwrap();
    assert_eq!(last["backend"], "cpu", "the solver fell back first");
    assert!(last["errors"].as_array().is_some_and(|e| !e.is_empty()));
    // The unsaved edit is in the recovery file.
    let text =
        std::fs::read_to_string(dir.path().join("recovery.json")).expect("recovery file kept");
    let v: Value = serde_json::from_str(&text).unwrap();
    assert_eq!(v["strokes"][0]["width_m"].as_f64(), Some(900.0), "{text}");
}

#[test]
fn recovery_autosave_is_offered_back_and_restores_the_scene() {
    let dir = tempfile::tempdir().unwrap();
    let recovery = dir.path().join("recovery.json");
    // 1. Draw a ridge, let the autosave run, then die without the clean exit (as a crash).
    let crash = dir.path().join("crash.json");
    std::fs::write(
        &crash,
        r#"{ "format": "terrasketch-session", "version": 1, "sketch": "empty", "size": 64,
             "window_px": [640, 400], "autosave_s": 0.05, "probes_px": [[457, 200]],
             "events": [ { "wait_converged": 30 }, { "tool": "ridge" },
               { "move": [307, 250] }, { "press": { "at": [307, 250] } },
               { "drag_to": { "to": [457, 150], "frames": 4 } },
               { "drag_to": { "to": [607, 250], "frames": 4 } },
               { "release": { "at": [607, 250] } }, { "wait_converged": 100 }, { "wait": 3 },
               { "mark": "before_crash" }, { "wait": 1 }, { "abort": true }, { "wait": 5 } ] }"#,
    )
    .unwrap();
    let log1 = dir.path().join("crash.jsonl");
    let o = run_editor(
        &[
            "--replay",
            crash.to_str().unwrap(),
            "--log",
            log1.to_str().unwrap(),
        ],
        dir.path(),
    );
    assert_eq!(
        o.status.code(),
        Some(3),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let log1 = read_log(&log1);
    let before = *with_mark(&log1, "before_crash").last().unwrap();
    assert_eq!(before["strokes"], 1);
    assert_eq!(before["dirty"], true);
    assert!(recovery.exists(), "no recovery autosave was written");

    // 2. The next start offers it; accepting restores the strokes (unsaved, dirty) and the terrain,
    // probed at the first run's crest.
    let crest = &before["probe_points_m"][0];
    let (cx, cy) = (crest[0].as_f64().unwrap(), crest[1].as_f64().unwrap());
    let h_before = before["probe_heights_m"][0].as_f64().unwrap();
    assert!(h_before > 100.0, "the first run's ridge rose: {h_before}");
    let restart = dir.path().join("restart.json");
    std::fs::write(
        &restart,
        format!(
            r#"{{ "format": "terrasketch-session", "version": 1, "sketch": "empty", "size": 64,
             "window_px": [640, 400], "autosave_s": 30, "probes_m": [[{cx}, {cy}]],
             "events": [ {{ "wait": 2 }}, {{ "mark": "offered" }}, {{ "wait": 1 }},
               {{ "recovery": "recover" }}, {{ "mark": "recovered" }}, {{ "wait": 1 }},
               {{ "wait_converged": 100 }}, {{ "mark": "settled" }}, {{ "wait": 1 }} ] }}"#
        ),
    )
    .unwrap();
    let log2 = dir.path().join("restart.jsonl");
    let o = run_editor(
        &[
            "--replay",
            restart.to_str().unwrap(),
            "--log",
            log2.to_str().unwrap(),
        ],
        dir.path(),
    );
    assert_ran(&o);
    let log2 = read_log(&log2);
    assert_eq!(log2[0]["strokes"], 0);
    assert_eq!(
        log2[0]["recovery_offered"], true,
        "the recovery file was not offered"
    );
    let recovered = *with_mark(&log2, "recovered").first().unwrap();
    assert_eq!(recovered["recovery_offered"], false);
    assert_eq!(
        recovered["sketch_digest"], before["sketch_digest"],
        "scene not restored"
    );
    assert_eq!(recovered["dirty"], true, "recovered work is unsaved");
    // The restored ridge is solved: the crest stands at the height it had before the crash.
    let settled = *with_mark(&log2, "settled").first().unwrap();
    assert_eq!(settled["converged"], true);
    let h_after = settled["probe_heights_m"][0].as_f64().unwrap();
    assert!(
        (h_after - h_before).abs() <= 0.01 * h_before,
        "crest {h_before} m before the crash, {h_after} m after recovery"
    );
    assert!(
        log2[0]["probe_heights_m"][0].as_f64().unwrap_or(0.0) < 1.0,
        "flat before recovery"
    );
    // A clean exit removes the recovery file.
    assert!(!recovery.exists(), "a clean exit leaves no recovery file");
}

#[test]
fn invalid_or_truncated_sketch_shows_error_and_replay_still_runs() {
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("truncated.json");
    std::fs::write(
        &bad,
        r#"{ "format": "terrasketch-sketch", "version": 1, "extent_m": [100"#,
    )
    .unwrap();
    let session = dir.path().join("s.json");
    std::fs::write(
        &session,
        r#"{ "format": "terrasketch-session", "version": 1, "size": 64, "window_px": [320, 240],
             "probes_m": [[50, 50]], "events": [ { "wait": 3 } ] }"#,
    )
    .unwrap();
    let log_path = dir.path().join("f.jsonl");
    let o = run_editor(
        &[
            "--replay",
            session.to_str().unwrap(),
            "--log",
            log_path.to_str().unwrap(),
            bad.to_str().unwrap(),
        ],
        dir.path(),
    );
    assert_ran(&o);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("truncated.json"),
        "the error names the file: {err}"
    );
    let log = read_log(&log_path);
    assert_eq!(log.len(), 3);
    assert!(log[0]["errors"].as_array().is_some_and(|e| {
        e.iter()
            .any(|m| m.as_str().unwrap_or("").contains("truncated.json"))
    }));
    assert_eq!(log[2]["strokes"], 0);
}

#[test]
fn bad_session_is_refused_before_any_window() {
    let dir = tempfile::tempdir().unwrap();
    let session = dir.path().join("s.json");
    std::fs::write(
        &session,
        r#"{ "format": "terrasketch-session", "version": 1, "events": [ { "jump": 1 } ] }"#,
    )
    .unwrap();
    let o = Command::new(bin())
        .args(["--replay", session.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("not valid") && !err.contains("panicked"),
        "{err}"
    );
}

#[test]
fn render_shaders_validate_without_gpu() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shaders/render");
    for name in ["terrain.wgsl", "lines.wgsl", "detail_amplitude.wgsl"] {
        let mut src = std::fs::read_to_string(dir.join(name)).unwrap();
        if name == "terrain.wgsl" {
            // The finer-than-a-cell octaves' functions are appended to it (`pipelines.rs`).
            src += &std::fs::read_to_string(dir.join("fine_detail.wgsl")).unwrap();
        }
        let module = naga::front::wgsl::parse_str(&src)
            .unwrap_or_else(|e| panic!("{name}: {}", e.emit_to_string(&src)));
        naga::valid::Validator::new(
            naga::valid::ValidationFlags::all(),
            naga::valid::Capabilities::default(),
        )
        .validate(&module)
        .unwrap_or_else(|e| panic!("{name}: {}", e.emit_to_string(&src)));
        assert!(src.starts_with("// Pass: "), "{name}: header comment");
    }
}

#[test]
fn bench_lod_reports_balanced_selection() {
    let o = Command::new(bin())
        .args(["bench", "lod", "--size", "256", "--frames", "30", "--json"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: Value = serde_json::from_slice(&o.stdout).expect("one JSON object");
    for key in [
        "select_us_median",
        "patches_median",
        "max_neighbour_level_diff",
        "triangles_median",
    ] {
        assert!(v.get(key).is_some(), "missing {key}");
    }
    assert!(v["max_neighbour_level_diff"].as_u64().unwrap() <= 1);
    assert!(v["patches_median"].as_u64().unwrap() > 0);
}

#[test]
fn missing_adapter_is_reported_clearly() {
    let dir = tempfile::tempdir().unwrap();
    let session = dir.path().join("s.json");
    std::fs::write(&session, r#"{ "format": "terrasketch-session", "version": 1, "size": 64, "events": [ { "wait": 1 } ] }"#).unwrap();
    let mut cmd = if std::env::var_os("DISPLAY").is_some() {
        Command::new(bin())
    } else {
        let mut c = Command::new("xvfb-run");
        c.args(["-a", "-s", "-screen 0 1280x800x24"]).arg(bin());
        c
    };
    let o = cmd
        .args(["--replay", session.to_str().unwrap()])
        .env("WGPU_ADAPTER_NAME", "no-such-gpu-anywhere")
        .env("TERRASKETCH_RECOVERY_DIR", dir.path())
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "expected a failure without an adapter");
    assert!(
        err.contains("no GPU adapter") && !err.contains("panicked"),
        "{err}"
    );
}

/// The realism pass session (also `examples/sessions/refine.json`): cancel, refine, undo / redo,
/// export, a stroke edit dropping the refined layer (and its undo), an edit during a refinement.
const REFINE_SESSION: &str = include_str!("../examples/sessions/refine.json");

/// Runs the realism pass session on `backend` and checks it. Tolerance of the constrained probes:
/// 0.1% of the relief of the example sketch's constraints (ridge top 1200 m, river end 120 m), a lower
/// bound of the terrain's relief.
fn refine_session(backend: &str) {
    let dir = tempfile::tempdir().unwrap();
    let session = dir.path().join("refine.json");
    let text = REFINE_SESSION.replace(r#""backend": "cpu""#, &format!(r#""backend": "{backend}""#));
    assert!(text.contains(&format!(r#""backend": "{backend}""#)));
    std::fs::write(&session, text).unwrap();
    let log_path = dir.path().join("frames.jsonl");
    let shots = dir.path().join("shots");
    // The exemplar features are cached in the temporary folder (cold cache: part of the cost).
    let cache = dir.path().join("cache");
    let t = std::time::Instant::now();
    let cmd_args = [
        "--replay",
        session.to_str().unwrap(),
        "--log",
        log_path.to_str().unwrap(),
        "--screenshots",
        shots.to_str().unwrap(),
    ];
    // Same as `run_editor`, plus the feature cache folder.
    let o = {
        let mut cmd = if std::env::var_os("DISPLAY").is_some() {
            Command::new(bin())
        } else {
            let mut c = Command::new("xvfb-run");
            c.args(["-a", "-s", "-screen 0 1280x800x24"]).arg(bin());
            c
        };
        cmd.args(cmd_args)
            .env("TERRASKETCH_RECOVERY_DIR", dir.path())
            .env("XDG_CACHE_HOME", &cache);
        if std::env::var_os("WGPU_BACKEND").is_none() {
            cmd.env("WGPU_BACKEND", "vulkan");
        }
        cmd.output()
            .expect("the terrasketch binary (or xvfb-run) runs")
    };
    assert_ran(&o);
    eprintln!(
        "refine session ({backend}): {:.1} s",
        t.elapsed().as_secs_f64()
    );
    let log = read_log(&log_path);
    let first = |m: &str| -> &Value {
        with_mark(&log, m)
            .first()
            .copied()
            .unwrap_or_else(|| panic!("no frame marked {m}"))
    };
    assert!(log.iter().all(|f| f["backend"] == backend));
    assert!(
        log.iter()
            .all(|f| f["errors"].as_array().is_some_and(|e| e.is_empty())),
        "errors logged"
    );
    let probes = |f: &Value| -> Vec<f64> {
        (0..8)
            .map(|i| probe(f, i).expect("probe height logged"))
            .collect()
    };
    let diffusion = first("diffusion");
    assert_eq!(diffusion["refine"]["state"], "idle");
    let h_diff = probes(diffusion);
    // Probes 0-2 lie on the plateau (450 m), the ridge's first point (about 700 m: the wiggle moves
    // it) and the river's last point (120 m).
    for (i, z, tol) in [(0, 450.0, 1.0), (1, 700.0, 10.0), (2, 120.0, 1.0)] {
        assert!(
            (h_diff[i] - z).abs() < tol,
            "probe {i} is not constrained: {} m",
            h_diff[i]
        );
    }
    // Cancel: the terrain, the history and the display are untouched.
    let cancelled = first("cancelled");
    assert_eq!(cancelled["refine"]["state"], "cancelled");
    assert_eq!(cancelled["compare_max_abs_m"].as_f64(), Some(0.0));
    assert_eq!(cancelled["undo_depth"], 0);
    assert_eq!(cancelled["refined_shown"], false);
    assert_eq!(probes(cancelled), h_diff);
    // While refining the editor keeps drawing frames, with the progress and stage.
    let running: Vec<&Value> = with_mark(&log, "refining")
        .into_iter()
        .filter(|f| f["refine"]["state"] == "running")
        .collect();
    assert!(
        running.len() >= 3,
        "only {} frames while refining",
        running.len()
    );
    let fr: Vec<f64> = running
        .iter()
        .map(|f| f["refine"]["progress"].as_f64().unwrap())
        .collect();
    assert!(fr.iter().all(|p| (0.0..=1.0).contains(p)));
    assert!(
        fr.windows(2).all(|w| w[1] >= w[0]),
        "progress goes back: {fr:?}"
    );
    assert!(
        running
            .iter()
            .all(|f| !f["refine"]["stage"].as_str().unwrap().is_empty())
    );
    // The refinement solves the sketch itself on the CPU: the CPU editor reads nothing back.
    if backend == "cpu" {
        assert!(log.iter().all(|f| f["bytes_down"] == 0));
    }
    // The refined terrain: shown, one undo step, constraints kept, the rest changed.
    let refined = first("refined");
    assert_eq!(refined["refine"]["state"], "done");
    assert!(refined["refine"]["patches"].as_u64().unwrap() > 0);
    assert_eq!(refined["refined_shown"], true);
    assert_eq!(refined["undo_depth"], 1);
    let h_ref = probes(refined);
    let relief = 1200.0 - 120.0;
    // Within the strokes' default height tolerance (2 m), where detail may play.
    for i in 0..3 {
        let d = (h_ref[i] - h_diff[i]).abs();
        assert!(
            d <= 2.0 + 1e-3 * relief,
            "constrained probe {i} moved by {d} m ({} -> {})",
            h_diff[i],
            h_ref[i]
        );
    }
    let moved = (3..8)
        .map(|i| (h_ref[i] - h_diff[i]).abs())
        .fold(0.0, f64::max);
    assert!(
        moved > 1.0,
        "the refinement changed no free probe ({moved} m)"
    );
    let (a, b) = (
        image::open(shots.join("diffusion.png")).unwrap().to_rgb8(),
        image::open(shots.join("refined.png")).unwrap().to_rgb8(),
    );
    let changed = a.pixels().zip(b.pixels()).filter(|(x, y)| x != y).count();
    assert!(
        changed > 2000,
        "the refined terrain changed only {changed} pixels"
    );
    // Undo: the diffusion terrain exactly; redo: the refined one exactly.
    let undone = first("undone_compared");
    assert_eq!(undone["refined_shown"], false);
    assert_eq!(undone["undo_depth"], 0);
    assert_eq!(undone["compare_max_abs_m"].as_f64(), Some(0.0));
    assert_eq!(probes(undone), h_diff);
    let redone = first("redone_compared");
    assert_eq!(redone["refined_shown"], true);
    assert_eq!(redone["compare_max_abs_m"].as_f64(), Some(0.0));
    assert_eq!(probes(redone), h_ref);
    // Export writes what is shown.
    let ed = terrasketch_raster::read_heightmap(&dir.path().join("diffusion.exr")).unwrap();
    let er = terrasketch_raster::read_heightmap(&dir.path().join("refined_export.exr")).unwrap();
    assert_eq!((ed.width, er.width), (128, 128));
    let max_d = ed
        .data
        .iter()
        .zip(&er.data)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0f32, f32::max);
    assert!(max_d > 1.0, "the export is the diffusion terrain");
    let (lo, hi) = ed
        .data
        .iter()
        .fold((f32::MAX, f32::MIN), |(l, h), &v| (l.min(v), h.max(v)));
    assert!(
        hi - lo >= relief as f32 - 1.0,
        "diffusion relief {}",
        hi - lo
    );
    // A stroke edit drops the refined layer (undoable); its undo brings the refined terrain back.
    let stroked = first("stroked");
    assert_eq!(stroked["refined_shown"], false);
    assert_eq!(stroked["undo_depth"], 2);
    assert_eq!(stroked["strokes"], 5);
    let back = first("stroke_undone_compared");
    assert_eq!(back["refined_shown"], true);
    assert_eq!(back["compare_max_abs_m"].as_f64(), Some(0.0));
    assert_eq!(back["strokes"], 4);
    // A refinement whose sketch was edited meanwhile is discarded.
    let edited = first("edited_while_refining");
    assert_eq!(edited["refine"]["state"], "discarded");
    assert_eq!(edited["refined_shown"], false);
    assert_eq!(edited["strokes"], 6);
}

#[test]
fn refine_cancel_undo_redo_export_via_replay_cpu_solver() {
    refine_session("cpu");
}

#[test]
fn refine_via_replay_gpu_solver_shows_the_refined_texture() {
    refine_session("gpu");
}

#[test]
fn height_tolerance_is_edited_saved_and_undone() {
    let dir = tempfile::tempdir().unwrap();
    let session = dir.path().join("s.json");
    std::fs::write(
        &session,
        r#"{ "format": "terrasketch-session", "version": 1, "sketch": "example", "size": 64, "backend": "cpu",
             "window_px": [320, 240], "autosave_s": 1000,
             "events": [ { "wait": 2 }, { "select": 0 }, { "set": { "height_tolerance_m": 7.5 } }, { "wait": 1 },
               { "save": "edited.json" }, { "wait": 1 }, { "key": "ctrl+z" }, { "wait": 1 },
               { "save": "undone.json" }, { "wait": 1 } ] }"#,
    )
    .unwrap();
    let o = run_editor(&["--replay", session.to_str().unwrap()], dir.path());
    assert_ran(&o);
    let tol = |f: &str| -> f64 {
        let text = std::fs::read_to_string(dir.path().join(f)).unwrap();
        let v: Value = serde_json::from_str(&text).unwrap();
        v["strokes"][0]["height_tolerance_m"].as_f64().unwrap()
    };
    assert_eq!(tol("edited.json"), 7.5);
    assert_eq!(
        tol("undone.json"),
        terrasketch_sketch::DEFAULT_HEIGHT_TOLERANCE_M
    );
}

/// The detail as drawn, probed at the same points with the CPU and the GPU solver: on, both agree
/// within 1e-3 of the relief and differ from the detail-off heights (`H` toggles it) on the slopes,
/// not on a ridge's crest (a hard elevation constraint).
#[test]
fn probes_see_the_same_detail_on_the_cpu_and_the_gpu_solver() {
    let dir = tempfile::tempdir().unwrap();
    let run = |backend: &str| {
        let session = format!(
            r#"{{
  "format": "terrasketch-session", "version": 1, "sketch": "example", "size": 256,
  "window_px": [640, 400], "backend": "{backend}",
  "probes_m": [[6000, 6000], [4000, 7000], [8500, 7000], [5500, 8500]],
  "events": [
    {{ "wait_converged": 200 }}, {{ "mark": "on" }}, {{ "wait": 2 }},
    {{ "key": "h" }}, {{ "wait": 2 }}, {{ "mark": "off" }}, {{ "wait": 2 }}
  ]
}}"#
        );
        let path = dir.path().join(format!("{backend}.json"));
        std::fs::write(&path, session).unwrap();
        let log = dir.path().join(format!("{backend}.jsonl"));
        let o = run_editor(
            &[
                "--replay",
                path.to_str().unwrap(),
                "--log",
                log.to_str().unwrap(),
            ],
            dir.path(),
        );
        assert_ran(&o);
        let log = read_log(&log);
        // "on": the first frame after convergence, before the key; "off": the last frame.
        let heights = |f: &Value| -> Vec<f64> {
            (0..4)
                .map(|i| probe(f, i).expect("a probe height"))
                .collect()
        };
        (
            heights(with_mark(&log, "on")[0]),
            heights(with_mark(&log, "off").last().unwrap()),
        )
    };
    let (cpu_on, cpu_off) = run("cpu");
    let (gpu_on, gpu_off) = run("gpu");
    // The example's relief is about 1300 m.
    let tol = 1e-3 * 1300.0;
    for i in 0..4 {
        assert!(
            (cpu_on[i] - gpu_on[i]).abs() < tol,
            "probe {i}: {cpu_on:?} vs {gpu_on:?}"
        );
        assert!(
            (cpu_off[i] - gpu_off[i]).abs() < tol,
            "probe {i}: {cpu_off:?} vs {gpu_off:?}"
        );
    }
    // The detail moves every slope probe; by its amplitude (tens of metres) where the noise is
    // not near one of its zeros, which a single point may be.
    let moved: Vec<f64> = (0..3).map(|i| (cpu_on[i] - cpu_off[i]).abs()).collect();
    assert!(
        moved.iter().all(|&m| m > 0.5) && moved.iter().filter(|&&m| m > 5.0).count() >= 2,
        "the detail moves the slope probes by {moved:?} m: {cpu_on:?} / {cpu_off:?}"
    );
    assert!(
        (cpu_on[3] - cpu_off[3]).abs() < 0.01,
        "no detail on the crest: {cpu_on:?} / {cpu_off:?}"
    );
}

/// Runs a replay session with the refine cache in `dir/cache`; returns its frame log.
fn run_logged(dir: &Path, name: &str, session: &str) -> Vec<Value> {
    let path = dir.join(format!("{name}.session.json"));
    std::fs::write(&path, session).unwrap();
    let log = dir.join(format!("{name}.jsonl"));
    let mut cmd = if std::env::var_os("DISPLAY").is_some() {
        Command::new(bin())
    } else {
        let mut c = Command::new("xvfb-run");
        c.args(["-a", "-s", "-screen 0 1280x800x24"]).arg(bin());
        c
    };
    cmd.args([
        "--replay",
        path.to_str().unwrap(),
        "--log",
        log.to_str().unwrap(),
    ])
    .env("TERRASKETCH_RECOVERY_DIR", dir)
    .env("XDG_CACHE_HOME", dir.join("cache"));
    if std::env::var_os("WGPU_BACKEND").is_none() {
        cmd.env("WGPU_BACKEND", "vulkan");
    }
    let o = cmd
        .output()
        .expect("the terrasketch binary (or xvfb-run) runs");
    assert_ran(&o);
    read_log(&log)
}

/// A small CPU session on `sketch` (size 128) with the refine session's probes.
fn persist_session(sketch: &str, events: &str) -> String {
    format!(
        r#"{{ "format": "terrasketch-session", "version": 1, "sketch": "{sketch}", "size": 128,
  "window_px": [640, 400], "solver_budget_wu": 4, "backend": "cpu", "camera": "top",
  "probes_m": [[1400, 1500], [1500, 7800], [9600, 1800], [5000, 500], [3000, 3500], [9000, 5000]],
  "events": [ {events} ] }}"#
    )
}

fn marked<'a>(log: &'a [Value], m: &str) -> &'a Value {
    with_mark(log, m)
        .first()
        .copied()
        .unwrap_or_else(|| panic!("no frame marked {m}"))
}

fn probes6(f: &Value) -> Vec<f64> {
    (0..6).map(|i| probe(f, i).expect("probe height")).collect()
}

fn refined_json(dir: &Path, file: &str) -> Value {
    let text = std::fs::read_to_string(dir.join(file)).unwrap();
    serde_json::from_str::<Value>(&text).unwrap()["refined"].clone()
}

/// Refine, save, reopen in a new editor process: the saved heights are loaded as they were; without
/// them (or with a stale file) the layer is made again from the sketch's record, bit for bit; a
/// stroke edit saves no record; a bad record is a warning and the plain sketch opens.
#[test]
fn refined_terrain_survives_save_and_reopen() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // A directory where the heights file of `fail.json` would go: its write fails.
    std::fs::create_dir(d.join("fail.refined.exr")).unwrap();
    let made = run_logged(
        d,
        "made",
        &persist_session(
            "example",
            r#"{ "wait_converged": 400 }, { "refine": { "seed": 3 } }, { "wait_refine": 20000 },
    { "mark": "refined" }, { "export": "made.exr" }, { "wait": 1 },
    { "save": "s.json" }, { "mark": "saved" }, { "wait": 1 }, { "save": "e.json" },
    { "save": "fail.json" }, { "mark": "save_failed" }, { "wait": 1 },
    { "tool": "ridge" }, { "move": [300, 200] }, { "press": { "at": [300, 200] } },
    { "drag_to": { "to": [440, 220], "frames": 4 } }, { "release": { "at": [440, 220] } },
    { "wait": 1 }, { "save": "e.json" }, { "mark": "edited" }, { "wait": 1 },
    { "key": "ctrl+z" }, { "wait": 1 }, { "save": "undone.json" }, { "mark": "undone" }, { "wait": 1 }"#,
        ),
    );
    let refined = marked(&made, "refined");
    assert_eq!(refined["refined_shown"], true);
    assert_eq!(refined["refined_origin"], "refined");
    assert_eq!(
        refined["dirty"], true,
        "the refined layer is an unsaved change"
    );
    let h_ref = probes6(refined);
    assert_eq!(marked(&made, "saved")["dirty"], false);
    let rec = refined_json(d, "s.json");
    assert_eq!(rec["seed"], 3);
    assert_eq!(rec["size"], 128);
    assert!(rec["exemplars"].as_array().is_some_and(|e| !e.is_empty()));
    assert!(rec["heights_digest"].is_string());
    assert!(d.join("s.refined.exr").is_file());
    // The heights file could not be written: a warning, the sketch saved with its record.
    let failed = marked(&made, "save_failed");
    assert!(
        failed["warnings"][0]
            .as_str()
            .is_some_and(|w| w.contains("fail.refined.exr")),
        "{failed}"
    );
    assert!(failed["errors"].as_array().unwrap().is_empty());
    let rec_fail = refined_json(d, "fail.json");
    assert_eq!(rec_fail["seed"], 3);
    assert!(rec_fail.get("heights_digest").is_none());
    // A stroke edit drops the layer: saving again writes no record and removes the heights file;
    // undo brings both back.
    let edited = marked(&made, "edited");
    assert_eq!(edited["refined_shown"], false);
    assert_eq!(edited["strokes"], 5);
    assert!(refined_json(d, "e.json").is_null());
    assert!(!d.join("e.refined.exr").exists());
    assert_eq!(marked(&made, "undone")["refined_shown"], true);
    assert_eq!(refined_json(d, "undone.json"), rec);
    let exported = |f: &str| terrasketch_raster::read_heightmap(&d.join(f)).unwrap().data;
    let want = exported("made.exr");

    // Reopen with the heights file: shown at once, exactly.
    let loaded = run_logged(
        d,
        "loaded",
        &persist_session(
            "s.json",
            r#"{ "wait": 2 }, { "mark": "reopened" }, { "export": "loaded.exr" }, { "wait": 1 }"#,
        ),
    );
    let f = marked(&loaded, "reopened");
    assert_eq!(f["refined_shown"], true);
    assert_eq!(f["refined_origin"], "loaded");
    assert_eq!(f["dirty"], false);
    let notice = loaded[0]["notice"].as_str().unwrap();
    assert!(notice.contains("refined terrain loaded from"), "{notice}");
    assert_eq!(probes6(f), h_ref);
    assert!(exported("loaded.exr") == want, "the loaded heights differ");

    // Without the heights file (fail.json), and with a stale one: recomputed, the same bits.
    let mut stale = terrasketch_raster::read_heightmap(&d.join("s.refined.exr")).unwrap();
    stale.data[100] += 5.0;
    std::fs::copy(d.join("s.json"), d.join("stale.json")).unwrap();
    terrasketch_raster::write_heightmap(&d.join("stale.refined.exr"), &stale).unwrap();
    for (name, why) in [("fail", "no heights file"), ("stale", "does not match")] {
        let log = run_logged(
            d,
            name,
            &persist_session(
                &format!("{name}.json"),
                &format!(
                    r#"{{ "wait": 1 }}, {{ "mark": "opened" }}, {{ "wait_refine": 20000 }}, {{ "mark": "recomputed" }},
    {{ "export": "{name}_out.exr" }}, {{ "wait": 1 }}"#
                ),
            ),
        );
        let opened = marked(&log, "opened");
        assert_eq!(opened["refined_origin"], "recomputing", "{name}");
        assert_eq!(
            opened["refined_shown"], false,
            "{name}: the stale file is not shown"
        );
        assert!(opened["notice"].as_str().unwrap().contains(why), "{opened}");
        let done = marked(&log, "recomputed");
        assert_eq!(done["refined_origin"], "recomputed", "{name}");
        assert_eq!(done["refined_shown"], true);
        assert_eq!(done["dirty"], false);
        assert_eq!(probes6(done), h_ref, "{name}");
        assert!(
            exported(&format!("{name}_out.exr")) == want,
            "{name}: other bits"
        );
    }

    // A corrupted record: a warning naming the field, the plain sketch.
    let text = std::fs::read_to_string(d.join("s.json")).unwrap();
    std::fs::write(
        d.join("bad.json"),
        text.replace("\"size\": 128", "\"size\": 100"),
    )
    .unwrap();
    let bad = run_logged(
        d,
        "bad",
        &persist_session(
            "bad.json",
            r#"{ "wait": 2 }, { "mark": "opened" }, { "wait": 1 },
    { "open": "s.json" }, { "mark": "open_event" }, { "wait": 1 }"#,
        ),
    );
    assert!(
        bad[0]["warnings"][0]
            .as_str()
            .is_some_and(|w| w.contains("refined.size")),
        "{}",
        bad[0]
    );
    let f = marked(&bad, "opened");
    assert_eq!(f["refined_shown"], false);
    assert!(f["refined_origin"].is_null());
    assert_eq!(f["strokes"], made[0]["strokes"]);
    assert!(
        bad.iter()
            .all(|f| f["errors"].as_array().unwrap().is_empty())
    );
    // Open (the menu's path) restores the saved layer too.
    let f = marked(&bad, "open_event");
    assert_eq!(f["refined_origin"], "loaded");
    assert_eq!(f["refined_shown"], true);
    assert_eq!(probes6(f), h_ref);
}
