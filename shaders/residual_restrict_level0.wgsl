// Pass: residual_restrict_level0: r = rhs - A x on level 0 (0 on hard cells), restricted to level 1 as the sum
// of the 4 children. One thread per level-1 cell.
// Bound as (x, rhs) = (z, r) in the preconditioner and (h, f) at the FMG start (h = the lift g).
// Reads:  x (`#import h_read`: a buffer, or mip 0 of the height texture for h), rhs, diag (level 0).
// Writes: out (level 1, n/2 x n/2).
// Params: n = level-0 side, ax, ay.
// Workgroup: 8 x 8 over (n/2, n/2) threads.
#import params
#import h_read

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(2) var<storage, read> rhs: array<f32>;
@group(0) @binding(3) var<storage, read> diag: array<f32>;
@group(0) @binding(4) var<storage, read_write> out: array<f32>;

// Residual of cell (i, j), 0 on hard cells. Neighbour order as `neighbour_sum` in cpu/level0.rs.
fn residual_at(i: u32, j: u32) -> f32 {
    let n = params.n;
    let idx = j * n + i;
    let d = diag[idx];
    if d == 0.0 {
        return 0.0;
    }
    var s = 0.0;
    if i > 0u {
        s += params.ax * h_get(i - 1u, j);
    }
    if i + 1u < n {
        s += params.ax * h_get(i + 1u, j);
    }
    if j > 0u {
        s += params.ay * h_get(i, j - 1u);
    }
    if j + 1u < n {
        s += params.ay * h_get(i, j + 1u);
    }
    return rhs[idx] - d * h_get(i, j) + s;
}

@compute @workgroup_size(8, 8)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let nc = params.n / 2u;
    let ic = gid.x;
    let jc = gid.y;
    if ic >= nc || jc >= nc {
        return;
    }
    let r00 = residual_at(2u * ic, 2u * jc);
    let r10 = residual_at(2u * ic + 1u, 2u * jc);
    let r01 = residual_at(2u * ic, 2u * jc + 1u);
    let r11 = residual_at(2u * ic + 1u, 2u * jc + 1u);
    out[jc * nc + ic] = r00 + r10 + r01 + r11;
}
