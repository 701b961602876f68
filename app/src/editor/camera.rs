//! The editor's camera: orbit around a target, pan, zoom to the cursor, fly (WASD + mouse), top view,
//! frame all. World space: x east, y north, z up, metres; wgpu clip space (depth in [0, 1]).

use glam::{Mat4, Vec2, Vec3, Vec4Swizzles};

/// Camera state (what the user moves).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ViewCamera {
    /// Point orbited around, metres.
    pub target_m: Vec3,
    /// Eye distance from the target, metres.
    pub distance_m: f32,
    /// Heading of the view direction, radians from east toward north.
    pub yaw: f32,
    /// Elevation of the view direction, radians (negative looks down).
    pub pitch: f32,
    /// Vertical field of view, radians.
    pub fov_y: f32,
    /// Fly mode: the mouse turns the view around the eye, WASD moves it.
    pub fly: bool,
}

/// A picking ray.
#[derive(Debug, Clone, Copy)]
pub struct Ray {
    /// Origin, metres.
    pub origin: Vec3,
    /// Unit direction.
    pub dir: Vec3,
}

/// The matrices of one frame (a snapshot: drawing keeps the camera of the stroke's start).
#[derive(Debug, Clone, Copy)]
pub struct Projection {
    /// World to view.
    pub view_from_world: Mat4,
    /// View to clip.
    pub clip_from_view: Mat4,
    /// Viewport in pixels.
    pub viewport_px: Vec2,
    /// Eye position.
    pub eye_m: Vec3,
}

const MIN_PITCH: f32 = -1.5690; // just short of straight down (look_at needs a defined up)
const MAX_PITCH: f32 = 1.2;

impl ViewCamera {
    /// A camera framing an extent (oblique view from the south).
    pub fn framing(extent_m: [f64; 2], z_range_m: [f32; 2]) -> ViewCamera {
        let mut c = ViewCamera {
            target_m: Vec3::ZERO,
            distance_m: 1.0,
            yaw: std::f32::consts::FRAC_PI_2,
            pitch: -0.6,
            fov_y: 50f32.to_radians(),
            fly: false,
        };
        c.frame_all(extent_m, z_range_m);
        c
    }

    /// Unit view direction.
    pub fn forward(&self) -> Vec3 {
        Vec3::new(
            self.pitch.cos() * self.yaw.cos(),
            self.pitch.cos() * self.yaw.sin(),
            self.pitch.sin(),
        )
    }

    /// Eye position.
    pub fn eye_m(&self) -> Vec3 {
        self.target_m - self.forward() * self.distance_m
    }

    /// Places the target at the centre and backs off until the whole extent is in view.
    pub fn frame_all(&mut self, extent_m: [f64; 2], z_range_m: [f32; 2]) {
        let (ex, ey) = (extent_m[0] as f32, extent_m[1] as f32);
        let zmid = 0.5 * (z_range_m[0] + z_range_m[1]);
        self.target_m = Vec3::new(
            ex * 0.5,
            ey * 0.5,
            if zmid.is_finite() { zmid } else { 0.0 },
        );
        let radius = 0.5 * (ex * ex + ey * ey).sqrt();
        self.distance_m = radius / (0.5 * self.fov_y).tan() * 0.95;
        if self.pitch > -0.2 {
            self.pitch = -0.6;
        }
        self.fly = false;
    }

    /// Looks straight down at the target (toggle back with `frame_all` or orbiting).
    pub fn top_view(&mut self) {
        self.pitch = MIN_PITCH;
        self.yaw = std::f32::consts::FRAC_PI_2;
    }

    /// Turns the view by a mouse delta in pixels: around the target when orbiting, around the eye in
    /// fly mode.
    pub fn rotate(&mut self, delta_px: Vec2) {
        let eye = self.eye_m();
        self.yaw -= delta_px.x * 0.005;
        self.pitch = (self.pitch - delta_px.y * 0.005).clamp(MIN_PITCH, MAX_PITCH);
        if self.fly {
            self.target_m = eye + self.forward() * self.distance_m;
        }
    }

    /// Moves the target (and eye) parallel to the ground by a mouse delta in pixels.
    pub fn pan(&mut self, delta_px: Vec2, viewport_px: Vec2) {
        let scale = 2.0 * self.distance_m * (0.5 * self.fov_y).tan() / viewport_px.y.max(1.0);
        let right = Vec3::new(self.yaw.sin(), -self.yaw.cos(), 0.0);
        let ahead = Vec3::new(self.yaw.cos(), self.yaw.sin(), 0.0);
        self.target_m += (-right * delta_px.x + ahead * delta_px.y) * scale;
    }

    /// Zooms by `factor` (< 1 comes closer) toward a world point (the terrain under the cursor).
    pub fn zoom_to(&mut self, factor: f32, toward_m: Option<Vec3>) {
        let factor = factor.clamp(0.2, 5.0);
        let new_distance = (self.distance_m * factor).clamp(10.0, 1.0e6);
        let f = new_distance / self.distance_m;
        if let Some(p) = toward_m {
            self.target_m = p + (self.target_m - p) * f;
        }
        self.distance_m = new_distance;
    }

    /// Fly-mode movement: `local` = (right, forward, up) in metres.
    pub fn fly_move(&mut self, local: Vec3) {
        let f = self.forward();
        let right = f.cross(Vec3::Z).normalize_or_zero();
        self.target_m += right * local.x + f * local.y + Vec3::Z * local.z;
    }

    /// The matrices for a viewport with nothing drawn over it.
    #[cfg(test)]
    pub fn projection(&self, viewport_px: Vec2, extent_m: [f64; 2]) -> Projection {
        self.projection_beside_panel(viewport_px, 0.0, extent_m)
    }

    /// The matrices for a viewport whose left `panel_px` pixels are covered by a side panel: the
    /// image centre (and so the orbit target and "frame all") moves to the centre of the free area by
    /// shifting the projection (an off-centre frustum), so nothing is squeezed and picking stays exact.
    pub fn projection_beside_panel(
        &self,
        viewport_px: Vec2,
        panel_px: f32,
        extent_m: [f64; 2],
    ) -> Projection {
        let eye = self.eye_m();
        let view_from_world = glam::camera::rh::view::look_at_mat4(eye, self.target_m, Vec3::Z);
        let size = extent_m[0].max(extent_m[1]) as f32;
        let near = (self.distance_m * 0.01).clamp(0.5, 50.0);
        let far = (self.distance_m + 4.0 * size).max(near * 10.0);
        let aspect = viewport_px.x.max(1.0) / viewport_px.y.max(1.0);
        let shift_ndc = (panel_px / viewport_px.x.max(1.0)).clamp(0.0, 0.9);
        let clip_from_view = Mat4::from_translation(Vec3::new(shift_ndc, 0.0, 0.0))
            * glam::camera::rh::proj::directx::perspective(self.fov_y, aspect, near, far);
        Projection {
            view_from_world,
            clip_from_view,
            viewport_px,
            eye_m: eye,
        }
    }
}

impl Projection {
    /// World to clip.
    pub fn clip_from_world(&self) -> Mat4 {
        self.clip_from_view * self.view_from_world
    }

    /// The ray through a window pixel (origin at the eye).
    pub fn ray(&self, px: Vec2) -> Ray {
        let ndc = Vec2::new(
            2.0 * px.x / self.viewport_px.x.max(1.0) - 1.0,
            1.0 - 2.0 * px.y / self.viewport_px.y.max(1.0),
        );
        let inv = self.clip_from_world().inverse();
        let far = inv * glam::Vec4::new(ndc.x, ndc.y, 1.0, 1.0);
        let near = inv * glam::Vec4::new(ndc.x, ndc.y, 0.0, 1.0);
        let far = far.xyz() / far.w;
        let near = near.xyz() / near.w;
        let dir = (far - near).normalize_or_zero();
        Ray {
            origin: self.eye_m,
            dir,
        }
    }

    /// Window pixel of a world point, or `None` behind the camera.
    pub fn screen_position(&self, p: Vec3) -> Option<Vec2> {
        let c = self.clip_from_world() * p.extend(1.0);
        if c.w <= 1e-6 {
            return None;
        }
        let ndc = c.xyz() / c.w;
        Some(Vec2::new(
            (ndc.x + 1.0) * 0.5 * self.viewport_px.x,
            (1.0 - ndc.y) * 0.5 * self.viewport_px.y,
        ))
    }
}

impl Ray {
    /// Intersection with the horizontal plane `z = z_m` (in front of the origin).
    pub fn hit_horizontal(&self, z_m: f32) -> Option<Vec3> {
        if self.dir.z.abs() < 1e-6 {
            return None;
        }
        let t = (z_m - self.origin.z) / self.dir.z;
        (t > 0.0).then(|| self.origin + self.dir * t)
    }

    /// Intersection with the plane through `p` with unit normal `n`, if in front and not grazing.
    pub fn hit_plane(&self, p: Vec3, n: Vec3, max_t: f32) -> Option<Vec3> {
        let d = self.dir.dot(n);
        if d.abs() < 1e-4 {
            return None;
        }
        let t = (p - self.origin).dot(n) / d;
        (t > 0.0 && t < max_t).then(|| self.origin + self.dir * t)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn screen_and_ray_agree() {
        let cam = ViewCamera::framing([10240.0, 10240.0], [0.0, 500.0]);
        let proj = cam.projection(Vec2::new(640.0, 400.0), [10240.0, 10240.0]);
        let p = Vec3::new(5000.0, 6000.0, 100.0);
        let s = proj.screen_position(p).unwrap();
        let r = proj.ray(s);
        let back = r.hit_horizontal(100.0).unwrap();
        assert!((back - p).length() < 1.0, "{back} vs {p}");
        let c = proj.screen_position(cam.target_m).unwrap();
        assert!((c - Vec2::new(320.0, 200.0)).length() < 0.5);
    }

    #[test]
    fn a_side_panel_moves_the_image_centre_to_the_free_area_and_picking_stays_exact() {
        let cam = ViewCamera::framing([10240.0, 10240.0], [0.0, 500.0]);
        let proj = cam.projection_beside_panel(Vec2::new(960.0, 600.0), 280.0, [10240.0; 2]);
        // The orbit target is drawn at the centre of the area right of the panel.
        let c = proj.screen_position(cam.target_m).unwrap();
        assert!(
            (c - Vec2::new(280.0 + 0.5 * 680.0, 300.0)).length() < 0.5,
            "{c}"
        );
        // Pixels still map to the world points drawn there.
        for p in [
            Vec3::new(200.0, 300.0, 0.0),
            Vec3::new(9000.0, 8000.0, 400.0),
        ] {
            let s = proj.screen_position(p).unwrap();
            let back = proj.ray(s).hit_horizontal(p.z).unwrap();
            assert!((back - p).length() < 1.0, "{back} vs {p}");
        }
        // The whole terrain is right of the panel after "frame all".
        for corner in [
            [0.0, 0.0],
            [10240.0, 0.0],
            [0.0, 10240.0],
            [10240.0, 10240.0],
        ] {
            for z in [0.0, 500.0] {
                let s = proj
                    .screen_position(Vec3::new(corner[0], corner[1], z))
                    .unwrap();
                assert!(
                    s.x > 280.0 && s.x < 960.0 && s.y > 0.0 && s.y < 600.0,
                    "{s}"
                );
            }
        }
    }
}
