// Pass: mip_constraints (ALGORITHM.md "Mip chain"): per mip level k >= 1 and cell, the number of hard level-0
// cells in its footprint and the sum of their E, as vec2(count, sum). Built from level 0 (mode 0) or from
// level k-1 of the same pyramid buffer (mode 1): W_k = count > 0, Ebar_k = sum / count.
// Level 0 is read from the assembled operator: a cell is hard exactly where diag == 0 (free cells have
// diag >= their in-domain edge weights > 0), and there h == E (the assembly sets it and no pass changes
// it), so the problem's weight and value are not needed after the assembly.
// Reads:  diag, h (level 0, `#import h_read`: a buffer, or mip 0 of the height texture; mode 0),
//         pyramid[src_offset ..] (level k-1; mode 1).
// Writes: pyramid[dst_offset ..] (level k, n/2 x n/2).
// Params: n = side of the finer level (level 0 in mode 0, level k-1 in mode 1), mode, src_offset, dst_offset.
// Workgroup: 8 x 8 over (n/2, n/2) threads.
#import params
#import h_read

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(2) var<storage, read> diag: array<f32>;
@group(0) @binding(3) var<storage, read_write> pyramid: array<vec2<f32>>;

fn child(idx: u32) -> vec2<f32> {
    if params.mode == 0u {
        if diag[idx] == 0.0 {
            return vec2<f32>(1.0, h_get(idx % params.n, idx / params.n));
        }
        return vec2<f32>(0.0, 0.0);
    }
    return pyramid[params.src_offset + idx];
}

@compute @workgroup_size(8, 8)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let nf = params.n;
    let nc = nf / 2u;
    let ic = gid.x;
    let jc = gid.y;
    if ic >= nc || jc >= nc {
        return;
    }
    let b = 2u * jc * nf + 2u * ic;
    pyramid[params.dst_offset + jc * nc + ic] = child(b) + child(b + 1u) + child(b + nf) + child(b + nf + 1u);
}
