// Pass: mip_downsample (ALGORITHM.md "Mip chain"): display downsample of mip k-1 into mip k,
// m_k = W_k Ebar_k + (1 - W_k) avg(4 children), so thin constrained curves survive on every level.
// Reads:  src (mip k-1, sampled R32Float view, textureLoad only), pyramid[src_offset ..] (level k:
//         vec2(hard count, sum of E)).
// Writes: dst (R32Float storage view of mip k).
// Params: n = side of mip k, src_offset = offset of level k in the constraint pyramid.
// Workgroup: 8 x 8, one thread per texel of mip k.
#import params

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var src: texture_2d<f32>;
@group(0) @binding(2) var dst: texture_storage_2d<r32float, write>;
@group(0) @binding(3) var<storage, read> pyramid: array<vec2<f32>>;

@compute @workgroup_size(8, 8)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let n = params.n;
    let i = gid.x;
    let j = gid.y;
    if i >= n || j >= n {
        return;
    }
    let c = pyramid[params.src_offset + j * n + i];
    var m: f32;
    if c.x > 0.0 {
        m = c.y / c.x;
    } else {
        let a = textureLoad(src, vec2<u32>(2u * i, 2u * j), 0).x;
        let b = textureLoad(src, vec2<u32>(2u * i + 1u, 2u * j), 0).x;
        let d = textureLoad(src, vec2<u32>(2u * i, 2u * j + 1u), 0).x;
        let e = textureLoad(src, vec2<u32>(2u * i + 1u, 2u * j + 1u), 0).x;
        m = 0.25 * (a + b + d + e);
    }
    textureStore(dst, vec2<u32>(i, j), vec4<f32>(m, 0.0, 0.0, 1.0));
}
