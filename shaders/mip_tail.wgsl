// Pass: mip_tail (ALGORITHM.md "Mip chain"): up to four consecutive mip levels k0 .. of side <= 32
// in one workgroup, each as `mip_level` computes it (`#import mip_cell`): the first from level k0-1
// (mode 0, k0 = 1: the level-0 diagonal and mip 0; mode 1: the pyramid's level k0-1 and mip k0-1),
// the next ones from the level before, kept in workgroup memory.
// Reads:  src (mip k0-1, sampled view), diag (level 0; mode 0), pyramid[src_offset ..] (mode 1).
// Writes: dst0 .. dst3 (storage views of mips k0 .. k0+3; slots past `partials` are bound to a
//         1 x 1 stand-in and not written), pyramid[dst_offset ..] (levels k0 .., consecutive).
// Params: n = side of level k0-1 (<= 64), mode, src_offset, dst_offset, partials = levels (1..4).
// Workgroup: 16 x 16, one workgroup; each thread takes up to 4 cells of a level.
#import params
#import mip_cell

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var src: texture_2d<f32>;
@group(0) @binding(2) var dst0: texture_storage_2d<r32float, write>;
@group(0) @binding(3) var dst1: texture_storage_2d<r32float, write>;
@group(0) @binding(4) var dst2: texture_storage_2d<r32float, write>;
@group(0) @binding(5) var dst3: texture_storage_2d<r32float, write>;
@group(0) @binding(6) var<storage, read> diag: array<f32>;
@group(0) @binding(7) var<storage, read_write> pyramid: array<vec2<f32>>;

const WG: u32 = 256u;
// The last finished level (side <= 32): constraint pairs and heights.
var<workgroup> pairs: array<vec2<f32>, 1024>;
var<workgroup> heights: array<f32, 1024>;

// A cell from the finer level in workgroup memory (side nf).
fn next_cell(i: u32, j: u32, nf: u32) -> MipCell {
    let b = 2u * j * nf + 2u * i;
    return mip_combine(
        pairs[b], pairs[b + 1u], pairs[b + nf], pairs[b + nf + 1u],
        heights[b], heights[b + 1u], heights[b + nf], heights[b + nf + 1u],
    );
}

fn store(slot: u32, i: u32, j: u32, m: f32) {
    let v = vec4<f32>(m, 0.0, 0.0, 1.0);
    switch slot {
        case 0u: { textureStore(dst0, vec2<u32>(i, j), v); }
        case 1u: { textureStore(dst1, vec2<u32>(i, j), v); }
        case 2u: { textureStore(dst2, vec2<u32>(i, j), v); }
        default: { textureStore(dst3, vec2<u32>(i, j), v); }
    }
}

@compute @workgroup_size(16, 16)
fn main(@builtin(local_invocation_index) li: u32) {
    var nf = params.n;
    var dst = params.dst_offset;
    for (var level = 0u; level < params.partials; level++) {
        let nc = nf / 2u;
        let cells = nc * nc;
        var out: array<MipCell, 4>;
        for (var t = 0u; t < 4u; t++) {
            let idx = li + t * WG;
            if idx < cells {
                if level == 0u {
                    out[t] = mip_cell_from(idx % nc, idx / nc);
                } else {
                    out[t] = next_cell(idx % nc, idx / nc, nf);
                }
            }
        }
        // Every thread has read the finer level before any overwrites it.
        workgroupBarrier();
        for (var t = 0u; t < 4u; t++) {
            let idx = li + t * WG;
            if idx < cells {
                pairs[idx] = out[t].c;
                heights[idx] = out[t].m;
                pyramid[dst + idx] = out[t].c;
                store(level, idx % nc, idx / nc, out[t].m);
            }
        }
        workgroupBarrier();
        dst += cells;
        nf = nc;
    }
}
