// Pass: detail_amplitude (compute). The GPU solver's detail amplitude on level `AMPLITUDE_LEVEL`
// (side m): the calibrated RMS for that mip's slope, scaled by the diffused roughness, faded out
// around blocks holding hard elevation constraints. The CPU twin is
// `terrasketch_detail::amplitude_map`.
// Reads: heights (the mip of the map's level in the solver's texture), roughness (the roughness
//        solve's last solution, level 2 of side rough_side, read at the cell covering each map
//        cell), pyramid (the map's level of the mips' constraint pyramid: vec2(hard count, sum) per
//        cell).
// Writes: amplitude (R32Float storage texture, m x m, row 0 = south).
// Params: m, element offsets of roughness and pyramid in their buffers, the roughness's side, the
//         map's cell size, the calibration constants (from the Rust crate, not repeated here).
// Workgroup: 8 x 8 over (m, m) threads.

struct Params {
    m: u32,
    rough_offset: u32,
    pyramid_offset: u32,
    rough_side: u32,
    cell_m: vec2<f32>,
    // RMS on flat land, growth per unit slope tangent, the tangent where it stops growing.
    rms_flat_m: f32,
    rms_per_slope_m: f32,
    slope_tan_max: f32,
    // 1 / (roughness reference * octave-sum residual RMS).
    gain: f32,
    zero_cells: i32,
    fade_cells: i32,
};

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var heights: texture_2d<f32>;
@group(0) @binding(2) var<storage, read> roughness: array<f32>;
@group(0) @binding(3) var<storage, read> pyramid: array<vec2<f32>>;
@group(0) @binding(4) var amplitude: texture_storage_2d<r32float, write>;

fn h(i: i32, j: i32) -> f32 {
    return textureLoad(heights, vec2<i32>(i, j), 0).r;
}

@compute @workgroup_size(8, 8)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let m = i32(params.m);
    let i = i32(gid.x);
    let j = i32(gid.y);
    if (i >= m || j >= m) {
        return;
    }
    // Chebyshev distance to the nearest block with a hard cell, capped past the fade.
    let reach = params.zero_cells + params.fade_cells;
    var d = reach + 1;
    for (var dj = -reach; dj <= reach; dj++) {
        for (var di = -reach; di <= reach; di++) {
            let x = i + di;
            let y = j + dj;
            if (x >= 0 && x < m && y >= 0 && y < m) {
                if (pyramid[params.pyramid_offset + u32(y * m + x)].x > 0.0) {
                    d = min(d, max(abs(di), abs(dj)));
                }
            }
        }
    }
    let t = clamp(f32(d - params.zero_cells) / f32(params.fade_cells), 0.0, 1.0);
    let fade = t * t * (3.0 - 2.0 * t);
    var a = 0.0;
    if (fade > 0.0) {
        let im = max(i - 1, 0);
        let ip = min(i + 1, m - 1);
        let jm = max(j - 1, 0);
        let jp = min(j + 1, m - 1);
        let gx = (h(ip, j) - h(im, j)) / (f32(ip - im) * params.cell_m.x);
        let gy = (h(i, jp) - h(i, jm)) / (f32(jp - jm) * params.cell_m.y);
        let slope = sqrt(gx * gx + gy * gy);
        let rs = params.rough_side;
        let ri = u32(i) * rs / params.m;
        let rj = u32(j) * rs / params.m;
        let r = clamp(roughness[params.rough_offset + rj * rs + ri], 0.0, 1.0);
        let rms = params.rms_flat_m + params.rms_per_slope_m * min(slope, params.slope_tan_max);
        a = fade * rms * r * params.gain;
    }
    textureStore(amplitude, vec2<i32>(i, j), vec4<f32>(a, 0.0, 0.0, 0.0));
}
