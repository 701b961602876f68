//! Replay sessions (`terrasketch --replay SESSION.json`): the scripted input format and the frame log.
//!
//! The format is documented in `app/EDITOR.md`. A session drives the real editor: its input events go
//! through the same handlers as the window's, one input event per frame.

use std::collections::VecDeque;
use std::io::Write;
use std::path::{Path, PathBuf};

use std::time::Duration;

use anyhow::{Context, Result, bail};
use serde::{Deserialize, Serialize};

use super::budget::{DEFAULT_FRAME_BUDGET, FrameBudget};

/// A replay session file.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Session {
    /// Must be `"terrasketch-session"`.
    pub format: String,
    /// Must be 1.
    pub version: u32,
    /// The sketch to open: `"example"`, `"empty"` or a path relative to the session file. A FILE on the
    /// command line wins over this.
    #[serde(default)]
    pub sketch: Option<String>,
    /// Heightmap side (power of two, 64..=4096); default 1024, as interactive use.
    #[serde(default)]
    pub size: Option<usize>,
    /// Window inner size in pixels; default 640 x 400.
    #[serde(default)]
    pub window_px: Option<[u32; 2]>,
    /// Solver time budget per frame, milliseconds; default 10, as interactive use.
    #[serde(default)]
    pub solver_budget_ms: Option<f64>,
    /// Solver work budget per frame instead of a time budget, in reference work units (one
    /// level-0 sweep of a 1024^2 grid, whatever the session's size): the same frames on any
    /// machine (app/EDITOR.md says which work budget matches the default 10 ms).
    #[serde(default)]
    pub solver_budget_wu: Option<f64>,
    /// Log `lag_m` every frame: how far the displayed heights at the probes are from a converged
    /// solve of the current sketch (a side solver; costs a solve per edit, so off by default).
    #[serde(default)]
    pub lag: bool,
    /// Camera at start: `"frame_all"` (default, oblique) or `"top"`.
    #[serde(default)]
    pub camera: Option<String>,
    /// Probe points in world metres `[x, y]`; their heights are logged every frame.
    #[serde(default)]
    pub probes_m: Vec<[f64; 2]>,
    /// Probe points in window pixels, turned into world points once, on the first frame, by casting a
    /// ray onto the terrain (appended after `probes_m`).
    #[serde(default)]
    pub probes_px: Vec<[f32; 2]>,
    /// Recovery autosave every this many seconds, to the same place as interactive use, and the
    /// recovery offer at start (default: neither during a replay).
    #[serde(default)]
    pub autosave_s: Option<f64>,
    /// Solver backend: `"gpu"` (the default when the window's adapter can run it) or `"cpu"`.
    #[serde(default)]
    pub backend: Option<String>,
    /// The script.
    pub events: Vec<Event>,
}

/// Mouse buttons a session can press.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum Button {
    /// Tool button.
    #[default]
    Left,
    /// Orbit (fly mode: look).
    Right,
    /// Pan.
    Middle,
}

/// A press, at a window position.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Press {
    /// Window pixels.
    pub at: [f32; 2],
    /// Which button (default left).
    #[serde(default)]
    pub button: Button,
}

/// A release, optionally after a move.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Release {
    /// Window pixels (default: where the pointer is).
    #[serde(default)]
    pub at: Option<[f32; 2]>,
    /// Which button (default left).
    #[serde(default)]
    pub button: Button,
}

/// Pointer moves from the current position to `to`, one move per frame.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DragTo {
    /// Window pixels.
    pub to: [f32; 2],
    /// Frames (moves) to get there (at least 1).
    pub frames: u32,
}

/// Arguments of a `refine` event.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RefineEvent {
    /// Seed of the synthesis (default 1).
    #[serde(default = "default_seed")]
    pub seed: u64,
    /// Gain of the detail finer than the exemplars (0 to 4; default the refinement's).
    #[serde(default = "default_fine_detail")]
    pub fine_detail: f32,
}

fn default_fine_detail() -> f32 {
    terrasketch_synthesis::refine::RefineParams::default().fine_detail
}

fn default_seed() -> u64 {
    1
}

/// Press on a stroke's end handle (where it is drawn on screen at that frame).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PressHandle {
    /// Stroke index; negative counts from the end (-1 = last stroke).
    pub stroke: i64,
    /// `"first"` or `"last"` (the end handles), or `"middle"`: a point on the stroke halfway along
    /// its middle segment (with the select tool, a press there moves the whole stroke).
    pub end: String,
}

/// One scripted event. Input events (`move`, `press`, `press_handle`, `release`, `key`, `scroll`) take one
/// frame each, `drag_to` one frame per move, `wait` its frames; the others take none (they apply at the
/// start of the next frame).
#[derive(Debug, Clone, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum Event {
    /// Render this many frames.
    Wait(u32),
    /// Render frames until the solver has converged and finished its idle refinement (at most this
    /// many).
    WaitConverged(u32),
    /// Choose a tool: `ridge`, `valley`, `plateau`, `select`, `delete`.
    Tool(String),
    /// Move the pointer.
    Move([f32; 2]),
    /// Press a button.
    Press(Press),
    /// Press the left button on a stroke handle.
    PressHandle(PressHandle),
    /// Release a button (left unless given), after moving to `at` if given.
    Release(Release),
    /// Interpolated pointer moves.
    DragTo(DragTo),
    /// Interpolated pointer moves by an offset from the current position (`to` is the offset).
    DragBy(DragTo),
    /// Mouse wheel at the current pointer position (lines; positive zooms in).
    Scroll(f32),
    /// A key chord such as `"ctrl+z"`, `"delete"`, `"f"`.
    Key(String),
    /// Write a screenshot of the frame (file name inside `--screenshots DIR`).
    Screenshot(String),
    /// Label the following frames in the log (`mark` field).
    Mark(String),
    /// Save the sketch to this path (relative to the session file).
    Save(String),
    /// Open a sketch (relative to the session file); a bad file shows an error and changes nothing.
    Open(String),
    /// Export the heightmap (format from the extension), relative to the session file.
    Export(String),
    /// Select a stroke by index (negative from the end).
    Select(i64),
    /// Set attributes of the selected stroke (`slope_left_deg`, `slope_right_deg`, `width_m`,
    /// `roughness`), as one undoable edit.
    Set(serde_json::Map<String, serde_json::Value>),
    /// Keep a copy of the level-0 heights under a name.
    Snapshot(String),
    /// Log `compare_max_abs_m`: the largest difference between the heights and a snapshot.
    Compare(String),
    /// Resize the window's drawing surface as a resize event would (`[0, 0]` = minimised).
    Resize([u32; 2]),
    /// Answer the recovery offer as its dialog's buttons do: `"recover"` or `"discard"`.
    Recovery(String),
    /// Start the realism pass as the side panel's "Refine" button does (`{"refine": {"seed": 1}}`).
    Refine(RefineEvent),
    /// Cancel the running realism pass (as its Cancel button).
    CancelRefine(bool),
    /// Render frames until the running realism pass has ended (at most this many).
    WaitRefine(u32),
    /// Switch the solver as the side panel's buttons do: `"cpu"` (the CPU solver takes the current
    /// sketch from scratch, as after a GPU failure) or `"gpu"`.
    Solver(String),
    /// Destroy the GPU device (as a lost device): the editor keeps the sketch in the recovery file and
    /// ends with an error.
    DestroyDevice(bool),
    /// End the process at once, without the clean-exit steps (as a crash would: the recovery file
    /// stays). Exit status 3.
    Abort(bool),
}

impl Session {
    /// Reads and checks a session file.
    pub fn load(path: &Path) -> Result<Session> {
        let text = std::fs::read_to_string(path)
            .with_context(|| format!("cannot read session {}", path.display()))?;
        let s: Session = serde_json::from_str(&text)
            .with_context(|| format!("session {} is not valid", path.display()))?;
        if s.format != "terrasketch-session" || s.version != 1 {
            bail!(
                "session {}: format must be \"terrasketch-session\", version 1",
                path.display()
            );
        }
        if let Some(n) = s.size
            && (!n.is_power_of_two() || !(64..=4096).contains(&n))
        {
            bail!(
                "session {}: size must be a power of two from 64 to 4096, got {n}",
                path.display()
            );
        }
        if s.solver_budget_ms.is_some() && s.solver_budget_wu.is_some() {
            bail!(
                "session {}: give solver_budget_ms or solver_budget_wu, not both",
                path.display()
            );
        }
        if let Some(ms) = s.solver_budget_ms
            && !(ms.is_finite() && (0.1..=1000.0).contains(&ms))
        {
            bail!(
                "session {}: solver_budget_ms must be within 0.1..1000, got {ms}",
                path.display()
            );
        }
        if let Some(wu) = s.solver_budget_wu
            && !(wu.is_finite() && (0.01..=10_000.0).contains(&wu))
        {
            bail!(
                "session {}: solver_budget_wu must be within 0.01..10000, got {wu}",
                path.display()
            );
        }
        if let Some([w, h]) = s.window_px
            && (!(64..=8192).contains(&w) || !(64..=8192).contains(&h))
        {
            bail!(
                "session {}: window_px must be within 64..8192",
                path.display()
            );
        }
        Ok(s)
    }
}

impl Session {
    /// The solver's share of each frame: the work budget if given, else the time budget (default
    /// 10 ms).
    pub fn frame_budget(&self) -> FrameBudget {
        match (self.solver_budget_wu, self.solver_budget_ms) {
            (Some(wu), _) => FrameBudget::Work(wu),
            (None, Some(ms)) => FrameBudget::Time(Duration::from_secs_f64(ms / 1000.0)),
            (None, None) => FrameBudget::Time(DEFAULT_FRAME_BUDGET),
        }
    }
}

/// What one frame of the script asks for.
#[derive(Debug, Default)]
pub struct FrameScript {
    /// Events applied this frame (input last), in order.
    pub events: Vec<Event>,
    /// True when the script has ended (no frame to run).
    pub finished: bool,
}

/// Feeds a session's events frame by frame.
pub struct Player {
    queue: VecDeque<Event>,
    /// Remaining frames of a `wait`.
    wait_frames: u32,
    /// Remaining frames of a `wait_converged`.
    wait_converged: u32,
    /// Remaining frames of a `wait_refine`.
    wait_refine: u32,
    /// Remaining moves of a `drag_to`: target and count.
    drag: Option<([f32; 2], u32)>,
    /// Base folder for relative paths.
    pub base_dir: PathBuf,
}

impl Player {
    /// A player for `session`, resolving paths against `base_dir`.
    pub fn new(session: &Session, base_dir: PathBuf) -> Player {
        Player {
            queue: session.events.iter().cloned().collect(),
            wait_frames: 0,
            wait_converged: 0,
            wait_refine: 0,
            drag: None,
            base_dir,
        }
    }

    /// Resolves a session path.
    pub fn path(&self, p: &str) -> PathBuf {
        let p = Path::new(p);
        if p.is_absolute() {
            p.to_path_buf()
        } else {
            self.base_dir.join(p)
        }
    }

    /// Starts interpolated moves toward `to`; returns the first move.
    fn start_drag(&mut self, pointer: [f32; 2], to: [f32; 2], frames: u32) -> Event {
        let left = frames.max(1);
        let t = 1.0 / left as f32;
        let p = [
            pointer[0] + (to[0] - pointer[0]) * t,
            pointer[1] + (to[1] - pointer[1]) * t,
        ];
        self.drag = if left > 1 { Some((to, left - 1)) } else { None };
        Event::Move(p)
    }

    /// The events of the next frame. `pointer` is the current pointer position, `converged` whether
    /// the solver has converged, `refining` whether a realism pass runs.
    pub fn next_frame(
        &mut self,
        pointer: [f32; 2],
        converged: bool,
        refining: bool,
    ) -> FrameScript {
        let mut out = FrameScript::default();
        if self.wait_frames > 0 {
            self.wait_frames -= 1;
            return out;
        }
        if self.wait_converged > 0 {
            if !converged {
                self.wait_converged -= 1;
                return out;
            }
            self.wait_converged = 0;
        }
        if self.wait_refine > 0 {
            if refining {
                self.wait_refine -= 1;
                return out;
            }
            self.wait_refine = 0;
        }
        if let Some((to, left)) = self.drag {
            let t = 1.0 / left as f32;
            let p = [
                pointer[0] + (to[0] - pointer[0]) * t,
                pointer[1] + (to[1] - pointer[1]) * t,
            ];
            self.drag = if left > 1 { Some((to, left - 1)) } else { None };
            out.events.push(Event::Move(p));
            return out;
        }
        while let Some(e) = self.queue.pop_front() {
            match e {
                Event::Wait(n) => {
                    if n == 0 {
                        continue;
                    }
                    self.wait_frames = n - 1;
                    return out;
                }
                Event::WaitConverged(n) => {
                    if converged || n == 0 {
                        continue;
                    }
                    self.wait_converged = n - 1;
                    return out;
                }
                Event::WaitRefine(n) => {
                    // A `refine` queued this frame starts before the wait is looked at again,
                    // and so may an `open` (a saved refinement made again).
                    let starting = out
                        .events
                        .iter()
                        .any(|e| matches!(e, Event::Refine(_) | Event::Open(_)));
                    if !(refining || starting) || n == 0 {
                        continue;
                    }
                    self.wait_refine = n - 1;
                    return out;
                }
                Event::DragTo(d) => {
                    out.events.push(self.start_drag(pointer, d.to, d.frames));
                    return out;
                }
                Event::DragBy(d) => {
                    let to = [pointer[0] + d.to[0], pointer[1] + d.to[1]];
                    out.events.push(self.start_drag(pointer, to, d.frames));
                    return out;
                }
                Event::Move(_)
                | Event::Press(_)
                | Event::PressHandle(_)
                | Event::Release(_)
                | Event::Key(_)
                | Event::Scroll(_) => {
                    out.events.push(e);
                    return out;
                }
                other => out.events.push(other),
            }
        }
        out.finished = out.events.is_empty();
        out
    }
}

/// One line of the frame log.
#[derive(Debug, Clone, Serialize)]
pub struct FrameRecord {
    /// Frame number from 0.
    pub frame: u64,
    /// Wall time of the frame, milliseconds (input, solver, upload, selection, render).
    pub ms: f64,
    /// Current tool.
    pub tool: &'static str,
    /// Finest mip level the solver has ready (null before any).
    pub solver_finest_level: Option<u32>,
    /// Normalised residual (null before level 0 is ready).
    pub solver_residual: Option<f32>,
    /// Solver work this frame (heights + fields), in reference work units (one level-0 sweep of a
    /// 1024^2 grid).
    pub work_units: f64,
    /// Level-0 iterations (global corrections) of the shown solver this frame.
    pub solver_vcycles: u32,
    /// Wall time of the solver's step this frame, milliseconds.
    pub solver_ms: f64,
    /// GPU solver: compute dispatches this frame (0 on the CPU).
    pub gpu_dispatches: u64,
    /// GPU solver: `queue.submit` calls this frame.
    pub gpu_submits: u64,
    /// GPU solver: blocking waits for the device this frame (each drains the queue).
    pub gpu_blocking_waits: u64,
    /// GPU solver: estimated bytes its passes moved this frame (`GpuCounters`).
    pub gpu_bytes_moved_estimate: u64,
    /// GPU solver: this frame's solver work on the mid-range reference GPU by the paper model,
    /// milliseconds (`multigrid/ALGORITHM.md`; 0 on the CPU).
    pub gpu_paper_model_ms: f64,
    /// With the session's `lag`: the largest difference at the probes between the displayed
    /// heights and a converged solve of the current sketch, metres.
    pub lag_m: Option<f32>,
    /// True once the solver meets its tolerance.
    pub converged: bool,
    /// True once the idle refinement after convergence is done too.
    pub settled: bool,
    /// Patches drawn.
    pub patches: usize,
    /// Bytes written to the GPU this frame (heightmap rows, instances, uniforms, lines).
    pub bytes_up: u64,
    /// Bytes read back from the GPU this frame (0 with the CPU solver; screenshots not counted).
    pub bytes_down: u64,
    /// Strokes in the sketch.
    pub strokes: usize,
    /// Heights at the probe points, metres (null where no mip is ready).
    pub probe_heights_m: Vec<Option<f32>>,
    /// Probe points, world metres.
    pub probe_points_m: Vec<[f64; 2]>,
    /// True while the left button is held.
    pub pointer_down: bool,
    /// The last `mark` label.
    pub mark: String,
    /// Event names applied this frame.
    pub events: Vec<String>,
    /// Errors reported this frame.
    pub errors: Vec<String>,
    /// Screen positions of each stroke's first and last points (null when behind the camera).
    pub handles_px: Vec<[Option<[f32; 2]>; 2]>,
    /// Digest of the sketch (FNV-1a of its JSON), to compare documents.
    pub sketch_digest: String,
    /// True when the document has unsaved changes.
    pub dirty: bool,
    /// Undo steps available.
    pub undo_depth: usize,
    /// Result of a `compare` event this frame.
    pub compare_max_abs_m: Option<f32>,
    /// Window surface size in pixels.
    pub surface_px: [u32; 2],
    /// Width of the side panel over the left of the 3D view; the view is centred right of it.
    pub panel_px: f32,
    /// Solver backend this frame (`"gpu"` or `"cpu"`).
    pub backend: &'static str,
    /// A recovery file is being offered.
    pub recovery_offered: bool,
    /// The realism pass: `state` is `idle`, `running` (with `progress` 0..1 and `stage`), or how
    /// the last one ended: `done`, `cancelled`, `discarded` (the sketch changed meanwhile), `failed`.
    pub refine: RefineStatus,
    /// True while the refined layer is shown instead of the diffusion terrain.
    pub refined_shown: bool,
    /// Where the last refined layer came from: `refined` (made in this session), `loaded` (the
    /// heights file saved beside the opened sketch), `recomputing` / `recomputed` (made again
    /// from the opened sketch's record); null when none.
    pub refined_origin: Option<&'static str>,
    /// Warnings reported this frame (e.g. a refused refined record).
    pub warnings: Vec<String>,
    /// The status line's notice.
    pub notice: String,
}

/// State of the realism pass (frame log).
#[derive(Debug, Clone, Serialize)]
pub struct RefineStatus {
    /// `idle`, `running`, `done`, `cancelled`, `discarded` or `failed`.
    pub state: &'static str,
    /// Fraction done (running) or 1.
    pub progress: f32,
    /// Stage text.
    pub stage: String,
    /// Patches of the last refined result.
    pub patches: Option<usize>,
    /// Largest constraint error of the last refined result, metres.
    pub max_error_m: Option<f64>,
}

impl Default for RefineStatus {
    fn default() -> Self {
        RefineStatus {
            state: "idle",
            progress: 0.0,
            stage: String::new(),
            patches: None,
            max_error_m: None,
        }
    }
}

/// Appends JSON lines to a file.
pub struct FrameLog {
    out: std::io::BufWriter<std::fs::File>,
}

impl FrameLog {
    /// Creates (truncates) the log file.
    pub fn create(path: &Path) -> Result<FrameLog> {
        let f = std::fs::File::create(path)
            .with_context(|| format!("cannot create frame log {}", path.display()))?;
        Ok(FrameLog {
            out: std::io::BufWriter::new(f),
        })
    }

    /// Writes one record.
    pub fn write(&mut self, rec: &FrameRecord) -> Result<()> {
        serde_json::to_writer(&mut self.out, rec)?;
        self.out.write_all(b"\n")?;
        self.out.flush()?;
        Ok(())
    }
}

/// Short name of an event for the log.
pub fn event_name(e: &Event) -> String {
    match e {
        Event::Wait(n) => format!("wait {n}"),
        Event::WaitConverged(n) => format!("wait_converged {n}"),
        Event::Tool(t) => format!("tool {t}"),
        Event::Move(p) => format!("move {:.0},{:.0}", p[0], p[1]),
        Event::Press(p) => format!("press {:?} {:.0},{:.0}", p.button, p.at[0], p.at[1]),
        Event::PressHandle(p) => format!("press_handle {} {}", p.stroke, p.end),
        Event::Release(p) => format!("release {:?}", p.button),
        Event::DragTo(d) => format!("drag_to {:.0},{:.0}", d.to[0], d.to[1]),
        Event::DragBy(d) => format!("drag_by {:.0},{:.0}", d.to[0], d.to[1]),
        Event::Scroll(s) => format!("scroll {s}"),
        Event::Key(k) => format!("key {k}"),
        Event::Screenshot(s) => format!("screenshot {s}"),
        Event::Mark(m) => format!("mark {m}"),
        Event::Save(p) => format!("save {p}"),
        Event::Open(p) => format!("open {p}"),
        Event::Export(p) => format!("export {p}"),
        Event::Select(i) => format!("select {i}"),
        Event::Set(_) => "set".to_string(),
        Event::Snapshot(s) => format!("snapshot {s}"),
        Event::Compare(s) => format!("compare {s}"),
        Event::Resize(r) => format!("resize {}x{}", r[0], r[1]),
        Event::Recovery(a) => format!("recovery {a}"),
        Event::Abort(_) => "abort".to_string(),
        Event::Solver(s) => format!("solver {s}"),
        Event::DestroyDevice(_) => "destroy_device".to_string(),
        Event::Refine(r) => format!("refine {}", r.seed),
        Event::CancelRefine(_) => "cancel_refine".to_string(),
        Event::WaitRefine(n) => format!("wait_refine {n}"),
    }
}

/// FNV-1a 64 of a string, as 16 hex digits.
pub fn digest(text: &str) -> String {
    let mut h: u64 = 0xcbf29ce484222325;
    for b in text.bytes() {
        h ^= b as u64;
        h = h.wrapping_mul(0x100000001b3);
    }
    format!("{h:016x}")
}
