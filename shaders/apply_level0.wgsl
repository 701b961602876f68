// Pass: apply_level0: the level-0 residual, matrix-free. One thread per level-0 cell.
// out = rhs - A h on free cells, 0 on hard cells (r = f - A h). A h is `apply_p` (shared/apply_p.wgsl),
// the very function the passes that need FCG's q = A p use (the GPU keeps no q vector), so the
// operator is written once; its vector `p` is h here.
// Reads:  h (`#import h_read`: a buffer, or mip 0 of the height texture), rhs, diag (level 0).
// Writes: out (level 0).
// Params: n = level-0 side, ax, ay.
// Workgroup: 8 x 8.
#import params
#import h_read
#import apply_p

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(2) var<storage, read> rhs: array<f32>;
@group(0) @binding(3) var<storage, read> diag: array<f32>;
@group(0) @binding(4) var<storage, read_write> out: array<f32>;

fn p_get(i: u32, j: u32) -> f32 {
    return h_get(i, j);
}

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
    out[idx] = rhs[idx] - apply_p(i, j, d);
}
