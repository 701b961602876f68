// Pass: mip_level (ALGORITHM.md "Mip chain"): mip level k >= 1 of the constraint pyramid and of the
// height texture in one pass (`#import mip_cell`): per cell of level k, the four children's
// constraint pairs summed (mode 0, k = 1: from the level-0 diagonal and mip 0, which is `h`; mode 1:
// from level k-1 of the pyramid) and the display downsample of mip k-1.
// Reads:  src (mip k-1, sampled R32Float view, textureLoad only), diag (level 0; mode 0),
//         pyramid[src_offset ..] (level k-1; mode 1).
// Writes: dst (R32Float storage view of mip k), pyramid[dst_offset ..] (level k, n/2 x n/2).
// Params: n = side of level k-1, mode, src_offset, dst_offset.
// Workgroup: 8 x 8 over (n/2, n/2) threads.
#import params
#import mip_cell

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var src: texture_2d<f32>;
@group(0) @binding(2) var dst: texture_storage_2d<r32float, write>;
@group(0) @binding(3) var<storage, read> diag: array<f32>;
@group(0) @binding(4) var<storage, read_write> pyramid: array<vec2<f32>>;

@compute @workgroup_size(8, 8)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let nc = params.n / 2u;
    let i = gid.x;
    let j = gid.y;
    if i >= nc || j >= nc {
        return;
    }
    let cell = mip_cell_from(i, j);
    pyramid[params.dst_offset + j * nc + i] = cell.c;
    textureStore(dst, vec2<u32>(i, j), vec4<f32>(cell.m, 0.0, 0.0, 1.0));
}
