// Pass: terrain (render). Draws the quadtree's patches: one instanced (N + 1)^2 grid per patch,
// displaced from the patch's heightmap mip and morphed toward the next coarser mip per the
// terrasketch-quadtree README contract (no cracks, no T-junctions). With the detail on (flags bit 4)
// the procedural detail is added: amplitude (level 1, bilinear) times the octave sum of the patch's
// mip (the noise texture, morphed like the heights); the CPU twin is `terrasketch_detail`.
// Normals from the displayed surface; with the detail on, the octaves finer than a heightmap cell
// shade them where the camera is close (`fine_detail.wgsl`, appended to this file: display only,
// never exported).
// Reads: heightmap, noise (R32Float, full mip chains), amplitude (R32Float, side
// amplitude_side), all row 0 = south, textureLoad only (no filtering feature needed); globals
// (uniform), per-instance patch data (vertex buffer, step mode instance).
// Writes: colour + depth. Workgroup: none (render pass).
// Keep `Globals` and `PatchInstance` in sync with `editor/render.rs`.

struct Globals {
    clip_from_world: mat4x4<f32>,
    eye_m: vec4<f32>,
    // xyz: unit vector toward the light.
    light_dir: vec4<f32>,
    extent_m: vec2<f32>,
    leaf_cells: u32,
    coarsest_mip: u32,
    height_min_m: f32,
    height_max_m: f32,
    contour_interval_m: f32,
    // bit 0 contours, bit 1 wireframe, bit 2 LOD colours, bit 3 constraint overlay, bit 4 detail.
    flags: u32,
    heightmap_side: u32,
    // The sketch's 32-bit detail seed.
    seed32: u32,
    // Side of the detail amplitude map (`terrasketch_detail::amplitude_side`).
    amplitude_side: u32,
    _pad2: u32,
    // The detail's Hurst exponent, reference wavelength (m), billow mean |n|, and the heightmap's
    // larger cell side (m).
    detail_shape: vec4<f32>,
};

@group(0) @binding(0) var<uniform> globals: Globals;
@group(0) @binding(1) var heightmap: texture_2d<f32>;
@group(0) @binding(2) var constraints: texture_2d<f32>;
@group(0) @binding(3) var noise: texture_2d<f32>;
@group(0) @binding(4) var amplitude: texture_2d<f32>;

struct PatchInstance {
    @location(0) uv_origin: vec2<f32>,
    @location(1) uv_size: f32,
    @location(2) mip_level: u32,
    @location(3) morph: vec4<f32>,
    @location(4) level: u32,
};

struct VsOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) world_m: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) grid: vec2<f32>,
    @location(3) @interpolate(flat) level: u32,
    @location(4) uv: vec2<f32>,
    @location(5) amp: f32,
};

// Bilinear sample of mip k of `map` (mip 0 of side `side0`) at uv, texel centres at (c + 0.5) / n_k,
// clamped at the borders. The same function for every patch and map (the CPU twins are
// `terrain::sample_bilinear` and `terrasketch_detail::sample_bilinear`).
fn sample_map(map: texture_2d<f32>, side0: u32, uv: vec2<f32>, k: u32) -> f32 {
    let side = max(side0 >> k, 1u);
    let s = f32(side);
    let p = clamp(uv * s - vec2<f32>(0.5), vec2<f32>(0.0), vec2<f32>(s - 1.0));
    let p0 = floor(p);
    let f = p - p0;
    let i0 = vec2<i32>(p0);
    let last = i32(side) - 1;
    let i1 = min(i0 + vec2<i32>(1), vec2<i32>(last));
    let h00 = textureLoad(map, vec2<i32>(i0.x, i0.y), i32(k)).r;
    let h10 = textureLoad(map, vec2<i32>(i1.x, i0.y), i32(k)).r;
    let h01 = textureLoad(map, vec2<i32>(i0.x, i1.y), i32(k)).r;
    let h11 = textureLoad(map, vec2<i32>(i1.x, i1.y), i32(k)).r;
    let south = h00 * (1.0 - f.x) + h10 * f.x;
    let north = h01 * (1.0 - f.x) + h11 * f.x;
    return south * (1.0 - f.y) + north * f.y;
}

fn sample_height(uv: vec2<f32>, k_in: u32) -> f32 {
    return sample_map(heightmap, globals.heightmap_side, uv, min(k_in, globals.coarsest_mip));
}

// The displayed surface: heights (and, with `amp` > 0, the detail) blended toward the coarser mip
// by m.
fn morphed_height(uv: vec2<f32>, mip: u32, m: f32, amp: f32) -> f32 {
    let k0 = min(mip, globals.coarsest_mip);
    let k1 = min(mip + 1u, globals.coarsest_mip);
    var fine = sample_map(heightmap, globals.heightmap_side, uv, k0);
    var coarse = sample_map(heightmap, globals.heightmap_side, uv, k1);
    if (amp > 0.0) {
        fine += amp * sample_map(noise, globals.heightmap_side, uv, k0);
        coarse += amp * sample_map(noise, globals.heightmap_side, uv, k1);
    }
    return fine * (1.0 - m) + coarse * m;
}

// Detail amplitude at uv (0 with the detail off).
fn detail_amplitude(uv: vec2<f32>) -> f32 {
    if ((globals.flags & 16u) == 0u || globals.amplitude_side < 1u) {
        return 0.0;
    }
    return sample_map(amplitude, globals.amplitude_side, uv, 0u);
}

@vertex
fn vs_main(@builtin(vertex_index) vi: u32, inst: PatchInstance) -> VsOut {
    let n = globals.leaf_cells;
    let i = vi % (n + 1u);
    let j = vi / (n + 1u);
    let g = vec2<f32>(f32(i), f32(j));
    let t = g / f32(n);
    // 1. Morph factor, edge-exact bilinear form (README contract).
    let south = inst.morph.x * (1.0 - t.x) + inst.morph.y * t.x;
    let north = inst.morph.z * (1.0 - t.x) + inst.morph.w * t.x;
    let m = south * (1.0 - t.y) + north * t.y;
    // 2. Odd grid lines slide onto their even neighbour.
    let odd = g - 2.0 * floor(g * 0.5);
    let g_m = g - odd * m;
    // 3. Position.
    let uv = inst.uv_origin + inst.uv_size * (g_m / f32(n));
    let xy_m = uv * globals.extent_m;
    // 4. Height, blended toward the coarser mip by m.
    let amp = detail_amplitude(uv);
    let z_m = morphed_height(uv, inst.mip_level, m, amp);
    // Normal: central differences of the same m-blended surface (the amplitude taken at the vertex), one texel of the patch's mip.
    let side = f32(max(globals.heightmap_side >> min(inst.mip_level, globals.coarsest_mip), 1u));
    let du = 1.0 / side;
    let he = morphed_height(uv + vec2<f32>(du, 0.0), inst.mip_level, m, amp);
    let hw = morphed_height(uv - vec2<f32>(du, 0.0), inst.mip_level, m, amp);
    let hn = morphed_height(uv + vec2<f32>(0.0, du), inst.mip_level, m, amp);
    let hs = morphed_height(uv - vec2<f32>(0.0, du), inst.mip_level, m, amp);
    let dzdx = (he - hw) / (2.0 * du * globals.extent_m.x);
    let dzdy = (hn - hs) / (2.0 * du * globals.extent_m.y);
    var out: VsOut;
    out.world_m = vec3<f32>(xy_m, z_m);
    out.clip = globals.clip_from_world * vec4<f32>(out.world_m, 1.0);
    out.normal = normalize(vec3<f32>(-dzdx, -dzdy, 1.0));
    out.grid = g_m;
    out.level = inst.level;
    out.uv = uv;
    out.amp = amp;
    return out;
}

fn elevation_tint(z: f32) -> vec3<f32> {
    let range = max(globals.height_max_m - globals.height_min_m, 1.0);
    let t = clamp((z - globals.height_min_m) / range, 0.0, 1.0);
    let low = vec3<f32>(0.30, 0.48, 0.24);
    let mid = vec3<f32>(0.55, 0.47, 0.32);
    let high = vec3<f32>(0.62, 0.60, 0.58);
    let top = vec3<f32>(0.95, 0.95, 0.97);
    if (t < 0.4) {
        return mix(low, mid, t / 0.4);
    } else if (t < 0.8) {
        return mix(mid, high, (t - 0.4) / 0.4);
    }
    return mix(high, top, (t - 0.8) / 0.2);
}

fn lod_colour(level: u32) -> vec3<f32> {
    let palette = array<vec3<f32>, 8>(
        vec3<f32>(0.90, 0.30, 0.30), vec3<f32>(0.95, 0.65, 0.25), vec3<f32>(0.90, 0.90, 0.30),
        vec3<f32>(0.40, 0.85, 0.35), vec3<f32>(0.30, 0.80, 0.85), vec3<f32>(0.35, 0.45, 0.95),
        vec3<f32>(0.70, 0.40, 0.90), vec3<f32>(0.90, 0.45, 0.70));
    return palette[level % 8u];
}

@fragment
fn fs_main(in: VsOut) -> @location(0) vec4<f32> {
    // The pixel's footprint on the ground (outside any branch: derivatives need uniform control).
    let footprint = max(length(dpdx(in.world_m.xy)), length(dpdy(in.world_m.xy)));
    var n = normalize(in.normal);
    if ((globals.flags & 16u) != 0u && in.amp > 0.0) {
        let d = fine_detail(in.world_m.xy, globals.detail_shape.w, max(footprint, 1e-3),
            globals.seed32, globals.detail_shape.xyz);
        n = normalize(vec3<f32>(n.xy / max(n.z, 1e-3) - in.amp * d.yz, 1.0));
    }
    var base = elevation_tint(in.world_m.z);
    if ((globals.flags & 4u) != 0u) {
        base = mix(base, lod_colour(in.level), 0.6);
    }
    if ((globals.flags & 8u) != 0u) {
        let side = max(globals.heightmap_side, 1u);
        let c = vec2<i32>(clamp(in.uv * f32(side), vec2<f32>(0.0), vec2<f32>(f32(side) - 1.0)));
        let w = textureLoad(constraints, c, 0).r;
        base = mix(base, vec3<f32>(0.95, 0.15, 0.85), 0.7 * w);
    }
    let diffuse = max(dot(n, globals.light_dir.xyz), 0.0);
    var colour = base * (0.35 + 0.75 * diffuse);
    if ((globals.flags & 1u) != 0u) {
        let z = in.world_m.z / max(globals.contour_interval_m, 1.0);
        let fw = max(fwidth(z), 1e-4);
        let d = abs(fract(z - 0.5) - 0.5) / fw;
        let line = 1.0 - clamp(d - 0.5, 0.0, 1.0);
        colour = mix(colour, vec3<f32>(0.12, 0.10, 0.08), 0.6 * line);
    }
    if ((globals.flags & 2u) != 0u) {
        let fw = max(fwidth(in.grid), vec2<f32>(1e-4));
        let d = abs(fract(in.grid - vec2<f32>(0.5)) - vec2<f32>(0.5)) / fw;
        let line = 1.0 - clamp(min(d.x, d.y) - 0.5, 0.0, 1.0);
        colour = mix(colour, vec3<f32>(0.05, 0.05, 0.05), 0.7 * line);
    }
    // Aerial perspective: fade toward the sky with distance.
    let dist = length(in.world_m - globals.eye_m.xyz);
    let fog = clamp(dist / (3.0 * max(globals.extent_m.x, globals.extent_m.y)), 0.0, 0.6);
    colour = mix(colour, vec3<f32>(0.62, 0.74, 0.86), fog);
    return vec4<f32>(colour, 1.0);
}
