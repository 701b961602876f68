//! A fixed camera path and a timing harness for the selection.

use std::time::Instant;

use glam::Vec3;

use crate::{
    Camera, LodSettings, MinMaxPyramid, QuadtreeError, Selection, max_neighbour_level_diff, select,
};

/// Viewport of the benchmark cameras.
pub const BENCH_VIEWPORT_PX: [f32; 2] = [1920.0, 1080.0];
/// Vertical field of view of the benchmark cameras (60 degrees).
pub const BENCH_FOV_Y_RAD: f32 = std::f32::consts::FRAC_PI_3;

/// A deterministic camera path over a terrain of `extent_m`, `frames` cameras at 1920x1080,
/// 60 degree vertical field of view, in three equal parts:
///
/// 1. a low fly-over along the south-west to north-east diagonal, at 1 % of the larger extent
///    side above z = 0, looking 10 degrees down with a gentle side-to-side sway;
/// 2. a high overview orbiting the centre at half the extent, 60 % of it up, looking at the
///    centre;
/// 3. a horizon view from near the south-west corner, 2 % up, looking 1 degree down toward the
///    north-east while panning +-40 degrees.
///
/// Altitudes are absolute (z = 0 is the sketch's base level).
pub fn bench_camera_path(extent_m: [f32; 2], frames: usize) -> Vec<Camera> {
    let [ex, ey] = extent_m;
    let size = ex.max(ey);
    let centre = Vec3::new(ex * 0.5, ey * 0.5, 0.0);
    let third = frames.div_ceil(3).max(1);
    let tau = std::f32::consts::TAU;
    (0..frames)
        .map(|f| {
            let (part, k) = (f / third, f % third);
            let t = k as f32 / third.saturating_sub(1).max(1) as f32;
            let (position, target) = match part {
                0 => {
                    let along = 0.1 + 0.8 * t;
                    let position = Vec3::new(ex * along, ey * along, 0.01 * size);
                    let yaw = std::f32::consts::FRAC_PI_4 + 0.25 * (tau * t).sin();
                    (
                        position,
                        position + direction(yaw, -10f32.to_radians()) * size,
                    )
                }
                1 => {
                    let angle = tau * t;
                    let offset = Vec3::new(angle.cos(), angle.sin(), 0.0) * 0.5 * size;
                    (centre + offset + Vec3::Z * 0.6 * size, centre)
                }
                _ => {
                    let position = Vec3::new(ex * 0.05, ey * 0.05, 0.02 * size);
                    let yaw = std::f32::consts::FRAC_PI_4 + 40f32.to_radians() * (tau * t).sin();
                    (
                        position,
                        position + direction(yaw, -1f32.to_radians()) * size,
                    )
                }
            };
            Camera::look_at(
                position,
                target,
                BENCH_FOV_Y_RAD,
                BENCH_VIEWPORT_PX,
                1.0,
                8.0 * size,
            )
        })
        .collect()
}

/// Unit vector with heading `yaw` (radians from east toward north) and elevation `pitch`.
fn direction(yaw: f32, pitch: f32) -> Vec3 {
    Vec3::new(
        yaw.cos() * pitch.cos(),
        yaw.sin() * pitch.cos(),
        pitch.sin(),
    )
}

/// Result of [`bench_lod`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LodBenchReport {
    /// Number of timed frames.
    pub frames: usize,
    /// Median wall time of one [`select`] call, microseconds.
    pub select_us_median: f64,
    /// Slowest [`select`] call, microseconds.
    pub select_us_max: f64,
    /// Median number of patches per frame.
    pub patches_median: usize,
    /// Median triangles per frame, `patches * 2 * leaf_cells^2`.
    pub triangles_median: u64,
    /// Largest level difference between edge-sharing patches over all frames
    /// ([`max_neighbour_level_diff`]).
    pub max_neighbour_level_diff: u32,
    /// Median nodes evaluated per frame.
    pub nodes_median: u32,
}

/// Runs [`select`] (all mips ready) over [`bench_camera_path`]`(settings.extent_m, frames)`:
/// one untimed warm-up pass over the path, then one timed pass. Build with `--release`.
pub fn bench_lod(
    pyramid: &MinMaxPyramid,
    settings: &LodSettings,
    frames: usize,
) -> Result<LodBenchReport, QuadtreeError> {
    let cameras = bench_camera_path(settings.extent_m, frames);
    let mut selection = Selection::new();
    for camera in &cameras {
        select(pyramid, settings, camera, 0, &mut selection)?;
    }
    let mut times_us = Vec::with_capacity(frames);
    let mut patches = Vec::with_capacity(frames);
    let mut nodes = Vec::with_capacity(frames);
    let mut worst_diff = 0;
    for camera in &cameras {
        let start = Instant::now();
        let stats = select(pyramid, settings, camera, 0, &mut selection)?;
        times_us.push(start.elapsed().as_secs_f64() * 1e6);
        patches.push(selection.patches.len());
        nodes.push(stats.nodes_visited);
        worst_diff = worst_diff.max(max_neighbour_level_diff(&selection.patches));
    }
    let select_us_max = times_us.iter().copied().fold(0.0, f64::max);
    times_us.sort_by(f64::total_cmp);
    patches.sort_unstable();
    nodes.sort_unstable();
    let median = |n: usize| n / 2;
    let patches_median = patches.get(median(frames)).copied().unwrap_or(0);
    let cells = settings.leaf_cells as u64;
    Ok(LodBenchReport {
        frames,
        select_us_median: times_us.get(median(frames)).copied().unwrap_or(0.0),
        select_us_max,
        patches_median,
        triangles_median: patches_median as u64 * 2 * cells * cells,
        max_neighbour_level_diff: worst_diff,
        nodes_median: nodes.get(median(frames)).copied().unwrap_or(0),
    })
}
