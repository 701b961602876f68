// Pass: mip_level0: mip 0 of the height texture is the level-0 solution h. Texel (i, j) = cell (i, j)
// (row 0 = south, as in the solver).
// Reads:  h (level 0, n x n).
// Writes: dst (R32Float storage texture view of mip 0).
// Params: n = level-0 side.
// Workgroup: 8 x 8, one thread per texel.
#import params

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> h: array<f32>;
@group(0) @binding(2) var dst: texture_storage_2d<r32float, write>;

@compute @workgroup_size(8, 8)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let n = params.n;
    if gid.x >= n || gid.y >= n {
        return;
    }
    textureStore(dst, vec2<u32>(gid.x, gid.y), vec4<f32>(h[gid.y * n + gid.x], 0.0, 0.0, 1.0));
}
