// Pass: restrict_sum: out = sum of the 4 children of fine (FMG right-hand sides f_{k+1} = R f_k).
// Reads:  fine (level k, n x n).
// Writes: out (level k+1, n/2 x n/2).
// Params: n = side of level k.
// Workgroup: 8 x 8 over (n/2, n/2) threads.
#import params

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> fine: array<f32>;
@group(0) @binding(2) var<storage, read_write> out: array<f32>;

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
    out[jc * nc + ic] = fine[b] + fine[b + 1u] + fine[b + nf] + fine[b + nf + 1u];
}
