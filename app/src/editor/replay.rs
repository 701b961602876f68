//! Replay sessions applied to the editor: each scripted event goes through the same paths as the
//! window's input and the interface's actions.

use std::collections::HashMap;
use std::path::PathBuf;

use anyhow::Result;
use terrasketch_multigrid::Grid;

use super::EditorArgs;
use super::input::{Button, Input, normalize_chord};
use super::lag::LagProbe;
use super::session::{FrameLog, Player, Session};
use super::state::Editor;
use super::tools::Tool;
use super::ui::Action;

/// A replay session's state: the script's player, the frame log and what it records (probes,
/// snapshots, marks), pending screenshots.
pub struct Replay {
    /// Plays the session's events frame by frame.
    pub player: Player,
    /// The frame log (`--log`).
    pub log: Option<FrameLog>,
    /// Screenshot folder (`--screenshots`).
    pub screenshots: Option<PathBuf>,
    /// Probe points, metres (logged heights).
    pub probes_m: Vec<[f64; 2]>,
    /// Probe points in window pixels, placed on the terrain once it exists.
    pub probes_px: Vec<[f32; 2]>,
    /// Heights kept by `snapshot` events, by name.
    pub snapshots: HashMap<String, Vec<f32>>,
    /// The last `mark` (logged with each frame).
    pub mark: String,
    /// A screenshot to take at the end of this frame.
    pub screenshot: Option<String>,
    /// The last `compare`'s largest difference, logged once.
    pub compare: Option<f32>,
    /// The side solver behind the log's `lag_m` (sessions with `"lag": true`).
    pub lag: Option<LagProbe>,
}

impl Replay {
    /// Plays `s` (paths relative to `base_dir`) on a terrain of `grid`, logging to `args.log`.
    pub fn new(s: &Session, args: &EditorArgs, base_dir: PathBuf, grid: Grid) -> Result<Replay> {
        let log = match &args.log {
            Some(p) => Some(FrameLog::create(p)?),
            None => None,
        };
        let lag = if s.lag && log.is_some() {
            Some(LagProbe::new(grid)?)
        } else {
            None
        };
        Ok(Replay {
            player: Player::new(s, base_dir),
            log,
            screenshots: args.screenshots.clone(),
            probes_m: s.probes_m.clone(),
            probes_px: s.probes_px.clone(),
            snapshots: HashMap::new(),
            mark: String::new(),
            screenshot: None,
            compare: None,
            lag,
        })
    }
}

impl Editor {
    /// Applies one replay event (input events go through `input`).
    pub fn replay_event(&mut self, e: super::session::Event) {
        use super::session::Event as E;
        let resolve = |ed: &Editor, p: &str| {
            ed.replay
                .as_ref()
                .map(|r| r.player.path(p))
                .unwrap_or_else(|| PathBuf::from(p))
        };
        match e {
            E::Wait(_) | E::WaitConverged(_) | E::WaitRefine(_) | E::DragTo(_) | E::DragBy(_) => {}
            E::Refine(r) => self.act(Action::Refine(r.seed, r.fine_detail)),
            E::CancelRefine(true) => self.act(Action::CancelRefine),
            E::CancelRefine(false) => {}
            E::Tool(t) => match Tool::parse(&t) {
                Some(t) => self.tool = t,
                None => self.error(format!("session: unknown tool {t:?}")),
            },
            E::Move(p) => self.input(Input::Move(p)),
            E::Press(p) => self.input(Input::Press(p.button, p.at)),
            E::PressHandle(h) => self.press_handle(&h),
            E::Release(p) => {
                if let Some(at) = p.at {
                    self.input(Input::Move(at));
                }
                self.input(Input::Release(p.button));
            }
            E::Scroll(s) => self.input(Input::Scroll(s)),
            E::Key(k) => {
                self.input(Input::Key {
                    chord: k.clone(),
                    pressed: true,
                });
                let base = normalize_chord(&k)
                    .rsplit('+')
                    .next()
                    .unwrap_or_default()
                    .to_string();
                self.input(Input::Key {
                    chord: base,
                    pressed: false,
                });
            }
            E::Screenshot(name) => {
                if let Some(r) = self.replay.as_mut() {
                    r.screenshot = Some(name);
                }
            }
            E::Mark(m) => {
                if let Some(r) = self.replay.as_mut() {
                    r.mark = m;
                }
            }
            E::Save(p) => {
                let p = resolve(self, &p);
                self.save_to(&p)
            }
            E::Open(p) => {
                let p = resolve(self, &p);
                self.open(&p)
            }
            E::Export(p) => {
                let p = resolve(self, &p);
                self.export(&p)
            }
            E::Select(i) => {
                let n = self.doc.sketch.strokes.len() as i64;
                let i = if i < 0 { n + i } else { i };
                self.act(Action::Select(usize::try_from(i).ok()));
            }
            E::Set(map) => self.set_attributes(&map),
            E::Snapshot(name) => self.snapshot(name),
            E::Compare(name) => self.compare(&name),
            E::Resize([w, h]) => self.resize(w, h),
            E::Recovery(answer) => self.answer_recovery(&answer),
            E::Solver(s) if s == "cpu" => self.act(Action::SolverCpu),
            E::Solver(s) if s == "gpu" => self.act(Action::SolverGpu),
            E::Solver(s) => self.error(format!(
                "session: solver {s:?}: only \"cpu\" can be switched to during a session"
            )),
            E::DestroyDevice(true) => self.gfx.gpu.device.destroy(),
            E::DestroyDevice(false) => {}
            E::Abort(true) => std::process::exit(3),
            E::Abort(false) => {}
        }
    }

    /// Presses the left button on a stroke's handle (`first`, `last`) or on its middle segment
    /// (`middle`), after moving the pointer there.
    fn press_handle(&mut self, h: &super::session::PressHandle) {
        let n = self.doc.sketch.strokes.len() as i64;
        let i = if h.stroke < 0 { n + h.stroke } else { h.stroke };
        let Some(s) = usize::try_from(i)
            .ok()
            .and_then(|i| self.doc.sketch.strokes.get(i))
        else {
            return self.error(format!("session: no stroke {}", h.stroke));
        };
        let p = match h.end.as_str() {
            "first" => s.points[0],
            "last" => s.points[s.points.len() - 1],
            "middle" => {
                // Halfway along the middle segment: on the stroke, away from its handles.
                let m = (s.points.len() / 2).max(1);
                let (a, b) = (s.points[m - 1], s.points[(m).min(s.points.len() - 1)]);
                [
                    0.5 * (a[0] + b[0]),
                    0.5 * (a[1] + b[1]),
                    0.5 * (a[2] + b[2]),
                ]
            }
            other => {
                return self.error(format!(
                    "session: press_handle end must be \"first\", \"last\" or \"middle\", got {other:?}"
                ));
            }
        };
        let proj = self.projection();
        match proj.screen_position(glam::Vec3::new(p[0] as f32, p[1] as f32, p[2] as f32)) {
            Some(px) => {
                self.input(Input::Move(px.to_array()));
                self.input(Input::Press(Button::Left, px.to_array()));
            }
            None => self.error("session: the handle is behind the camera".into()),
        }
    }

    /// Keeps the shown heights under `name`.
    fn snapshot(&mut self, name: String) {
        self.sync_refined();
        let h = match self.terrain.heights() {
            Ok(h) => h,
            Err(e) => return self.error(format!("snapshot: {e:#}")),
        };
        if let Some(r) = self.replay.as_mut() {
            r.snapshots.insert(name, h);
        }
    }

    /// Logs the largest difference between the shown heights and snapshot `name`.
    fn compare(&mut self, name: &str) {
        self.sync_refined();
        let h = match self.terrain.heights() {
            Ok(h) => h,
            Err(e) => return self.error(format!("compare: {e:#}")),
        };
        let d = self
            .replay
            .as_ref()
            .and_then(|r| r.snapshots.get(name))
            .map(|s| {
                s.iter()
                    .zip(h)
                    .map(|(a, b)| (a - b).abs())
                    .fold(0.0f32, f32::max)
            });
        match d {
            Some(d) => {
                if let Some(r) = self.replay.as_mut() {
                    r.compare = Some(d);
                }
            }
            None => self.error(format!("session: no snapshot {name:?}")),
        }
    }

    /// Answers the recovery offer (`recover` or `discard`).
    fn answer_recovery(&mut self, answer: &str) {
        let Some(path) = self.ui.recovery_offer.take() else {
            return self.error("session: no recovery file is offered".into());
        };
        match answer {
            "recover" => self.act(Action::Recover(path)),
            "discard" => self.act(Action::DiscardRecovery(path)),
            other => {
                self.ui.recovery_offer = Some(path);
                self.error(format!(
                    "session: recovery answer {other:?} is not \"recover\" or \"discard\""
                ))
            }
        }
    }

    pub(super) fn set_attributes(&mut self, map: &serde_json::Map<String, serde_json::Value>) {
        let Some(i) = self.doc.selected else {
            return self.error("session: set needs a selected stroke".into());
        };
        let s = &self.doc.sketch.strokes[i];
        let mut v = [
            s.slope_left_deg,
            s.slope_right_deg,
            s.width_m,
            s.roughness,
            s.height_tolerance_m,
        ];
        for (k, val) in map {
            let Some(x) = val.as_f64() else {
                return self.error(format!("session: {k} must be a number"));
            };
            match k.as_str() {
                "slope_left_deg" => v[0] = x,
                "slope_right_deg" => v[1] = x,
                "width_m" => v[2] = x,
                "roughness" => v[3] = x,
                "height_tolerance_m" => v[4] = x,
                _ => return self.error(format!("session: unknown attribute {k:?}")),
            }
        }
        self.act(Action::Attributes(i, v));
        self.commit_attributes();
    }
}
