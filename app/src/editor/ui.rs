//! The egui interface: menu and tool bar, side panel (strokes, attributes, view options), status line,
//! dialogs. It reads the editor's state and returns actions; it never edits the document itself.

use std::path::PathBuf;

use terrasketch_sketch::{CurveKind, Falloff, Sketch, StrokeKind};

use super::tools::{Shape, Tool, can_close};

/// View options (also the shader's flag bits).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ViewOptions {
    /// Contour lines.
    pub contours: bool,
    /// Patch grid wireframe.
    pub wireframe: bool,
    /// One colour per quadtree level.
    pub lod_colours: bool,
    /// Elevation-constraint overlay.
    pub constraints: bool,
    /// Stroke curves and handles.
    pub strokes: bool,
    /// The procedural detail on the diffusion terrain.
    pub detail: bool,
    /// Quadtree pixel budget.
    pub pixel_budget: f32,
}

impl Default for ViewOptions {
    fn default() -> Self {
        ViewOptions {
            contours: false,
            wireframe: false,
            lod_colours: false,
            constraints: false,
            strokes: true,
            detail: true,
            pixel_budget: 128.0,
        }
    }
}

impl ViewOptions {
    /// Shader flag bits.
    pub fn flags(&self) -> u32 {
        (self.contours as u32)
            | ((self.wireframe as u32) << 1)
            | ((self.lod_colours as u32) << 2)
            | ((self.constraints as u32) << 3)
            | ((self.detail as u32) << 4)
    }
}

/// Which file a path dialog asks for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PathKind {
    /// Open a sketch.
    Open,
    /// Save the sketch under a new name.
    SaveAs,
    /// Export the heightmap.
    Export,
}

/// Dialog state (what is open).
#[derive(Debug)]
pub struct UiState {
    /// A path being typed.
    pub path_dialog: Option<(PathKind, String)>,
    /// The unsaved-changes prompt on close.
    pub confirm_close: bool,
    /// A recovery file offered at start.
    pub recovery_offer: Option<PathBuf>,
    /// An error to show until dismissed.
    pub error: Option<String>,
    /// A short notice in the status line.
    pub notice: String,
    /// Seed of the next realism pass (same seed and sketch, same result; the CLI's default is 1).
    pub refine_seed: u64,
    /// Gain of the detail finer than the exemplars in the next realism pass.
    pub refine_fine_detail: f32,
}

impl Default for UiState {
    fn default() -> Self {
        UiState {
            path_dialog: None,
            confirm_close: false,
            recovery_offer: None,
            error: None,
            notice: String::new(),
            refine_seed: 1,
            refine_fine_detail: terrasketch_synthesis::refine::RefineParams::default().fine_detail,
        }
    }
}

/// What the user asked for this frame.
#[derive(Debug, Clone)]
pub enum Action {
    /// Choose a tool.
    Tool(Tool),
    /// Undo.
    Undo,
    /// Redo.
    Redo,
    /// Open a sketch file.
    Open(PathBuf),
    /// Save to the current path (Save As if none).
    Save,
    /// Save under a new path.
    SaveAs(PathBuf),
    /// Export the heightmap.
    Export(PathBuf),
    /// Frame the whole terrain.
    FrameAll,
    /// Look straight down.
    TopView,
    /// Toggle fly mode.
    Fly,
    /// Select a stroke (or none).
    Select(Option<usize>),
    /// Delete a stroke.
    Delete(usize),
    /// Live attribute edit of a stroke: (index, slope left, slope right, width, roughness,
    /// height tolerance).
    Attributes(usize, [f64; 5]),
    /// Set a stroke's curve options (one undo step each).
    Shape(usize, Shape),
    /// Quit now (changes discarded or saved).
    Quit,
    /// Save, then quit.
    SaveAndQuit,
    /// Load the recovery file.
    Recover(PathBuf),
    /// Delete the recovery file.
    DiscardRecovery(PathBuf),
    /// Give up the GPU solver for the CPU one.
    SolverCpu,
    /// Switch to the GPU solver (it takes the current sketch from scratch).
    SolverGpu,
    /// Start the realism pass with this seed and gain of the detail finer than the exemplars.
    Refine(u64, f32),
    /// Stop the running realism pass.
    CancelRefine,
}

/// Figures for the status line.
#[derive(Debug, Clone, Default)]
pub struct Status {
    /// Last frame, ms.
    pub frame_ms: f64,
    /// Finest ready mip.
    pub finest_level: Option<u32>,
    /// Residual.
    pub residual: Option<f32>,
    /// Work units this frame.
    pub work_units: f64,
    /// Converged.
    pub converged: bool,
    /// Patches drawn.
    pub patches: usize,
    /// Bytes up this frame.
    pub bytes_up: u64,
    /// Bytes down this frame.
    pub bytes_down: u64,
    /// Heightmap side.
    pub size: usize,
    /// Adapter name.
    pub adapter: String,
    /// Solver backend ("gpu" or "cpu").
    pub backend: String,
    /// The GPU solver's device counters this frame (all 0 on the CPU).
    pub gpu_counts: terrasketch_multigrid::gpu::GpuCounters,
    /// Document title.
    pub title: String,
    /// Undo / redo depth.
    pub undo: (usize, usize),
    /// Fly mode on.
    pub fly: bool,
    /// A refinement runs: fraction done and stage.
    pub refine_running: Option<(f32, String)>,
    /// The refined layer is shown.
    pub refined: bool,
}

/// Runs the interface for one frame.
pub fn show(
    root: &mut egui::Ui,
    state: &mut UiState,
    tool: Tool,
    view: &mut ViewOptions,
    sketch: &Sketch,
    selected: Option<usize>,
    status: &Status,
) -> Vec<Action> {
    let mut actions = Vec::new();
    egui::Panel::top("menu").show(root, |ui| menu_bar(ui, state, tool, status, &mut actions));
    egui::Panel::bottom("status").show(root, |ui| status_line(ui, state, status));
    egui::Panel::left("side").default_size(230.0).show(root, |ui| {
        egui::ScrollArea::vertical().show(ui, |ui| {
            strokes_panel(ui, sketch, selected, &mut actions);
            ui.separator();
            view_panel(ui, view);
            ui.separator();
            realism_panel(ui, state, status, &mut actions);
            ui.separator();
            ui.label(format!("Solver: {}", status.backend));
            if status.backend == "gpu" && ui.button("Use the CPU solver").clicked() {
                actions.push(Action::SolverCpu);
            }
            if status.backend == "cpu" && ui.button("Use the GPU solver").clicked() {
                actions.push(Action::SolverGpu);
            }
            ui.separator();
            ui.small(
                "Left: tool. Right drag: orbit (fly: look). Middle or Shift+right drag: pan. Wheel: zoom to \
                 cursor. G: fly mode (WASD, Q/E). 1-5: tools. Esc: cancel.",
            );
        });
    });
    dialogs(root, state, &mut actions);
    actions
}

/// The menu bar: File, Edit, the tools, the camera's buttons.
fn menu_bar(
    ui: &mut egui::Ui,
    state: &mut UiState,
    tool: Tool,
    status: &Status,
    actions: &mut Vec<Action>,
) {
    ui.horizontal(|ui| {
        ui.menu_button("File", |ui| {
            if ui.button("Open…  (Ctrl+O)").clicked() {
                state.path_dialog = Some((PathKind::Open, String::new()));
            }
            if ui.button("Save  (Ctrl+S)").clicked() {
                actions.push(Action::Save);
            }
            if ui.button("Save As…").clicked() {
                state.path_dialog = Some((PathKind::SaveAs, String::new()));
            }
            if ui.button("Export heightmap…  (Ctrl+E)").clicked() {
                state.path_dialog = Some((PathKind::Export, "heightmap.exr".to_string()));
            }
            if ui.button("Quit").clicked() {
                state.confirm_close = true;
            }
        });
        ui.menu_button("Edit", |ui| {
            if ui.button("Undo  (Ctrl+Z)").clicked() {
                actions.push(Action::Undo);
            }
            if ui.button("Redo  (Ctrl+Y)").clicked() {
                actions.push(Action::Redo);
            }
        });
        ui.separator();
        for (i, t) in Tool::ALL.into_iter().enumerate() {
            if ui
                .selectable_label(tool == t, format!("{} {}", i + 1, t.name()))
                .clicked()
            {
                actions.push(Action::Tool(t));
            }
        }
        ui.separator();
        if ui.button("Frame all (F)").clicked() {
            actions.push(Action::FrameAll);
        }
        if ui.button("Top (T)").clicked() {
            actions.push(Action::TopView);
        }
        if ui.selectable_label(status.fly, "Fly (G)").clicked() {
            actions.push(Action::Fly);
        }
    });
}

/// The status line.
fn status_line(ui: &mut egui::Ui, state: &UiState, status: &Status) {
    let residual = status
        .residual
        .map(|r| format!("{r:.1e}"))
        .unwrap_or_else(|| "-".into());
    let level = status
        .finest_level
        .map(|l| l.to_string())
        .unwrap_or_else(|| "-".into());
    ui.label(format!(
        "{} | {:.1} ms | {} solver {}^2: finest level {level}, residual {residual}{}, {:.2} WU | {} patches | up {} B, down {} B | {} | undo {} redo {} | {}",
        status.title,
        status.frame_ms,
        status.backend,
        status.size,
        if status.converged { " (converged)" } else { "" },
        status.work_units,
        status.patches,
        status.bytes_up,
        status.bytes_down,
        status.adapter,
        status.undo.0,
        status.undo.1,
        state.notice,
    ));
}

/// The strokes, and the selected stroke's attributes and shape.
fn strokes_panel(
    ui: &mut egui::Ui,
    sketch: &Sketch,
    selected: Option<usize>,
    actions: &mut Vec<Action>,
) {
    ui.heading("Strokes");
    for (i, s) in sketch.strokes.iter().enumerate() {
        let label = format!("{i}: {} ({} pts)", s.kind.as_str(), s.points.len());
        if ui.selectable_label(selected == Some(i), label).clicked() {
            actions.push(Action::Select(Some(i)));
        }
    }
    if let Some(i) = selected.filter(|&i| i < sketch.strokes.len()) {
        stroke_panel(ui, sketch, i, actions);
    }
}

/// Stroke `i`'s slopes, width, roughness, tolerance, curve, loop and falloff.
fn stroke_panel(ui: &mut egui::Ui, sketch: &Sketch, i: usize, actions: &mut Vec<Action>) {
    let s = &sketch.strokes[i];
    ui.separator();
    ui.heading(format!("Stroke {i}: {}", s.kind.as_str()));
    let now = [
        s.slope_left_deg,
        s.slope_right_deg,
        s.width_m,
        s.roughness,
        s.height_tolerance_m,
    ];
    let mut v = now;
    let slopes = s.kind != StrokeKind::Plateau;
    ui.add_enabled(
        slopes,
        egui::Slider::new(&mut v[0], 0.0..=85.0).text("slope left °"),
    );
    ui.add_enabled(
        slopes,
        egui::Slider::new(&mut v[1], 0.0..=85.0).text("slope right °"),
    );
    let max_w = (sketch.extent_m[0].max(sketch.extent_m[1]) * 0.5).max(10.0);
    ui.add(
        egui::Slider::new(&mut v[2], 1.0..=max_w)
            .logarithmic(true)
            .text("width m"),
    );
    ui.add(egui::Slider::new(&mut v[3], 0.0..=1.0).text("roughness"));
    ui.add(egui::Slider::new(&mut v[4], 0.0..=50.0).text("height tolerance m"))
        .on_hover_text("how far refine may move the stroke's heights (0 = exactly)");
    if v != now {
        actions.push(Action::Attributes(i, v));
    }
    let mut shape = Shape::of(s);
    ui.horizontal(|ui| {
        ui.label("curve");
        ui.selectable_value(&mut shape.curve, CurveKind::Smooth, "smooth");
        ui.selectable_value(&mut shape.curve, CurveKind::Polyline, "polyline");
    });
    ui.add_enabled(
        can_close(s),
        egui::Checkbox::new(&mut shape.closed, "closed loop"),
    )
    .on_disabled_hover_text("a loop needs at least 3 distinct points");
    ui.add_enabled_ui(slopes, |ui| {
        ui.horizontal(|ui| {
            ui.label("falloff");
            for f in Falloff::ALL {
                ui.selectable_value(&mut shape.falloff, f, f.as_str());
            }
        })
        .response
        .on_hover_text(
            "How the slope fades towards the band edge: foot = steep upper flank, gentle foot; \
             none = constant slope to the edge",
        );
    });
    if shape != Shape::of(s) {
        actions.push(Action::Shape(i, shape));
    }
    if ui.button("Delete stroke (Del)").clicked() {
        actions.push(Action::Delete(i));
    }
}

/// The view options.
fn view_panel(ui: &mut egui::Ui, view: &mut ViewOptions) {
    ui.heading("View");
    ui.checkbox(&mut view.contours, "contour lines");
    ui.checkbox(&mut view.wireframe, "wireframe");
    ui.checkbox(&mut view.lod_colours, "LOD colours");
    ui.checkbox(&mut view.constraints, "constraint overlay");
    ui.checkbox(&mut view.strokes, "strokes and handles");
    ui.checkbox(&mut view.detail, "procedural detail (H)");
    ui.add(egui::Slider::new(&mut view.pixel_budget, 32.0..=512.0).text("LOD pixel budget"));
}

/// The realism pass: its progress and Cancel while it runs, else the button and the seed.
fn realism_panel(
    ui: &mut egui::Ui,
    state: &mut UiState,
    status: &Status,
    actions: &mut Vec<Action>,
) {
    ui.heading("Realism");
    match &status.refine_running {
        Some((f, stage)) => {
            ui.add(
                egui::ProgressBar::new(*f)
                    .show_percentage()
                    .text(stage.as_str()),
            );
            if ui.button("Cancel").clicked() {
                actions.push(Action::CancelRefine);
            }
        }
        None => {
            if ui
                .button("Refine (realism)")
                .on_hover_text(
                    "Example-based detail from the shipped exemplars; the strokes' elevations stay",
                )
                .clicked()
            {
                actions.push(Action::Refine(state.refine_seed, state.refine_fine_detail));
            }
            ui.horizontal(|ui| {
                ui.label("seed");
                ui.add(egui::DragValue::new(&mut state.refine_seed))
                    .on_hover_text("Another seed gives another variation of the same layout");
            });
            ui.horizontal(|ui| {
                ui.label("fine detail");
                ui.add(
                    egui::DragValue::new(&mut state.refine_fine_detail)
                        .range(0.0..=terrasketch_synthesis::refine::MAX_FINE_DETAIL)
                        .speed(0.01),
                )
                .on_hover_text(
                    "Gain of the calibrated detail below the exemplars' own cells \
                     (1: as on real land, 0: none)",
                );
            });
            if status.refined {
                ui.label("refined terrain shown (Undo: diffusion)");
            }
        }
    }
}

fn dialogs(root: &mut egui::Ui, state: &mut UiState, actions: &mut Vec<Action>) {
    let ctx = root.ctx().clone();
    if let Some((kind, mut text)) = state.path_dialog.take() {
        let title = match kind {
            PathKind::Open => "Open sketch",
            PathKind::SaveAs => "Save sketch as",
            PathKind::Export => {
                "Export: a heightmap (.exr, .tif, .png, .r16), a mesh (.glb, .obj) or a folder with --masks png"
            }
        };
        let mut keep = true;
        egui::Window::new(title)
            .collapsible(false)
            .show(&ctx, |ui| {
                ui.label("Path:");
                let r = ui.text_edit_singleline(&mut text);
                let enter = r.lost_focus() && ui.input(|i| i.key_pressed(egui::Key::Enter));
                ui.horizontal(|ui| {
                    if (ui.button("OK").clicked() || enter) && !text.trim().is_empty() {
                        let p = PathBuf::from(text.trim());
                        actions.push(match kind {
                            PathKind::Open => Action::Open(p),
                            PathKind::SaveAs => Action::SaveAs(p),
                            PathKind::Export => Action::Export(p),
                        });
                        keep = false;
                    }
                    if ui.button("Cancel").clicked() {
                        keep = false;
                    }
                });
            });
        if keep {
            state.path_dialog = Some((kind, text));
        }
    }
    if state.confirm_close {
        egui::Window::new("Unsaved changes")
            .collapsible(false)
            .show(&ctx, |ui| {
                ui.label("The sketch has unsaved changes.");
                ui.horizontal(|ui| {
                    if ui.button("Save and quit").clicked() {
                        actions.push(Action::SaveAndQuit);
                        state.confirm_close = false;
                    }
                    if ui.button("Quit without saving").clicked() {
                        actions.push(Action::Quit);
                        state.confirm_close = false;
                    }
                    if ui.button("Cancel").clicked() {
                        state.confirm_close = false;
                    }
                });
            });
    }
    if let Some(path) = state.recovery_offer.clone() {
        egui::Window::new("Recover unsaved work?")
            .collapsible(false)
            .show(&ctx, |ui| {
                ui.label(format!(
                    "A recovery autosave from a session that did not end cleanly exists:\n{}",
                    path.display()
                ));
                ui.horizontal(|ui| {
                    if ui.button("Recover").clicked() {
                        actions.push(Action::Recover(path.clone()));
                        state.recovery_offer = None;
                    }
                    if ui.button("Discard").clicked() {
                        actions.push(Action::DiscardRecovery(path.clone()));
                        state.recovery_offer = None;
                    }
                });
            });
    }
    if let Some(msg) = state.error.clone() {
        egui::Window::new("Error")
            .collapsible(false)
            .show(&ctx, |ui| {
                ui.label(msg);
                if ui.button("OK").clicked() {
                    state.error = None;
                }
            });
    }
}
