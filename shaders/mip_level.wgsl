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

fn pair(i: u32, j: u32, h: f32) -> vec2<f32> {
    if params.mode == 0u {
        return mip_level0_pair(diag[j * params.n + i], h);
    }
    return pyramid[params.src_offset + j * params.n + i];
}

@compute @workgroup_size(8, 8)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let nc = params.n / 2u;
    let i = gid.x;
    let j = gid.y;
    if i >= nc || j >= nc {
        return;
    }
    let h00 = textureLoad(src, vec2<u32>(2u * i, 2u * j), 0).x;
    let h10 = textureLoad(src, vec2<u32>(2u * i + 1u, 2u * j), 0).x;
    let h01 = textureLoad(src, vec2<u32>(2u * i, 2u * j + 1u), 0).x;
    let h11 = textureLoad(src, vec2<u32>(2u * i + 1u, 2u * j + 1u), 0).x;
    let cell = mip_combine(
        pair(2u * i, 2u * j, h00), pair(2u * i + 1u, 2u * j, h10),
        pair(2u * i, 2u * j + 1u, h01), pair(2u * i + 1u, 2u * j + 1u, h11),
        h00, h10, h01, h11,
    );
    pyramid[params.dst_offset + j * nc + i] = cell.c;
    textureStore(dst, vec2<u32>(i, j), vec4<f32>(cell.m, 0.0, 0.0, 1.0));
}
