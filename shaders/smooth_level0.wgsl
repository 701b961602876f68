// Pass: smooth_level0 (ALGORITHM.md "Smoothers"): one red-black Gauss-Seidel colour on level 0.
// Keep the cell update in sync with `update` in smooth_level0_tiles.wgsl (the first sweep from 0).
// Thread (t, j) updates cell i = 2t + ((j + colour) & 1) of row j: x_i = (rhs_i + sum_j a_ij x_j) / diag_i.
// Reads:  rhs, diag (level 0); x (neighbours, of the other colour).
// Writes: x on the free cells of this colour (hard cells, diag == 0, are never touched).
// Params: n = level-0 side, colour in {0, 1}, ax, ay.
// Workgroup: 8 x 8 over (n/2, n) threads.
#import params

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read_write> x: array<f32>;
@group(0) @binding(2) var<storage, read> rhs: array<f32>;
@group(0) @binding(3) var<storage, read> diag: array<f32>;

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
        s = ax * (x[idx - 1u] + x[idx + 1u]) + ay * (x[idx - n] + x[idx + n]);
    } else {
        if i > 0u {
            s += ax * x[idx - 1u];
        }
        if i + 1u < n {
            s += ax * x[idx + 1u];
        }
        if j > 0u {
            s += ay * x[idx - n];
        }
        if j + 1u < n {
            s += ay * x[idx + n];
        }
    }
    x[idx] = (rhs[idx] + s) / d;
}
