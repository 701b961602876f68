// Pass: lift_pull (ALGORITHM.md "FMG lift", cpu/lift.rs): one pull step of the FMG lift, level k+1 -> k.
// e = P g_{k+1}, the cell-centred bilinear prolongation clamped at the border (no cell inactive), computed
// in the CPU's order (`prolong_row`: the two coarse rows first, then along the row).
// mode 0 (k >= 1): g_k = a V_k + (1 - a) e in place of V_k, a = min(1, W_k) (packed storage as lift_push).
// mode 1 (k = 0): h = a_0 E + (1 - a_0) e, a_0 = `lift_weight0` (so h = E exactly on hard cells).
// Reads:  v[src_offset ..] (g_{k+1}, n/2 x n/2), w[dst_offset ..], v[dst_offset ..] (level k; mode 0),
//         diag, value (level 0; mode 1).
// Writes: v[dst_offset ..] (g_k; mode 0) or h (level 0, `#import h`: a buffer, or mip 0 of the
//         height texture; mode 1).
// Params: n = side of level k, mode, ax, ay, src_offset, dst_offset.
// Workgroup: 8 x 8, one thread per level-k cell (levels below 8 x 8 use one workgroup).
#import params
#import transfer
#import lift
#import h

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(2) var<storage, read> diag: array<f32>;
@group(0) @binding(3) var<storage, read> value: array<f32>;
@group(0) @binding(4) var<storage, read> w: array<f32>;
@group(0) @binding(5) var<storage, read_write> v: array<f32>;

fn g_coarse(ic: u32, jc: u32, nc: u32) -> f32 {
    return v[params.src_offset + jc * nc + ic];
}

@compute @workgroup_size(8, 8)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let n = params.n;
    let i = gid.x;
    let j = gid.y;
    if i >= n || j >= n {
        return;
    }
    let nc = n / 2u;
    let jc = j / 2u;
    let ic = i / 2u;
    let jn = p_side(j, nc);
    let inb = p_side(i, nc);
    let vc = 0.75 * g_coarse(ic, jc, nc) + 0.25 * g_coarse(ic, jn, nc);
    let vs = 0.75 * g_coarse(inb, jc, nc) + 0.25 * g_coarse(inb, jn, nc);
    let e = 0.75 * vc + 0.25 * vs;
    if params.mode == 0u {
        let idx = params.dst_offset + j * n + i;
        let a = min(w[idx], 1.0);
        v[idx] = a * v[idx] + (1.0 - a) * e;
    } else {
        let idx = j * n + i;
        let a = lift_weight0(i, j);
        h_put(i, j, a * value[idx] + (1.0 - a) * e);
    }
}
