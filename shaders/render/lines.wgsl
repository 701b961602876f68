// Pass: lines (render). Stroke curves and handles as 3D line segments drawn over the terrain.
// Reads: globals (uniform, the terrain pass's `Globals`: only `clip_from_world` is used), per-vertex
// position (metres) and colour. Writes: colour (no depth write). Workgroup: none (render pass).
// Keep `Globals` in sync with `terrain.wgsl` and `editor/render.rs`.

struct Globals {
    clip_from_world: mat4x4<f32>,
    eye_m: vec4<f32>,
    light_dir: vec4<f32>,
    extent_m: vec2<f32>,
    leaf_cells: u32,
    coarsest_mip: u32,
    height_min_m: f32,
    height_max_m: f32,
    contour_interval_m: f32,
    flags: u32,
    heightmap_side: u32,
    seed32: u32,
    amplitude_side: u32,
    _pad2: u32,
    detail_shape: vec4<f32>,
};

@group(0) @binding(0) var<uniform> globals: Globals;

struct VsOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) colour: vec4<f32>,
};

@vertex
fn vs_main(@location(0) position_m: vec3<f32>, @location(1) colour: vec4<f32>) -> VsOut {
    var out: VsOut;
    out.clip = globals.clip_from_world * vec4<f32>(position_m, 1.0);
    out.colour = colour;
    return out;
}

@fragment
fn fs_main(in: VsOut) -> @location(0) vec4<f32> {
    return in.colour;
}
