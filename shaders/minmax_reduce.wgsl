// Pass: minmax_reduce: next coarser level of the min/max pyramid (min of the 4 children's mins, max of their
// maxes; exact).
// Reads:  minmax[src_offset ..] (finer level, n x n).
// Writes: minmax[dst_offset ..] (coarser level, n/2 x n/2).
// Params: n = side of the finer level, src_offset, dst_offset.
// Workgroup: 8 x 8 over (n/2, n/2) threads.
#import params

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read_write> minmax: array<vec2<f32>>;

@compute @workgroup_size(8, 8)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let nf = params.n;
    let nc = nf / 2u;
    if gid.x >= nc || gid.y >= nc {
        return;
    }
    let b = params.src_offset + 2u * gid.y * nf + 2u * gid.x;
    let a = minmax[b];
    let c = minmax[b + 1u];
    let d = minmax[b + nf];
    let e = minmax[b + nf + 1u];
    let mn = min(min(a.x, c.x), min(d.x, e.x));
    let mx = max(max(a.y, c.y), max(d.y, e.y));
    minmax[params.dst_offset + gid.y * nc + gid.x] = vec2<f32>(mn, mx);
}
