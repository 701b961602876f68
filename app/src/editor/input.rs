//! Input in one vocabulary for the window and for replay scripts: pointer events in window pixels and
//! key chords such as `"ctrl+z"`.

use glam::Vec2;
use winit::event::{ElementState, MouseButton, MouseScrollDelta, WindowEvent};
use winit::event_loop::ActiveEventLoop;
use winit::keyboard::{Key, ModifiersState, NamedKey};

use super::state::Editor;
use super::tools::{self, Gesture, Tool};
use super::ui::{Action, PathKind};

/// A mouse button.
pub use super::session::Button;

/// One input event.
#[derive(Debug, Clone, PartialEq)]
pub enum Input {
    /// Pointer moved to a window position.
    Move([f32; 2]),
    /// Button pressed at a window position.
    Press(Button, [f32; 2]),
    /// Button released.
    Release(Button),
    /// Wheel, in lines (positive zooms in).
    Scroll(f32),
    /// Key pressed (chord name) or released (`pressed = false`, no modifiers).
    Key { chord: String, pressed: bool },
}

/// Normalises a chord such as `"Ctrl+Shift+Z"` to `"ctrl+shift+z"` (modifiers in that order).
pub fn normalize_chord(chord: &str) -> String {
    let parts: Vec<String> = chord
        .split('+')
        .map(|p| p.trim().to_lowercase())
        .filter(|p| !p.is_empty())
        .collect();
    let has = |m: &str| parts.iter().any(|p| p == m);
    let key = parts
        .iter()
        .rev()
        .find(|p| !matches!(p.as_str(), "ctrl" | "shift" | "alt"))
        .cloned()
        .unwrap_or_default();
    let mut out = String::new();
    for m in ["ctrl", "shift", "alt"] {
        if has(m) {
            out.push_str(m);
            out.push('+');
        }
    }
    out.push_str(&key);
    out
}

/// The key name of a winit key (`None` for keys the editor does not use).
pub fn key_name(key: &Key) -> Option<String> {
    match key {
        Key::Character(c) => Some(c.to_lowercase()),
        Key::Named(n) => Some(
            match n {
                NamedKey::Delete => "delete",
                NamedKey::Backspace => "backspace",
                NamedKey::Escape => "escape",
                NamedKey::Space => "space",
                NamedKey::Shift => "shift",
                NamedKey::Control => "ctrl",
                _ => return None,
            }
            .to_string(),
        ),
        _ => None,
    }
}

/// The chord for a key with the current modifiers.
pub fn chord(name: &str, mods: ModifiersState) -> String {
    let mut s = String::new();
    if mods.control_key() && name != "ctrl" {
        s.push_str("ctrl+");
    }
    if mods.shift_key() && name != "shift" {
        s.push_str("shift+");
    }
    if mods.alt_key() {
        s.push_str("alt+");
    }
    s.push_str(name);
    s
}

/// Window events become [`Input`] (or go to egui when it has the pointer or keyboard), and input
/// becomes tool gestures, camera moves and shortcuts.
impl Editor {
    /// A window event.
    pub fn window_event(&mut self, _el: &ActiveEventLoop, event: WindowEvent) {
        let egui_resp = self
            .gfx
            .egui_state
            .on_window_event(&self.gfx.window, &event);
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
                    self.gfx.window.request_redraw();
                } else {
                    self.done = true;
                }
            }
            WindowEvent::Resized(size) => self.resize(size.width, size.height),
            WindowEvent::RedrawRequested => self.frame(),
            WindowEvent::ModifiersChanged(m) => self.view.modifiers = m.state(),
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
                        if !egui_resp.consumed && !self.gfx.egui_ctx.is_pointer_over_egui() =>
                    {
                        self.input(Input::Press(b, self.view.pointer.to_array()))
                    }
                    ElementState::Released => self.input(Input::Release(b)),
                    _ => {}
                }
            }
            WindowEvent::MouseWheel { delta, .. }
                if !egui_resp.consumed && !self.gfx.egui_ctx.is_pointer_over_egui() =>
            {
                let lines = match delta {
                    MouseScrollDelta::LineDelta(_, y) => y,
                    MouseScrollDelta::PixelDelta(p) => p.y as f32 / 40.0,
                };
                self.input(Input::Scroll(lines));
            }
            WindowEvent::KeyboardInput { event, .. }
                if !egui_resp.consumed && !self.gfx.egui_ctx.egui_wants_keyboard_input() =>
            {
                if let Some(name) = key_name(&event.logical_key) {
                    let pressed = event.state == ElementState::Pressed;
                    if pressed && event.repeat {
                        return;
                    }
                    let c = if pressed {
                        chord(&name, self.view.modifiers)
                    } else {
                        name
                    };
                    self.input(Input::Key { chord: c, pressed });
                }
            }
            _ => {}
        }
        if egui_resp.repaint || is_input {
            self.gfx.window.request_redraw();
        }
    }

    /// One input event (window or replay): the pointer drives the tool's gesture (`tools`) with
    /// the left button and the camera with the others (`view`); keys are shortcuts (`shortcut`).
    pub fn input(&mut self, input: Input) {
        let proj = self.projection();
        match input {
            Input::Move(p) => {
                let p = Vec2::from(p);
                if self.view.left_down {
                    let rows =
                        tools::update(&mut self.gesture, p, &mut self.doc, &self.terrain, &proj);
                    self.resolve(rows);
                }
                self.view.pointer_moved(p, &proj);
            }
            Input::Press(b, p) => {
                self.view.pointer = Vec2::from(p);
                self.view.set_button(b, true);
                if let Button::Left = b {
                    let (g, rows) = tools::begin(
                        self.tool,
                        self.view.pointer,
                        &mut self.doc,
                        &self.terrain,
                        &proj,
                    );
                    self.gesture = g;
                    self.resolve(rows);
                }
            }
            Input::Release(b) => {
                self.view.set_button(b, false);
                if let Button::Left = b {
                    let g = std::mem::replace(&mut self.gesture, Gesture::Idle);
                    tools::end(g, &mut self.doc);
                }
            }
            Input::Scroll(lines) => {
                let toward = self
                    .terrain
                    .field()
                    .and_then(|f| f.raycast(&proj.ray(self.view.pointer)));
                self.view.camera.zoom_to(0.85f32.powf(lines), toward);
            }
            Input::Key { chord, pressed } => {
                let chord = normalize_chord(&chord);
                self.view.hold_key(&chord, pressed);
                if pressed {
                    self.shortcut(&chord);
                }
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
            "f" if !self.view.camera.fly => Some(Action::FrameAll),
            "t" => Some(Action::TopView),
            "h" => {
                self.view.options.detail = !self.view.options.detail;
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
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chords_normalise() {
        assert_eq!(normalize_chord("Shift+Ctrl+Z"), "ctrl+shift+z");
        assert_eq!(normalize_chord("delete"), "delete");
    }
}
