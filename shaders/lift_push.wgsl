// Pass: lift_push (ALGORITHM.md "FMG lift", cpu/lift.rs): one push step of the FMG lift, level k-1 -> k.
// Per level-k cell: W_k = sum of the 4 children's weights a, V_k = their a-weighted mean of the values
// (0 where the weight sum is 0). Children in the order (0,0), (1,0), (0,1), (1,1) as on the CPU.
// mode 0 (k = 1): from level 0, a = a_0 (`lift_weight0`), values E.
// mode 1 (k >= 2): from level k-1 of the packed storage, a = min(1, W_{k-1}), values V_{k-1}.
// Levels 1 ..= log2 n are packed in `w` and `v` (level k at element offset sum_{l<k} (n0 >> l)^2); the
// solver lends them its level-0 z (the preconditioner's output) and FCG's p, dead during FMG.
// Reads:  diag, value (level 0; mode 0), w[src_offset ..], v[src_offset ..] (level k-1; mode 1).
// Writes: w[dst_offset ..], v[dst_offset ..] (level k, n/2 x n/2).
// Params: n = side of level k-1, mode, ax, ay, src_offset, dst_offset.
// Workgroup: 8 x 8 over (n/2, n/2) threads (levels below 8 x 8 use one workgroup).
#import params
#import lift

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> diag: array<f32>;
@group(0) @binding(2) var<storage, read> value: array<f32>;
@group(0) @binding(3) var<storage, read_write> w: array<f32>;
@group(0) @binding(4) var<storage, read_write> v: array<f32>;

@compute @workgroup_size(8, 8)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let nf = params.n;
    let nc = nf / 2u;
    let ic = gid.x;
    let jc = gid.y;
    if ic >= nc || jc >= nc {
        return;
    }
    var sw = 0.0;
    var sv = 0.0;
    for (var dj = 0u; dj < 2u; dj++) {
        for (var di = 0u; di < 2u; di++) {
            let i = 2u * ic + di;
            let j = 2u * jc + dj;
            var a: f32;
            var x: f32;
            if params.mode == 0u {
                a = lift_weight0(i, j);
                x = value[j * nf + i];
            } else {
                let idx = params.src_offset + j * nf + i;
                a = min(w[idx], 1.0);
                x = v[idx];
            }
            sw += a;
            sv += a * x;
        }
    }
    let c = params.dst_offset + jc * nc + ic;
    w[c] = sw;
    if sw > 0.0 {
        v[c] = sv / sw;
    } else {
        v[c] = 0.0;
    }
}
