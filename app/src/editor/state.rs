//! The editor: the document and its history (`doc`), the active tool and gesture (`tools`), the
//! view and camera (`view`), the terrain solver (`terrain`), the GPU resources and renderers
//! (`graphics`), the realism pass (`refining`) and a replay session (`replay`), put together.
//! Window events and input are handled in `input.rs` (a mouse press: `Editor::input`), the
//! interface's actions in `actions.rs`, one frame in `frame.rs`.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::Result;
use terrasketch_sketch::{Sketch, example_sketch};
use winit::window::Window;

use super::EditorArgs;
use super::budget::FrameBudget;
use super::camera::ViewCamera;
use super::doc::Document;
use super::files::{self, Autosave};
use super::gpu::Gpu;
use super::graphics::Graphics;
use super::refining::Refinement;
use super::replay::Replay;
use super::session::Session;
use super::terrain::Terrain;
use super::tools::{Gesture, Tool};
use super::ui::{Status, UiState};
use super::view::View;

/// Heightmap side of the interactive editor (sessions choose their own).
pub const DEFAULT_SIZE: usize = 1024;

/// The whole editor.
pub struct Editor {
    /// The document and its undo history.
    pub doc: Document,
    /// The active tool.
    pub tool: Tool,
    /// The tool's gesture in progress.
    pub gesture: Gesture,
    /// Camera, display options, held input.
    pub view: View,
    /// Dialogs, notices and errors shown by the interface.
    pub ui: UiState,
    /// Figures for the status line.
    pub status: Status,
    /// The solver and what the renderer needs from it.
    pub terrain: Terrain,
    /// The solver's share of each frame.
    pub budget: FrameBudget,
    /// Window, device, renderers, LOD selection.
    pub gfx: Graphics,
    /// The realism pass.
    pub refine: Refinement,
    /// The replay session (tests and scripted runs).
    pub replay: Option<Replay>,
    /// The recovery file.
    pub autosave: Autosave,
    /// Frames run so far.
    pub frame_no: u64,
    /// When the last frame started.
    pub last_frame: Instant,
    /// Errors raised this frame (logged, shown).
    pub errors: Vec<String>,
    /// Warnings raised this frame (logged, shown as the notice).
    pub warnings: Vec<String>,
    /// Level-0 rows of the constraint overlay to upload.
    pub overlay_rows: Option<std::ops::Range<usize>>,
    /// The GPU device was lost: the editor ends, keeping the recovery file.
    pub device_lost: bool,
    /// The editor should close.
    pub done: bool,
    /// The run's result (errors that end the editor).
    pub result: Result<()>,
}

/// Lowest and highest elevation of the sketch's strokes and base (framing before any terrain).
pub(super) fn stroke_z_range(s: &Sketch) -> [f32; 2] {
    let mut r = [s.base_elevation_m as f32; 2];
    for st in &s.strokes {
        for p in &st.points {
            r[0] = r[0].min(p[2] as f32);
            r[1] = r[1].max(p[2] as f32);
        }
    }
    r
}

/// The sketch the editor starts with: the file given, the session's (`example`, `empty` or a
/// path relative to the session), else the example. A file that cannot be opened gives an empty
/// sketch and an error.
fn open_at_start(
    args: &EditorArgs,
    session: Option<&Session>,
    base_dir: &Path,
    errors: &mut Vec<String>,
) -> (files::Opened, Option<PathBuf>) {
    let empty = || files::Opened {
        sketch: Sketch::empty(example_sketch().extent_m, 0.0),
        refined: None,
        warnings: Vec::new(),
    };
    let file = match (&args.file, session.and_then(|s| s.sketch.clone())) {
        (Some(f), _) => f.clone(),
        (None, Some(name)) if name == "empty" => return (empty(), None),
        (None, Some(name)) if name != "example" => {
            if Path::new(&name).is_absolute() {
                PathBuf::from(name)
            } else {
                base_dir.join(name)
            }
        }
        _ => {
            let example = files::Opened {
                sketch: example_sketch(),
                ..empty()
            };
            return (example, None);
        }
    };
    match files::open_sketch(&file) {
        Ok(s) => (s, Some(file)),
        Err(e) => {
            errors.push(format!("{e:#}; opened an empty sketch instead"));
            (empty(), None)
        }
    }
}

/// The terrain of side `size` for `sketch` on the backend asked for: the session's or
/// $TERRASKETCH_SOLVER ("cpu" / "gpu"); by default the GPU when the window's device can run it, but
/// the CPU on a software adapter (lavapipe, llvmpipe, WARP), which runs the GPU solver 10-20 times
/// slower than the CPU solver. Returns the terrain and a notice.
fn start_terrain(
    gpu: &Gpu,
    sketch: &Sketch,
    size: usize,
    session: Option<&Session>,
    errors: &mut Vec<String>,
) -> Result<(Terrain, String)> {
    let wanted = session
        .and_then(|s| s.backend.clone())
        .or_else(|| std::env::var("TERRASKETCH_SOLVER").ok());
    let software = gpu.adapter_info.device_type == wgpu::DeviceType::Cpu;
    let mut notice = String::new();
    let want_gpu = match wanted.as_deref() {
        Some("gpu") => true,
        Some("cpu") => false,
        None if software => {
            notice =
                "software adapter: CPU solver (the side panel switches to the GPU solver)".into();
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
    let terrain = match Terrain::new(sketch, size, ctx.as_ref()) {
        Ok(t) => t,
        Err(e) if ctx.is_some() => {
            errors.push(format!("{e:#}: using the CPU solver"));
            Terrain::new(sketch, size, None)?
        }
        Err(e) => return Err(e),
    };
    Ok((terrain, notice))
}

/// The recovery file: a session's own interval (`autosave_s`), none for other sessions, else the
/// default. A recovery file left by an earlier run is offered (`ui.recovery_offer`).
fn start_autosave(session: Option<&Session>, ui: &mut UiState) -> Autosave {
    let every = session
        .and_then(|s| s.autosave_s)
        .filter(|s| s.is_finite() && *s > 0.0)
        .map(|s| Duration::from_secs_f64(s.min(3600.0)));
    if session.is_some() && every.is_none() {
        return Autosave::new(None);
    }
    let p = files::recovery_path();
    if let Some(p) = p.as_ref().filter(|p| p.exists()) {
        ui.recovery_offer = Some(p.clone());
    }
    match every {
        Some(every) => Autosave::with_interval(p, every),
        None => Autosave::new(p),
    }
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
        let (opened, path) = open_at_start(args, session.as_ref(), &base_dir, &mut errors);
        let files::Opened {
            sketch,
            refined: record,
            warnings: open_warnings,
        } = opened;
        let size = session
            .as_ref()
            .and_then(|s| s.size)
            .unwrap_or(DEFAULT_SIZE);
        let (terrain, notice) = start_terrain(&gpu, &sketch, size, session.as_ref(), &mut errors)?;
        let gfx = Graphics::new(window, gpu, size, sketch.extent_m, terrain.gpu_texture());
        let mut view = View::new(ViewCamera::framing(
            sketch.extent_m,
            stroke_z_range(&sketch),
        ));
        let budget = match session.as_ref() {
            Some(s) => s.frame_budget(),
            None => FrameBudget::Time(super::budget::DEFAULT_FRAME_BUDGET),
        };
        let mut ui = UiState::default();
        let autosave = start_autosave(session.as_ref(), &mut ui);
        let replay = match session {
            Some(s) => {
                if s.camera.as_deref() == Some("top") {
                    view.camera.top_view();
                }
                Some(Replay::new(&s, args, base_dir, terrain.grid)?)
            }
            None => None,
        };
        for e in &errors {
            eprintln!("terrasketch: error: {e}");
        }
        ui.error = errors.first().cloned();
        ui.notice = notice;
        let status = Status {
            size,
            adapter: gfx.gpu.adapter_name.clone(),
            backend: terrain.backend_name().to_string(),
            ..Default::default()
        };
        let mut editor = Editor {
            doc: Document::new(sketch, path.clone()),
            tool: Tool::Ridge,
            gesture: Gesture::Idle,
            view,
            ui,
            status,
            terrain,
            budget,
            gfx,
            refine: Refinement::default(),
            replay,
            autosave,
            frame_no: 0,
            last_frame: Instant::now(),
            errors,
            warnings: Vec::new(),
            overlay_rows: Some(0..size),
            device_lost: false,
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
            || self.view.moving()
            || self.refine.running()
    }

    /// Asks for the next frame; without a drawable surface (minimised) runs it directly.
    pub fn request_redraw(&mut self) {
        if self.gfx.gpu.drawable() {
            self.gfx.window.request_redraw();
        } else if self.replay.is_some() || !self.terrain.settled() {
            self.frame();
        }
    }

    /// Surface resize (0 x 0 = minimised: frames run without drawing).
    pub fn resize(&mut self, width: u32, height: u32) {
        self.gfx.gpu.resize(width, height);
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

    /// The camera's matrices for the current surface.
    pub fn projection(&self) -> super::camera::Projection {
        self.view
            .projection(self.gfx.surface_px(), self.doc.sketch.extent_m)
    }
}
