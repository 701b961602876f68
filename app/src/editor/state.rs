//! The editor: UI state (document, tool, camera, dialogs), the terrain solver and the GPU renderers,
//! and what input and actions do to them. The per-frame pipeline is in `frame.rs`.

use std::collections::{HashMap, HashSet};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::Result;
use glam::Vec2;
use terrasketch_quadtree::{LodSettings, Selection};
use terrasketch_sketch::{Sketch, example_sketch};
use winit::event::{ElementState, MouseButton, MouseScrollDelta, WindowEvent};
use winit::event_loop::ActiveEventLoop;
use winit::keyboard::ModifiersState;
use winit::window::Window;

use super::EditorArgs;
use super::budget::FrameBudget;
use super::camera::ViewCamera;
use super::doc::Document;
use super::files::{self, Autosave};
use super::gpu::Gpu;
use super::input::{Button, Input, chord, key_name, normalize_chord};
use super::lag::LagProbe;
use super::render::SceneRenderer;
use super::session::{FrameLog, Player, Session};
use super::terrain::Terrain;
use super::tools::{self, Gesture, Tool};
use super::ui::{Action, PathKind, UiState, ViewOptions};

/// Heightmap side of the interactive editor (sessions choose their own).
pub const DEFAULT_SIZE: usize = 1024;

/// Replay state.
pub struct Replay {
    pub player: Player,
    pub log: Option<FrameLog>,
    pub screenshots: Option<PathBuf>,
    pub probes_m: Vec<[f64; 2]>,
    pub probes_px: Vec<[f32; 2]>,
    pub snapshots: HashMap<String, Vec<f32>>,
    pub mark: String,
    pub screenshot: Option<String>,
    pub compare: Option<f32>,
    /// The side solver behind the log's `lag_m` (sessions with `"lag": true`).
    pub lag: Option<LagProbe>,
}

/// The whole editor.
pub struct Editor {
    pub window: Arc<Window>,
    pub doc: Document,
    pub tool: Tool,
    pub gesture: Gesture,
    pub camera: ViewCamera,
    pub view: ViewOptions,
    pub ui: UiState,
    pub pointer: Vec2,
    pub left_down: bool,
    pub right_down: bool,
    pub middle_down: bool,
    pub modifiers: ModifiersState,
    pub held: HashSet<String>,
    /// Sketch before a live attribute edit (committed when the slider is let go).
    pub attr_before: Option<Sketch>,
    pub terrain: Terrain,
    /// The solver's share of each frame.
    pub budget: FrameBudget,
    pub gpu: Gpu,
    pub scene: SceneRenderer,
    pub egui_ctx: egui::Context,
    pub egui_state: egui_winit::State,
    pub egui_renderer: egui_wgpu::Renderer,
    pub selection: Selection,
    pub settings: LodSettings,
    pub frame_no: u64,
    pub last_frame: Instant,
    /// Width in pixels of the side panel covering the left of the 3D view (from the last UI frame).
    pub panel_px: f32,
    pub status: super::ui::Status,
    /// Errors raised this frame (logged, shown).
    pub errors: Vec<String>,
    /// Warnings raised this frame (logged, shown as the notice).
    pub warnings: Vec<String>,
    /// Where the shown refined layer came from: `refined` (this session), `loaded` (the heights
    /// file saved beside the sketch), `recomputing` / `recomputed` (from the sketch's record).
    pub refined_origin: Option<&'static str>,
    /// Level-0 rows of the constraint overlay to upload.
    pub overlay_rows: Option<std::ops::Range<usize>>,
    pub replay: Option<Replay>,
    pub autosave: Autosave,
    /// The GPU device was lost: the editor ends, keeping the recovery file.
    pub device_lost: bool,
    /// The realism pass running in the background.
    pub refine_job: Option<super::refine::RefineJob>,
    /// The realism pass's state for the log and the interface.
    pub refine_status: super::session::RefineStatus,
    pub done: bool,
    pub result: Result<()>,
}

fn stroke_z_range(s: &Sketch) -> [f32; 2] {
    let mut r = [s.base_elevation_m as f32; 2];
    for st in &s.strokes {
        for p in &st.points {
            r[0] = r[0].min(p[2] as f32);
            r[1] = r[1].max(p[2] as f32);
        }
    }
    r
}

impl Editor {
    /// Opens the GPU, loads the sketch, builds the renderers.
    pub fn new(
        window: Arc<Window>,
        display: Box<dyn wgpu::wgt::WgpuHasDisplayHandle>,
        args: &EditorArgs,
        session: Option<Session>,
    ) -> Result<Editor> {
        let gpu = Gpu::new(window.clone(), display)?;
        let mut errors = Vec::new();
        let base_dir = args
            .replay
            .as_ref()
            .and_then(|p| p.parent())
            .map(Path::to_path_buf)
            .unwrap_or_else(|| PathBuf::from("."));
        let resolve = |p: &str| {
            if Path::new(p).is_absolute() {
                PathBuf::from(p)
            } else {
                base_dir.join(p)
            }
        };
        let empty = || files::Opened {
            sketch: Sketch::empty(example_sketch().extent_m, 0.0),
            refined: None,
            warnings: Vec::new(),
        };
        let example = || files::Opened {
            sketch: example_sketch(),
            ..empty()
        };
        let (opened, path) = match (&args.file, session.as_ref().and_then(|s| s.sketch.clone())) {
            (Some(f), _) => match files::open_sketch(f) {
                Ok(s) => (s, Some(f.clone())),
                Err(e) => {
                    errors.push(format!("{e:#}; opened an empty sketch instead"));
                    (empty(), None)
                }
            },
            (None, Some(name)) if name == "example" => (example(), None),
            (None, Some(name)) if name == "empty" => (empty(), None),
            (None, Some(name)) => match files::open_sketch(&resolve(&name)) {
                Ok(s) => (s, Some(resolve(&name))),
                Err(e) => {
                    errors.push(format!("{e:#}; opened an empty sketch instead"));
                    (empty(), None)
                }
            },
            (None, None) => (example(), None),
        };
        let files::Opened {
            sketch,
            refined: record,
            warnings: open_warnings,
        } = opened;
        let size = session
            .as_ref()
            .and_then(|s| s.size)
            .unwrap_or(DEFAULT_SIZE);
        // Solver backend: the session's or $TERRASKETCH_SOLVER ("cpu" / "gpu"); by default the GPU
        // when the window's device can run it, but the CPU on a software adapter (lavapipe,
        // llvmpipe, WARP), which runs the GPU solver 10-20 times slower than the CPU solver.
        let wanted = session
            .as_ref()
            .and_then(|s| s.backend.clone())
            .or_else(|| std::env::var("TERRASKETCH_SOLVER").ok());
        let software = gpu.adapter_info.device_type == wgpu::DeviceType::Cpu;
        let mut notice = String::new();
        let want_gpu = match wanted.as_deref() {
            Some("gpu") => true,
            Some("cpu") => false,
            None if software => {
                notice = "software adapter: CPU solver (the side panel switches to the GPU solver)"
                    .to_string();
                false
            }
            None => true,
            Some(other) => {
                errors.push(format!(
                    "unknown solver backend {other:?} (expected \"gpu\" or \"cpu\"); using the default"
                ));
                !software
            }
        };
        let ctx = if want_gpu { gpu.solver_context() } else { None };
        if want_gpu && ctx.is_none() {
            errors.push(format!(
                "the GPU solver cannot run on {}: using the CPU solver",
                gpu.adapter_name
            ));
        }
        let terrain = match Terrain::new(&sketch, size, ctx.as_ref()) {
            Ok(t) => t,
            Err(e) if ctx.is_some() => {
                errors.push(format!("{e:#}: using the CPU solver"));
                Terrain::new(&sketch, size, None)?
            }
            Err(e) => return Err(e),
        };
        let settings =
            LodSettings::new(size, [sketch.extent_m[0] as f32, sketch.extent_m[1] as f32]);
        let scene = SceneRenderer::new(
            &gpu.device,
            gpu.config.format,
            size as u32,
            settings.leaf_cells as u32,
            terrain.gpu_texture(),
        );
        let egui_ctx = egui::Context::default();
        let max_tex = gpu.device.limits().max_texture_dimension_2d as usize;
        let egui_state = egui_winit::State::new(
            egui_ctx.clone(),
            egui::ViewportId::ROOT,
            &window,
            Some(window.scale_factor() as f32),
            None,
            Some(max_tex),
        );
        let egui_renderer = egui_wgpu::Renderer::new(
            &gpu.device,
            gpu.config.format,
            egui_wgpu::RendererOptions::default(),
        );
        let mut camera = ViewCamera::framing(sketch.extent_m, stroke_z_range(&sketch));
        let budget = match session.as_ref() {
            Some(s) => s.frame_budget(),
            None => FrameBudget::Time(super::budget::DEFAULT_FRAME_BUDGET),
        };
        let mut ui = UiState::default();
        let session_autosave = session.as_ref().and_then(|s| s.autosave_s);
        let replay = match session {
            Some(s) => {
                if s.camera.as_deref() == Some("top") {
                    camera.top_view();
                }
                let log_wanted = args.log.is_some();
                let log = match &args.log {
                    Some(p) => Some(FrameLog::create(p)?),
                    None => None,
                };
                Some(Replay {
                    player: Player::new(&s, base_dir.clone()),
                    log,
                    screenshots: args.screenshots.clone(),
                    probes_m: s.probes_m.clone(),
                    probes_px: s.probes_px.clone(),
                    snapshots: HashMap::new(),
                    mark: String::new(),
                    screenshot: None,
                    compare: None,
                    lag: if s.lag && log_wanted {
                        Some(LagProbe::new(terrain.grid)?)
                    } else {
                        None
                    },
                })
            }
            None => None,
        };
        let replay_autosave = session_autosave
            .filter(|s| s.is_finite() && *s > 0.0)
            .map(|s| Duration::from_secs_f64(s.min(3600.0)));
        let autosave = if let Some(every) = replay_autosave {
            let p = files::recovery_path();
            if let Some(p) = p.as_ref().filter(|p| p.exists()) {
                ui.recovery_offer = Some(p.clone());
            }
            Autosave::with_interval(p, every)
        } else if replay.is_some() {
            Autosave::new(None)
        } else {
            let p = files::recovery_path();
            if let Some(p) = p.as_ref().filter(|p| p.exists()) {
                ui.recovery_offer = Some(p.clone());
            }
            Autosave::new(p)
        };
        for e in &errors {
            eprintln!("terrasketch: error: {e}");
        }
        ui.error = errors.first().cloned();
        ui.notice = notice;
        let status = super::ui::Status {
            size,
            adapter: gpu.adapter_name.clone(),
            backend: terrain.backend_name().to_string(),
            ..Default::default()
        };
        let mut editor = Editor {
            window,
            doc: Document::new(sketch, path.clone()),
            tool: Tool::Ridge,
            gesture: Gesture::Idle,
            camera,
            view: ViewOptions::default(),
            ui,
            pointer: Vec2::ZERO,
            left_down: false,
            right_down: false,
            middle_down: false,
            modifiers: ModifiersState::empty(),
            held: HashSet::new(),
            attr_before: None,
            terrain,
            budget,
            gpu,
            scene,
            egui_ctx,
            egui_state,
            egui_renderer,
            selection: Selection::new(),
            settings,
            frame_no: 0,
            last_frame: Instant::now(),
            panel_px: 0.0,
            status,
            errors,
            warnings: Vec::new(),
            refined_origin: None,
            overlay_rows: Some(0..size),
            replay,
            autosave,
            device_lost: false,
            refine_job: None,
            refine_status: Default::default(),
            done: false,
            result: Ok(()),
        };
        for w in open_warnings {
            editor.warn(w);
        }
        if let (Some(record), Some(path)) = (record, path) {
            editor.restore_refined(record, &path);
        }
        Ok(editor)
    }

    /// True once the editor should close.
    pub fn finished(&self) -> bool {
        self.done
    }

    /// The run's result (errors that end the editor).
    pub fn take_result(&mut self) -> Result<()> {
        std::mem::replace(&mut self.result, Ok(()))
    }

    /// Clean exit: the recovery file is no longer needed.
    pub fn shutdown(&mut self) {
        if !self.device_lost {
            self.autosave.clear();
        }
    }

    /// True while something changes on screen by itself.
    pub fn wants_frames(&self) -> bool {
        self.replay.is_some()
            || !self.terrain.settled()
            || self.left_down
            || self.right_down
            || self.middle_down
            || self.refine_job.is_some()
            || (self.camera.fly && !self.held.is_empty())
    }

    /// Asks for the next frame; without a drawable surface (minimised) runs it directly.
    pub fn request_redraw(&mut self) {
        if self.gpu.drawable() {
            self.window.request_redraw();
        } else if self.replay.is_some() || !self.terrain.settled() {
            self.frame();
        }
    }

    /// A window event.
    pub fn window_event(&mut self, _el: &ActiveEventLoop, event: WindowEvent) {
        let egui_resp = self.egui_state.on_window_event(&self.window, &event);
        let is_input = matches!(
            event,
            WindowEvent::CursorMoved { .. }
                | WindowEvent::MouseInput { .. }
                | WindowEvent::MouseWheel { .. }
                | WindowEvent::KeyboardInput { .. }
        );
        match event {
            WindowEvent::CloseRequested => {
                if self.doc.dirty && self.replay.is_none() {
                    self.ui.confirm_close = true;
                    self.window.request_redraw();
                } else {
                    self.done = true;
                }
            }
            WindowEvent::Resized(size) => self.resize(size.width, size.height),
            WindowEvent::RedrawRequested => self.frame(),
            WindowEvent::ModifiersChanged(m) => self.modifiers = m.state(),
            WindowEvent::CursorMoved { position, .. } => {
                self.input(Input::Move([position.x as f32, position.y as f32]));
            }
            WindowEvent::MouseInput { state, button, .. } => {
                let b = match button {
                    MouseButton::Left => Button::Left,
                    MouseButton::Right => Button::Right,
                    MouseButton::Middle => Button::Middle,
                    _ => return,
                };
                match state {
                    ElementState::Pressed
                        if !egui_resp.consumed && !self.egui_ctx.is_pointer_over_egui() =>
                    {
                        self.input(Input::Press(b, self.pointer.to_array()))
                    }
                    ElementState::Released => self.input(Input::Release(b)),
                    _ => {}
                }
            }
            WindowEvent::MouseWheel { delta, .. }
                if !egui_resp.consumed && !self.egui_ctx.is_pointer_over_egui() =>
            {
                let lines = match delta {
                    MouseScrollDelta::LineDelta(_, y) => y,
                    MouseScrollDelta::PixelDelta(p) => p.y as f32 / 40.0,
                };
                self.input(Input::Scroll(lines));
            }
            WindowEvent::KeyboardInput { event, .. }
                if !egui_resp.consumed && !self.egui_ctx.egui_wants_keyboard_input() =>
            {
                if let Some(name) = key_name(&event.logical_key) {
                    let pressed = event.state == ElementState::Pressed;
                    if pressed && event.repeat {
                        return;
                    }
                    let c = if pressed {
                        chord(&name, self.modifiers)
                    } else {
                        name
                    };
                    self.input(Input::Key { chord: c, pressed });
                }
            }
            _ => {}
        }
        if egui_resp.repaint || is_input {
            self.window.request_redraw();
        }
    }

    /// Surface resize (0 x 0 = minimised: frames run without drawing).
    pub fn resize(&mut self, width: u32, height: u32) {
        self.gpu.resize(width, height);
    }

    /// One input event (window or replay).
    pub fn input(&mut self, input: Input) {
        let proj = self.projection();
        match input {
            Input::Move(p) => {
                let p = Vec2::from(p);
                let delta = p - self.pointer;
                self.pointer = p;
                if self.left_down {
                    let rows =
                        tools::update(&mut self.gesture, p, &mut self.doc, &self.terrain, &proj);
                    self.resolve(rows);
                }
                if self.right_down && !self.modifiers.shift_key() {
                    self.camera.rotate(delta);
                } else if self.middle_down || (self.right_down && self.modifiers.shift_key()) {
                    self.camera.pan(delta, proj.viewport_px);
                }
            }
            Input::Press(b, p) => {
                self.pointer = Vec2::from(p);
                match b {
                    Button::Left => {
                        self.left_down = true;
                        let (g, rows) = tools::begin(
                            self.tool,
                            self.pointer,
                            &mut self.doc,
                            &self.terrain,
                            &proj,
                        );
                        self.gesture = g;
                        self.resolve(rows);
                    }
                    Button::Right => self.right_down = true,
                    Button::Middle => self.middle_down = true,
                }
            }
            Input::Release(b) => match b {
                Button::Left => {
                    self.left_down = false;
                    let g = std::mem::replace(&mut self.gesture, Gesture::Idle);
                    tools::end(g, &mut self.doc);
                }
                Button::Right => self.right_down = false,
                Button::Middle => self.middle_down = false,
            },
            Input::Scroll(lines) => {
                let toward = self
                    .terrain
                    .field()
                    .and_then(|f| f.raycast(&proj.ray(self.pointer)));
                self.camera.zoom_to(0.85f32.powf(lines), toward);
            }
            Input::Key { chord, pressed } => {
                let chord = normalize_chord(&chord);
                if !pressed {
                    self.held.remove(&chord);
                    return;
                }
                if ["w", "a", "s", "d", "q", "e"].contains(&chord.as_str()) {
                    self.held.insert(chord.clone());
                }
                self.shortcut(&chord);
            }
        }
    }

    fn shortcut(&mut self, chord: &str) {
        let action = match chord {
            "ctrl+z" => Some(Action::Undo),
            "ctrl+y" | "ctrl+shift+z" => Some(Action::Redo),
            "ctrl+s" => Some(Action::Save),
            "ctrl+shift+s" => {
                self.ui.path_dialog = Some((PathKind::SaveAs, String::new()));
                None
            }
            "ctrl+o" => {
                self.ui.path_dialog = Some((PathKind::Open, String::new()));
                None
            }
            "ctrl+e" => {
                self.ui.path_dialog = Some((PathKind::Export, "heightmap.exr".into()));
                None
            }
            "1" | "2" | "3" | "4" | "5" => chord
                .parse::<usize>()
                .ok()
                .map(|i| Action::Tool(Tool::ALL[i - 1])),
            "f" if !self.camera.fly => Some(Action::FrameAll),
            "t" => Some(Action::TopView),
            "h" => {
                self.view.detail = !self.view.detail;
                None
            }
            "g" => Some(Action::Fly),
            "delete" | "backspace" => self.doc.selected.map(Action::Delete),
            "escape" => {
                let g = std::mem::replace(&mut self.gesture, Gesture::Idle);
                let rows = tools::cancel(g, &mut self.doc, &self.terrain);
                self.resolve(rows);
                None
            }
            _ => None,
        };
        if let Some(a) = action {
            self.act(a);
        }
    }

    /// Re-solves warm after an edit of `rows`.
    pub fn resolve(&mut self, rows: std::ops::Range<usize>) {
        if rows.is_empty() {
            return;
        }
        self.overlay_rows = Some(match self.overlay_rows.take() {
            Some(o) => o.start.min(rows.start)..o.end.max(rows.end),
            None => rows.clone(),
        });
        self.terrain.update(rows);
    }

    /// Reports a warning once: stderr, the frame log, the notice line.
    pub fn warn(&mut self, msg: String) {
        eprintln!("terrasketch: warning: {msg}");
        self.ui.notice = msg.clone();
        self.warnings.push(msg);
    }

    /// Reports an error once: stderr, the frame log, the error dialog.
    pub fn error(&mut self, msg: String) {
        eprintln!("terrasketch: error: {msg}");
        self.ui.error = Some(msg.clone());
        self.errors.push(msg);
    }

    /// Does what the interface (or a shortcut) asked.
    pub fn act(&mut self, action: Action) {
        let busy = !matches!(self.gesture, Gesture::Idle);
        match action {
            Action::Tool(t) => self.tool = t,
            Action::Undo | Action::Redo if busy => {}
            Action::Undo | Action::Redo => {
                self.commit_attributes();
                let old = if matches!(action, Action::Undo) {
                    self.doc.undo()
                } else {
                    self.doc.redo()
                };
                if let Some(old) = old {
                    let rows = self.terrain.diff_rows(&old, &self.doc.sketch);
                    self.resolve(rows);
                }
            }
            Action::Open(p) => self.open(&p),
            Action::Save => match self.doc.path.clone() {
                Some(p) => self.save_to(&p),
                None => self.ui.path_dialog = Some((PathKind::SaveAs, String::new())),
            },
            Action::SaveAs(p) => self.save_to(&p),
            Action::Export(p) => self.export(&p),
            Action::FrameAll => self
                .camera
                .frame_all(self.doc.sketch.extent_m, self.terrain.z_range()),
            Action::TopView => self.camera.top_view(),
            Action::Fly => self.camera.fly = !self.camera.fly,
            Action::Select(i) => {
                self.doc.selected = i.filter(|&i| i < self.doc.sketch.strokes.len())
            }
            Action::Delete(i) if !busy => {
                self.commit_attributes();
                let rows = tools::delete_stroke(&mut self.doc, &self.terrain, i);
                self.resolve(rows);
            }
            Action::Delete(_) => {}
            Action::Attributes(i, v) if !busy && i < self.doc.sketch.strokes.len() => {
                if self.attr_before.is_none() {
                    self.attr_before = Some(self.doc.sketch.clone());
                }
                let before = self.doc.sketch.clone();
                let s = &mut self.doc.sketch.strokes[i];
                s.slope_left_deg = v[0].clamp(0.0, 85.0);
                s.slope_right_deg = v[1].clamp(0.0, 85.0);
                s.width_m = v[2].max(1e-3);
                s.roughness = v[3].clamp(0.0, 1.0);
                s.height_tolerance_m = v[4].clamp(0.0, terrasketch_sketch::MAX_HEIGHT_TOLERANCE_M);
                let rows = self.terrain.diff_rows(&before, &self.doc.sketch);
                self.resolve(rows);
            }
            Action::Attributes(..) => {}
            Action::Shape(i, shape) if !busy => {
                self.commit_attributes();
                let rows = tools::set_shape(&mut self.doc, &self.terrain, i, shape);
                self.resolve(rows);
            }
            Action::Shape(..) => {}
            Action::Quit => self.done = true,
            Action::SaveAndQuit => {
                match self.doc.path.clone() {
                    Some(p) => self.save_to(&p),
                    None => self.ui.path_dialog = Some((PathKind::SaveAs, String::new())),
                }
                if !self.doc.dirty {
                    self.done = true;
                }
            }
            Action::Recover(p) => {
                self.open(&p);
                self.doc.path = None;
                self.doc.dirty = true;
            }
            Action::DiscardRecovery(p) => {
                let _ = std::fs::remove_file(p);
            }
            Action::Refine(seed) => self.start_refine(seed),
            Action::CancelRefine => match &self.refine_job {
                Some(job) => {
                    job.cancel();
                    self.ui.notice = "cancelling the refinement…".into();
                }
                None => self.ui.notice = "no refinement is running".into(),
            },
            Action::SolverGpu => match self.gpu.solver_context() {
                None => self.error(format!(
                    "the GPU solver cannot run on {}",
                    self.gpu.adapter_name
                )),
                Some(ctx) => {
                    match Terrain::new(&self.doc.sketch, self.terrain.grid.n, Some(&ctx)) {
                        Ok(t) => {
                            self.terrain = t;
                            self.overlay_rows = Some(0..self.terrain.grid.n);
                            self.ui.notice = "switched to the GPU solver".into();
                        }
                        Err(e) => self.error(format!("{e:#}; keeping the CPU solver")),
                    }
                }
            },
            Action::SolverCpu => {
                self.terrain.fall_back_to_cpu(String::new());
                // Asked for: a notice, not an error (`fallback` reports GPU failures).
                match self.terrain.fallback.take().filter(|m| !m.is_empty()) {
                    Some(why) => self.error(why),
                    None => self.ui.notice = "switched to the CPU solver".into(),
                }
            }
        }
    }

    /// Commits a pending live attribute edit as one undo step.
    pub fn commit_attributes(&mut self) {
        if let Some(before) = self.attr_before.take() {
            self.doc.commit(before);
        }
    }

    /// Opens a sketch; on any error the current scene is left untouched.
    pub fn open(&mut self, path: &Path) {
        let files::Opened {
            sketch,
            refined: record,
            warnings,
        } = match files::open_sketch(path) {
            Ok(s) => s,
            Err(e) => return self.error(format!("{e:#}")),
        };
        if sketch.extent_m != self.doc.sketch.extent_m {
            match self.terrain.rebuilt(&sketch, self.terrain.grid.n) {
                Ok(t) => {
                    self.terrain = t;
                    self.scene
                        .use_heightmap(&self.gpu.device, self.terrain.gpu_texture());
                }
                Err(e) => return self.error(format!("{e:#}")),
            }
            self.settings.extent_m = [sketch.extent_m[0] as f32, sketch.extent_m[1] as f32];
        } else {
            self.terrain.restart();
        }
        self.gesture = Gesture::Idle;
        self.attr_before = None;
        let z = stroke_z_range(&sketch);
        self.camera.frame_all(sketch.extent_m, z);
        self.doc = Document::new(sketch, Some(path.to_path_buf()));
        self.overlay_rows = Some(0..self.terrain.grid.n);
        self.ui.notice = format!("opened {}", path.display());
        // A refinement of the previous document is of no use any more (dropping it cancels it).
        self.refine_job = None;
        self.refine_status = Default::default();
        self.refined_origin = None;
        for w in warnings {
            self.warn(w);
        }
        if let Some(record) = record {
            self.restore_refined(record, path);
        }
    }

    /// Saves the sketch and, when a refined layer is shown, its heights beside it
    /// (`persist.rs`) and its record in the sketch. A failed heights write still saves the
    /// sketch, with a record to recompute from.
    pub(super) fn save_to(&mut self, path: &Path) {
        self.commit_attributes();
        let g = self.terrain.grid;
        let heights_file = super::persist::heights_path(path);
        let mut heights_warning = None;
        let record = match self.doc.shown_refined() {
            Some(r) => r.made.as_ref().map(|made| {
                let digest = match super::persist::write_heights(&heights_file, &g, &r.mips[0]) {
                    Ok(d) => Some(d),
                    Err(e) => {
                        heights_warning = Some(e);
                        None
                    }
                };
                super::persist::record(made, &self.doc.sketch, g.n, digest)
            }),
            // A refinement being made again from the opened file's record keeps that record.
            None => self
                .refine_job
                .as_ref()
                .filter(|j| j.sketch == self.doc.sketch)
                .and_then(|j| j.restore.clone())
                .map(|r| terrasketch_sketch::RefinedRecord {
                    heights_digest: None,
                    ..r
                }),
        };
        match files::save(&self.doc.sketch, record.as_ref(), path) {
            Ok(()) => {
                self.doc.path = Some(path.to_path_buf());
                self.doc.dirty = false;
                self.autosave.clear();
                let with_heights = record.as_ref().is_some_and(|r| r.heights_digest.is_some());
                self.ui.notice = match (&record, with_heights) {
                    (Some(_), true) => format!(
                        "saved {} with the refined terrain ({})",
                        path.display(),
                        heights_file.display()
                    ),
                    (Some(_), false) => {
                        format!("saved {} with its refinement record", path.display())
                    }
                    (None, _) => format!("saved {}", path.display()),
                };
                if record.is_none() {
                    // No refined layer: a heights file left by an earlier save is stale.
                    let _ = std::fs::remove_file(&heights_file);
                }
                if let Some(w) = heights_warning {
                    self.warn(format!(
                        "{w}; the sketch was saved with its refinement record (reopening recomputes it)"
                    ));
                }
            }
            Err(e) => self.error(format!("{e:#}")),
        }
    }

    /// Shows the refined layer recorded in an opened sketch: the saved heights file when it
    /// matches the record and the sketch, else a background recomputation from the record.
    fn restore_refined(&mut self, record: terrasketch_sketch::RefinedRecord, path: &Path) {
        use super::persist;
        let params = match persist::params_from_record(record.seed, &record.params) {
            Ok(p) => p,
            Err(e) => {
                return self.warn(format!(
                    "the refined-terrain record is ignored ({e}); the sketch opens without it"
                ));
            }
        };
        let g = self.terrain.grid;
        let file = persist::heights_path(path);
        match persist::load_heights(&file, &record, &self.doc.sketch, &g) {
            Ok(h0) => {
                let maps = terrasketch_multigrid::ConstraintMaps::rasterize(&self.doc.sketch, &g);
                let mips = super::refine::display_mips(&g, &maps, h0);
                let pyramid = match terrasketch_quadtree::MinMaxPyramid::from_heights(
                    g.n,
                    &mips[0],
                    terrasketch_multigrid::pyramid::MINMAX_MAX_SIDE.min(g.n),
                ) {
                    Ok(p) => p,
                    Err(e) => return self.warn(format!("refined heights not shown: {e}")),
                };
                self.doc.refined = Some(Arc::new(super::refine::Refined {
                    sketch: self.doc.sketch.clone(),
                    mips,
                    pyramid,
                    patches: 0,
                    max_error_m: f64::NAN,
                    made: Some(persist::Provenance {
                        exemplars: record.exemplars,
                        params,
                    }),
                }));
                self.refined_origin = Some("loaded");
                self.ui.notice = format!("refined terrain loaded from {}", file.display());
            }
            Err(why) => {
                let seed = record.seed;
                self.start_refine_job(params, Some(record.exemplars.clone()), Some(record));
                if self.refine_job.is_some() {
                    self.refined_origin = Some("recomputing");
                    self.ui.notice = format!(
                        "refined terrain not loaded ({why}): recomputing it from the saved record (seed {seed})"
                    );
                }
            }
        }
    }

    pub(super) fn export(&mut self, path: &Path) {
        self.terrain.finish(&self.doc.sketch);
        // What is shown is exported: the refined layer when it is.
        self.sync_refined();
        let g = self.terrain.grid;
        let heights = match self.terrain.export_heights(&self.doc.sketch) {
            Ok(h) => h,
            Err(e) => return self.error(format!("cannot read the heights back: {e:#}")),
        };
        match files::export(path, g.n, &heights, g.cell_size_m()) {
            Ok(msg) => self.ui.notice = msg,
            Err(e) => self.error(format!("{e:#}")),
        }
    }

    /// Makes the terrain show the document's refined layer if it belongs to the current sketch.
    pub fn sync_refined(&mut self) {
        // While a refinement runs, its latest finished level is shown (if the sketch is still
        // the one being refined).
        let level = self.refine_job.as_mut().and_then(|j| j.latest_level());
        match level.filter(|l| l.sketch == self.doc.sketch) {
            Some(l) => self.terrain.show_refined(Some(&l)),
            None => self.terrain.show_refined(self.doc.shown_refined()),
        }
    }

    /// Starts the realism pass on the current sketch (default parameters, the whole library).
    fn start_refine(&mut self, seed: u64) {
        let params = terrasketch_synthesis::refine::RefineParams {
            seed,
            ..Default::default()
        };
        self.start_refine_job(params, None, None);
    }

    /// Starts a refinement of the current sketch in the background; `restore`: the opened file's
    /// record it makes again (shown without an undo step).
    fn start_refine_job(
        &mut self,
        params: terrasketch_synthesis::refine::RefineParams,
        exemplars: Option<Vec<String>>,
        restore: Option<terrasketch_sketch::RefinedRecord>,
    ) {
        if self.refine_job.is_some() {
            self.ui.notice = "a refinement is already running".into();
            return;
        }
        if !matches!(self.gesture, Gesture::Idle) {
            self.ui.notice = "finish the stroke edit first".into();
            return;
        }
        self.commit_attributes();
        // The thread solves the sketch itself (a cold CPU solve: the same bits every time).
        let req = super::refine::RefineRequest {
            sketch: self.doc.sketch.clone(),
            grid: self.terrain.grid,
            params,
            exemplars,
            cache_dir: crate::refine::default_cache_dir(),
        };
        match super::refine::RefineJob::start(req) {
            Ok(mut job) => {
                job.restore = restore;
                self.refine_job = Some(job);
                self.refine_status = super::session::RefineStatus {
                    state: "running",
                    stage: "starting".into(),
                    ..Default::default()
                };
                self.ui.notice = "refining…".into();
            }
            Err(e) => self.error(format!("cannot start the refinement thread: {e}")),
        }
    }

    /// Picks up the realism pass's progress or result (once per frame).
    pub fn poll_refine(&mut self) {
        use super::refine::JobEnd;
        let Some(job) = self.refine_job.as_mut() else {
            return;
        };
        let Some(end) = job.poll() else {
            let (f, stage) = job.progress();
            self.refine_status.state = "running";
            self.refine_status.progress = f;
            self.refine_status.stage = if job.cancelling() {
                "cancelling".into()
            } else {
                stage
            };
            return;
        };
        let (job_sketch, restore) = match self.refine_job.take() {
            Some(mut j) => (Some(j.sketch.clone()), j.restore.take()),
            None => (None, None),
        };
        let st = &mut self.refine_status;
        st.progress = 1.0;
        match end {
            JobEnd::Done(r)
                if restore.is_some() && job_sketch.as_ref() == Some(&self.doc.sketch) =>
            {
                st.state = "done";
                st.stage = "done".into();
                st.patches = Some(r.patches);
                st.max_error_m = Some(r.max_error_m);
                self.ui.notice = format!(
                    "refined terrain recomputed from the saved record (seed {})",
                    r.made.as_ref().map_or(0, |m| m.params.seed)
                );
                // The opened document's layer: no undo step, nothing unsaved.
                self.doc.refined = Some(std::sync::Arc::from(r));
                self.refined_origin = Some("recomputed");
            }
            JobEnd::Done(r) if job_sketch.as_ref() == Some(&self.doc.sketch) => {
                self.refined_origin = Some("refined");
                st.state = "done";
                st.stage = "done".into();
                st.patches = Some(r.patches);
                st.max_error_m = Some(r.max_error_m);
                self.ui.notice = format!(
                    "refined ({} patches, max constraint error {:.3} m)",
                    r.patches, r.max_error_m
                );
                self.doc.apply_refined(std::sync::Arc::from(r));
            }
            JobEnd::Done(_) => {
                st.state = "discarded";
                st.stage = "discarded".into();
                self.ui.notice =
                    "refinement discarded: the sketch changed while it ran (refine again)".into();
            }
            JobEnd::Cancelled => {
                st.state = "cancelled";
                st.stage = "cancelled".into();
                self.ui.notice = "refinement cancelled".into();
            }
            JobEnd::Failed(msg) => {
                st.state = "failed";
                st.stage = "failed".into();
                self.error(msg);
            }
        }
        if self.refined_origin == Some("recomputing") {
            self.refined_origin = None;
        }
    }

    /// The camera's matrices for the current surface.
    pub fn projection(&self) -> super::camera::Projection {
        let w = self.gpu.config.width.max(1) as f32;
        let h = self.gpu.config.height.max(1) as f32;
        self.camera.projection_beside_panel(
            Vec2::new(w, h),
            self.panel_px,
            self.doc.sketch.extent_m,
        )
    }
}
