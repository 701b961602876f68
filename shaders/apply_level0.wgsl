// Pass: apply_level0: the level-0 residual, matrix-free. One thread per level-0 cell.
// out = rhs - A x on free cells, 0 on hard cells (r = f - A h). FCG's q = A p is not stored: the
// passes reading it recompute it with the same arithmetic (shared/apply_p.wgsl; keep both in sync).
// Reads:  x, rhs, diag (level 0).
// Writes: out (level 0).
// Params: n = level-0 side, ax, ay.
// Workgroup: 8 x 8.
#import params

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> x: array<f32>;
@group(0) @binding(2) var<storage, read> rhs: array<f32>;
@group(0) @binding(3) var<storage, read> diag: array<f32>;
@group(0) @binding(4) var<storage, read_write> out: array<f32>;

@compute @workgroup_size(8, 8)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let n = params.n;
    let i = gid.x;
    let j = gid.y;
    if i >= n || j >= n {
        return;
    }
    let idx = j * n + i;
    let d = diag[idx];
    if d == 0.0 {
        out[idx] = 0.0;
        return;
    }
    // Neighbour order as `neighbour_sum` in cpu/level0.rs.
    var s = 0.0;
    if i > 0u {
        s += params.ax * x[idx - 1u];
    }
    if i + 1u < n {
        s += params.ax * x[idx + 1u];
    }
    if j > 0u {
        s += params.ay * x[idx - n];
    }
    if j + 1u < n {
        s += params.ay * x[idx + n];
    }
    let ax_i = d * x[idx] - s;
    out[idx] = rhs[idx] - ax_i;
}
