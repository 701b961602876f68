// Pass: relax_mask (ALGORITHM.md "Local relaxation on the GPU"): the windows of the GPU's local
// relaxation, the level-0 cells within Chebyshev radius `params.radius` of a seed, where a seed is a
// cell whose residual |r| exceeds `scalars.relax_limit` (the seed threshold times `(2 ax + 2 ay)
// relief`; NaN never does), as the CPU's `Windows` (`cpu/local.rs`). Two separable passes,
// one thread per level-0 cell:
// mode 0 (rows):    z = 1 if a cell of the row within the radius is a seed, else 0.
// mode 1 (columns): r = 1 if a cell of the column within the radius has z = 1, else 0 (the window
//                   mask; r is recomputed by FCG's start), and the mask's cells are counted into
//                   `scalars.relax_cells` (for the work units and the quarter-of-the-level rule).
// Reads:  r (mode 0), z (mode 1), scalars.relax_limit.
// Writes: z (mode 0), r (mode 1), scalars.relax_cells (atomic).
// Params: n = level-0 side, mode, radius = window radius.
// Workgroup: 8 x 8 over (n, n) threads.
#import params

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read_write> r: array<f32>;
@group(0) @binding(2) var<storage, read_write> z: array<f32>;
// The scalar block (`shared/scalars.wgsl`) as words, for the atomic counter: word 8 is
// `relax_limit` (f32 bits), word 9 `relax_cells`.
@group(0) @binding(3) var<storage, read_write> words: array<atomic<u32>, 12>;

@compute @workgroup_size(8, 8)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let n = params.n;
    let i = gid.x;
    let j = gid.y;
    if i >= n || j >= n {
        return;
    }
    let radius = params.radius;
    if params.mode == 0u {
        let limit = bitcast<f32>(atomicLoad(&words[8]));
        let a = select(0u, i - radius, i >= radius);
        let b = min(i + radius, n - 1u);
        var hit = 0.0;
        for (var c = a; c <= b; c++) {
            if abs(r[j * n + c]) > limit {
                hit = 1.0;
                break;
            }
        }
        z[j * n + i] = hit;
    } else {
        let a = select(0u, j - radius, j >= radius);
        let b = min(j + radius, n - 1u);
        var hit = 0.0;
        for (var row = a; row <= b; row++) {
            if z[row * n + i] != 0.0 {
                hit = 1.0;
                break;
            }
        }
        r[j * n + i] = hit;
        if hit != 0.0 {
            atomicAdd(&words[9], 1u);
        }
    }
}
