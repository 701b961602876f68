// Pass: prolong_level0: cell-centred bilinear interpolation of level-1 values onto level 0.
// x += P u1 on free cells (hard cells untouched). Bound with x = z in the preconditioner and x = h at the
// end of FMG (h = g + P u1, the lift g holding E on hard cells).
// Reads:  u1 (level 1, n/2 x n/2), diag (level 0).
// Writes: x (`#import h`: a buffer, or mip 0 of the height texture for h; level 0).
// Params: n = level-0 side.
// Workgroup: 8 x 8, one thread per level-0 cell.
#import params
#import transfer
#import h

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(2) var<storage, read> u1: array<f32>;
@group(0) @binding(3) var<storage, read> diag: array<f32>;

@compute @workgroup_size(8, 8)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let n = params.n;
    let i = gid.x;
    let j = gid.y;
    if i >= n || j >= n {
        return;
    }
    let idx = j * n + i;
    if diag[idx] == 0.0 {
        return;
    }
    let nc = n / 2u;
    let jc = j / 2u;
    let ic = i / 2u;
    let jn = p_side(j, nc);
    let inb = p_side(i, nc);
    let e = 0.5625 * u1[jc * nc + ic] + 0.1875 * (u1[jc * nc + inb] + u1[jn * nc + ic]) + 0.0625 * u1[jn * nc + inb];
    h_put(i, j, h_get(i, j) + e);
}
