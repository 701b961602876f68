// Pass: minmax_reduce: every coarser level of the min/max pyramid below the finest stored one, in one
// workgroup (min of the 4 children's mins, max of their maxes; exact). Level after level, each written
// after a barrier that makes the finer one visible to the whole workgroup.
// Reads:  minmax[0 ..] (the finest stored level, n x n, then each level as it is written).
// Writes: minmax[n^2 ..] (the levels of side n/2 .. 1, consecutive).
// Params: n = side of the finest stored level (<= 64).
// Workgroup: 16 x 16, one workgroup; each thread takes up to 4 cells of a level.
#import params

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read_write> minmax: array<vec2<f32>>;

const WG: u32 = 256u;

@compute @workgroup_size(16, 16)
fn main(@builtin(local_invocation_index) li: u32) {
    var nf = params.n;
    var src = 0u;
    loop {
        if nf <= 1u {
            break;
        }
        let nc = nf / 2u;
        let dst = src + nf * nf;
        for (var idx = li; idx < nc * nc; idx += WG) {
            let b = src + 2u * (idx / nc) * nf + 2u * (idx % nc);
            let a = minmax[b];
            let c = minmax[b + 1u];
            let d = minmax[b + nf];
            let e = minmax[b + nf + 1u];
            let mn = min(min(a.x, c.x), min(d.x, e.x));
            let mx = max(max(a.y, c.y), max(d.y, e.y));
            minmax[dst + idx] = vec2<f32>(mn, mx);
        }
        storageBarrier();
        src = dst;
        nf = nc;
    }
}
