//! The camera the selection projects node boxes with.

use glam::camera::rh;
use glam::{Mat4, Vec3};

use crate::QuadtreeError;

/// A camera in world space (metres; x east, y north, z up).
///
/// Clip space follows wgpu: after the perspective divide x and y are in `[-1, 1]` and depth in
/// `[0, 1]`, so the frustum is `-w <= x <= w`, `-w <= y <= w`, `0 <= z <= w`. Any projection
/// with that clip volume works (standard, reversed-Z, infinite far plane, orthographic).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    /// World to view transform (view space: camera at the origin looking down -z, y up).
    pub view_from_world: Mat4,
    /// Projection, view to clip.
    pub clip_from_view: Mat4,
    /// Viewport size in pixels `[width, height]`.
    pub viewport_px: [f32; 2],
    /// Camera position in world metres (`view_from_world.inverse()` applied to the origin).
    pub position_m: Vec3,
}

impl Camera {
    /// A perspective camera at `position_m` looking at `target_m`, z up (y up when looking
    /// straight up or down), vertical field of view `fov_y_rad`, wgpu clip space (glam's
    /// right-handed `directx` projection: depth in `[0, 1]`, y up).
    pub fn look_at(
        position_m: Vec3,
        target_m: Vec3,
        fov_y_rad: f32,
        viewport_px: [f32; 2],
        near_m: f32,
        far_m: f32,
    ) -> Self {
        let forward = (target_m - position_m).normalize_or_zero();
        let up = if forward.cross(Vec3::Z).length_squared() < 1e-8 {
            Vec3::Y
        } else {
            Vec3::Z
        };
        let view_from_world = rh::view::look_at_mat4(position_m, target_m, up);
        let aspect = viewport_px[0] / viewport_px[1].max(1.0);
        let clip_from_view = rh::proj::directx::perspective(fov_y_rad, aspect, near_m, far_m);
        Self {
            view_from_world,
            clip_from_view,
            viewport_px,
            position_m,
        }
    }

    /// A camera from its matrices; the position is recovered from `view_from_world`.
    pub fn from_matrices(
        view_from_world: Mat4,
        clip_from_view: Mat4,
        viewport_px: [f32; 2],
    ) -> Self {
        let position_m = view_from_world.inverse().transform_point3(Vec3::ZERO);
        Self {
            view_from_world,
            clip_from_view,
            viewport_px,
            position_m,
        }
    }

    /// World to clip transform, `clip_from_view * view_from_world`.
    pub fn clip_from_world(&self) -> Mat4 {
        self.clip_from_view * self.view_from_world
    }

    /// Checks that everything is finite and the viewport is at least 1x1 px.
    pub fn validate(&self) -> Result<(), QuadtreeError> {
        let matrices_finite = self.view_from_world.is_finite() && self.clip_from_view.is_finite();
        if !matrices_finite || !self.position_m.is_finite() {
            return Err(QuadtreeError::InvalidCamera(
                "matrix or position is not finite",
            ));
        }
        if !self.viewport_px.iter().all(|v| v.is_finite() && *v >= 1.0) {
            return Err(QuadtreeError::InvalidCamera(
                "viewport sides must be finite and >= 1 px",
            ));
        }
        Ok(())
    }
}
