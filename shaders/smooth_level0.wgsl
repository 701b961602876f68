// Pass: smooth_level0 (ALGORITHM.md "Smoothers"): one red-black Gauss-Seidel colour on level 0.
// Keep the cell update in sync with `update` in smooth_level0_tiles.wgsl (the first sweep from 0).
// Thread (t, j) updates cell i = 2t + ((j + colour) & 1) of row j: x_i = (rhs_i + sum_j a_ij x_j) / diag_i.
// mode 1: the post-sweep's first colour with the prolongation before it (prolong_level0.wgsl,
//         x += P u1 on free cells) applied to the neighbours as they are read. The update reads
//         only the other colour, and the next colour pass overwrites every free cell of that
//         colour, so the prolonged values need not be stored; this pass's own cells' are never read.
// Reads:  rhs, diag (level 0); x (neighbours, of the other colour); u1 (level 1, mode 1).
// Writes: x on the free cells of this colour (hard cells, diag == 0, are never touched).
// Params: n = level-0 side, colour in {0, 1}, mode, ax, ay.
// Workgroup: 8 x 8 over (n/2, n) threads.
#import params
#import transfer

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read_write> x: array<f32>;
@group(0) @binding(2) var<storage, read> rhs: array<f32>;
@group(0) @binding(3) var<storage, read> diag: array<f32>;
@group(0) @binding(4) var<storage, read> u1: array<f32>;

// x at cell (i, j), in mode 1 as prolong_level0.wgsl leaves it (the same arithmetic).
fn xv(i: u32, j: u32) -> f32 {
    let n = params.n;
    let idx = j * n + i;
    let v = x[idx];
    if params.mode == 0u || diag[idx] == 0.0 {
        return v;
    }
    let nc = n / 2u;
    let jc = j / 2u;
    let ic = i / 2u;
    let jn = p_side(j, nc);
    let inb = p_side(i, nc);
    let e = 0.5625 * u1[jc * nc + ic] + 0.1875 * (u1[jc * nc + inb] + u1[jn * nc + ic]) + 0.0625 * u1[jn * nc + inb];
    return v + e;
}

@compute @workgroup_size(8, 8)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let n = params.n;
    let j = gid.y;
    if gid.x >= n / 2u || j >= n {
        return;
    }
    let i = 2u * gid.x + ((params.colour + j) & 1u);
    let idx = j * n + i;
    let d = diag[idx];
    if d == 0.0 {
        return;
    }
    let ax = params.ax;
    let ay = params.ay;
    var s = 0.0;
    if i > 0u && i + 1u < n && j > 0u && j + 1u < n {
        s = ax * (xv(i - 1u, j) + xv(i + 1u, j)) + ay * (xv(i, j - 1u) + xv(i, j + 1u));
    } else {
        if i > 0u {
            s += ax * xv(i - 1u, j);
        }
        if i + 1u < n {
            s += ax * xv(i + 1u, j);
        }
        if j > 0u {
            s += ay * xv(i, j - 1u);
        }
        if j + 1u < n {
            s += ay * xv(i, j + 1u);
        }
    }
    x[idx] = (rhs[idx] + s) / d;
}
