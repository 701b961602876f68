// Pass: relax_level0 (ALGORITHM.md "Local relaxation on the GPU"): one red-black Gauss-Seidel
// colour of the local relaxation on the level-0 solution h, in the windows `relax_mask` left in r,
// unless they cover more than a quarter of the level (then the cycles do it better: no cell is
// touched), as the CPU's `relax_windows` (`cpu/local.rs`): x_i = (f_i + sum_j a_ij x_j) / diag_i on
// the free cells (hard cells, diag == 0, are never touched). Dispatched indirectly over the
// windows' box only (`relax_mask` mode 2): thread (x, y) is pair column t = t0 + x of row
// j = j0 + y, (t0, j0) packed in scalars word 13, and updates cell i = 2t + ((j + colour) & 1).
// Reads:  f, diag (level 0), r (the window mask), scalars.relax_cells and word 13; h (neighbours, of the other
//         colour; `#import h`: a buffer, or mip 0 of the height texture).
// Writes: h on the free cells of this colour in the windows.
// Params: n = level-0 side, colour in {0, 1}, ax, ay.
// Workgroup: 8 x 8 over the box's (pair columns, rows), at most (n/2, n) threads.
#import params
#import h

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(2) var<storage, read> f: array<f32>;
@group(0) @binding(3) var<storage, read> diag: array<f32>;
@group(0) @binding(4) var<storage, read> mask: array<f32>;
// The scalar block (`shared/scalars.wgsl`) as words: word 9 is `relax_cells`, word 13 the box's
// first pair column and row (`t0 | j0 << 16`).
@group(0) @binding(5) var<storage, read> words: array<u32, 16>;

@compute @workgroup_size(8, 8)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let n = params.n;
    let origin = words[13];
    let t = (origin & 0xffffu) + gid.x;
    let j = (origin >> 16u) + gid.y;
    if t >= n / 2u || j >= n {
        return;
    }
    // More than a quarter of the level (compared as the CPU does: cells * 4 > n * n).
    if words[9] > (n / 2u) * (n / 2u) {
        return;
    }
    let i = 2u * t + ((params.colour + j) & 1u);
    let idx = j * n + i;
    let d = diag[idx];
    if mask[idx] == 0.0 || d == 0.0 {
        return;
    }
    let ax = params.ax;
    let ay = params.ay;
    var s = 0.0;
    if i > 0u {
        s += ax * h_get(i - 1u, j);
    }
    if i + 1u < n {
        s += ax * h_get(i + 1u, j);
    }
    if j > 0u {
        s += ay * h_get(i, j - 1u);
    }
    if j + 1u < n {
        s += ay * h_get(i, j + 1u);
    }
    h_put(i, j, (f[idx] + s) / d);
}
