//! The view: the camera, the display options, and what the pointer and keyboard hold (buttons,
//! modifiers, fly keys), with the side panel's width that the projection leaves free. Plain state:
//! no document, no GPU.

use std::collections::HashSet;

use glam::{Vec2, Vec3};
use winit::keyboard::ModifiersState;

use super::camera::{Projection, ViewCamera};
use super::input::Button;
use super::ui::ViewOptions;

/// Keys that move the camera while held in fly mode.
const FLY_KEYS: [&str; 6] = ["w", "a", "s", "d", "q", "e"];

/// The camera, display options and held input.
pub struct View {
    /// The orbit (or fly) camera.
    pub camera: ViewCamera,
    /// What is drawn (contours, strokes, detail, LOD pixel budget...).
    pub options: ViewOptions,
    /// Last pointer position, window pixels.
    pub pointer: Vec2,
    /// Left (tool), right (orbit) and middle (pan) buttons held.
    pub left_down: bool,
    pub right_down: bool,
    pub middle_down: bool,
    /// Keyboard modifiers held.
    pub modifiers: ModifiersState,
    /// Fly keys held (`w a s d q e`).
    pub held: HashSet<String>,
    /// Width in pixels of the side panel covering the left of the 3D view (from the last UI frame).
    pub panel_px: f32,
}

impl View {
    /// A view through `camera` with the default options and nothing held.
    pub fn new(camera: ViewCamera) -> View {
        View {
            camera,
            options: ViewOptions::default(),
            pointer: Vec2::ZERO,
            left_down: false,
            right_down: false,
            middle_down: false,
            modifiers: ModifiersState::empty(),
            held: HashSet::new(),
            panel_px: 0.0,
        }
    }

    /// The camera's matrices for a surface of `surface_px` pixels over a sketch of `extent_m`.
    pub fn projection(&self, surface_px: [u32; 2], extent_m: [f64; 2]) -> Projection {
        let size = Vec2::new(surface_px[0].max(1) as f32, surface_px[1].max(1) as f32);
        self.camera
            .projection_beside_panel(size, self.panel_px, extent_m)
    }

    /// True while the view changes by itself (a button held, or flying with a key held).
    pub fn moving(&self) -> bool {
        self.left_down || self.right_down || self.middle_down || self.flying()
    }

    fn flying(&self) -> bool {
        self.camera.fly && !self.held.is_empty()
    }

    /// A button went down or up.
    pub fn set_button(&mut self, b: Button, down: bool) {
        match b {
            Button::Left => self.left_down = down,
            Button::Right => self.right_down = down,
            Button::Middle => self.middle_down = down,
        }
    }

    /// The pointer moved to `p`: orbits with the right button, pans with the middle one (or
    /// shift + right).
    pub fn pointer_moved(&mut self, p: Vec2, proj: &Projection) {
        let delta = p - self.pointer;
        self.pointer = p;
        if self.right_down && !self.modifiers.shift_key() {
            self.camera.rotate(delta);
        } else if self.middle_down || (self.right_down && self.modifiers.shift_key()) {
            self.camera.pan(delta, proj.viewport_px);
        }
    }

    /// A key (a normalised chord) went down or up: fly keys are held until released.
    pub fn hold_key(&mut self, chord: &str, pressed: bool) {
        if !pressed {
            self.held.remove(chord);
        } else if FLY_KEYS.contains(&chord) {
            self.held.insert(chord.to_string());
        }
    }

    /// Moves the fly camera by the held keys over `dt_s` seconds.
    pub fn fly_step(&mut self, dt_s: f32) {
        if !self.flying() {
            return;
        }
        let speed = 0.5 * self.camera.distance_m.max(200.0) * dt_s;
        let axis =
            |a: &str, b: &str| (self.held.contains(a) as i32 - self.held.contains(b) as i32) as f32;
        let local = Vec3::new(axis("d", "a"), axis("w", "s"), axis("e", "q")) * speed;
        self.camera.fly_move(local);
    }
}
