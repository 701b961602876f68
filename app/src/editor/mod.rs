//! The interactive editor: winit window, wgpu rendering of the quadtree LOD terrain, egui
//! interface, the GPU solver (or the CPU one) stepped within a frame budget, and replay sessions for
//! tests.
//!
//! # How it works
//! - `state::Editor` puts together small parts: the document and its undo history (`doc`), the
//!   tool's gestures (`tools`), the view and camera (`view`, `camera`), the interface (`ui`), the
//!   GPU resources and renderers (`graphics`: `gpu`, `render`, egui, LOD selection), the realism
//!   pass (`refining`) and a replay session (`replay`). Window events and input are handled in
//!   `input` (a mouse press: `Editor::input`), the interface's actions in `actions`.
//! - `terrain` wraps the solver: one frame loop and budget policy (`Terrain::step`) over the
//!   `engine::TerrainSolver` trait, implemented by `terrain_cpu` and `terrain_gpu`, whose solvers
//!   follow the pen by `follow`'s rule (`budget`: a frame's share); `lag` measures how far behind it
//!   is for replay logs.
//! - Every frame (`frame`, `Editor::frame`): input (window or replay script) edits the sketch; the
//!   changed constraints are re-rasterised and the solver runs warm within the frame budget; the
//!   heightmap texture is updated (in place on the GPU, or the changed rows on the CPU path); the
//!   quadtree selects patches from the solver's min/max pyramid; terrain, strokes and the interface
//!   are drawn; in replay mode one JSON line is logged.
//! - On the GPU solver (default on hardware adapters) the heights stay in the solver's texture,
//!   which the renderer binds; only stroke geometry goes up and only the min/max pyramid, FCG's stop
//!   tests and the probes come back. On the CPU solver (chosen, or after a GPU failure) the changed
//!   mip rows go up and nothing comes back (`bytes_down = 0`). See `app/EDITOR.md`.

mod actions;
mod budget;
mod camera;
mod detail_gpu;
mod doc;
mod engine;
mod files;
mod follow;
mod frame;
mod gpu;
mod graphics;
mod heightfield;
mod input;
mod lag;
mod persist;
mod pipelines;
mod refine;
mod refining;
mod render;
mod replay;
mod session;
mod state;
mod terrain;
mod terrain_cpu;
mod terrain_detail;
mod terrain_gpu;
pub(crate) use terrain_gpu::HeadlessFrames;
mod tools;
mod ui;
mod view;

use std::path::PathBuf;
use std::sync::Arc;

use anyhow::{Result, anyhow};
use winit::application::ApplicationHandler;
use winit::event::WindowEvent;
use winit::event_loop::{ActiveEventLoop, ControlFlow, EventLoop};
use winit::window::{Window, WindowId};

use state::Editor;

/// How the editor was started.
#[derive(Debug, Clone, Default)]
pub struct EditorArgs {
    /// A sketch to open.
    pub file: Option<PathBuf>,
    /// A replay session.
    pub replay: Option<PathBuf>,
    /// Screenshot folder (replay).
    pub screenshots: Option<PathBuf>,
    /// Frame log (replay).
    pub log: Option<PathBuf>,
}

/// Runs the editor until the window closes (or the replay script ends).
pub fn run(args: EditorArgs) -> Result<()> {
    if args.replay.is_none() && (args.screenshots.is_some() || args.log.is_some()) {
        return Err(anyhow!(
            "--screenshots and --log only apply with --replay SESSION.json"
        ));
    }
    // Load the session first: a bad session is reported before any window opens.
    let session = match &args.replay {
        Some(p) => Some(session::Session::load(p)?),
        None => None,
    };
    if let Some(dir) = &args.screenshots {
        std::fs::create_dir_all(dir)
            .map_err(|e| anyhow!("cannot create screenshot folder {}: {e}", dir.display()))?;
    }
    let event_loop = EventLoop::new().map_err(|e| {
        anyhow!(
            "cannot open a window: {e} (the editor needs a display; for tests run it under Xvfb)"
        )
    })?;
    let mut app = App {
        args,
        session,
        editor: None,
        result: Ok(()),
    };
    event_loop
        .run_app(&mut app)
        .map_err(|e| anyhow!("the window system failed: {e}"))?;
    app.result
}

struct App {
    args: EditorArgs,
    session: Option<session::Session>,
    editor: Option<Editor>,
    result: Result<()>,
}

impl ApplicationHandler for App {
    fn resumed(&mut self, event_loop: &ActiveEventLoop) {
        if self.editor.is_some() {
            return;
        }
        let [w, h] =
            self.session
                .as_ref()
                .and_then(|s| s.window_px)
                .unwrap_or(if self.session.is_some() {
                    [640, 400]
                } else {
                    [1280, 800]
                });
        let attrs = Window::default_attributes()
            .with_title("terrasketch")
            .with_inner_size(winit::dpi::PhysicalSize::new(w, h));
        let window = match event_loop.create_window(attrs) {
            Ok(w) => Arc::new(w),
            Err(e) => {
                self.result = Err(anyhow!("cannot create the editor window: {e}"));
                event_loop.exit();
                return;
            }
        };
        let display = Box::new(event_loop.owned_display_handle());
        match Editor::new(window, display, &self.args, self.session.take()) {
            Ok(ed) => {
                self.editor = Some(ed);
            }
            Err(e) => {
                self.result = Err(e);
                event_loop.exit();
            }
        }
    }

    fn window_event(&mut self, event_loop: &ActiveEventLoop, _id: WindowId, event: WindowEvent) {
        let Some(ed) = self.editor.as_mut() else {
            return;
        };
        ed.window_event(event_loop, event);
        if ed.finished() {
            // `finished` is seen by more than one callback: keep the first error.
            if let Err(e) = ed.take_result() {
                self.result = Err(e);
            }
            ed.shutdown();
            event_loop.exit();
        }
    }

    fn about_to_wait(&mut self, event_loop: &ActiveEventLoop) {
        let Some(ed) = self.editor.as_mut() else {
            return;
        };
        if ed.finished() {
            // `finished` is seen by more than one callback: keep the first error.
            if let Err(e) = ed.take_result() {
                self.result = Err(e);
            }
            ed.shutdown();
            event_loop.exit();
            return;
        }
        if ed.wants_frames() {
            event_loop.set_control_flow(ControlFlow::Poll);
            ed.request_redraw();
        } else {
            event_loop.set_control_flow(ControlFlow::wait_duration(
                std::time::Duration::from_millis(250),
            ));
        }
    }
}
