// Pass: coarsest_solve (ALGORITHM.md "Cycles"): exact solve A u = f on the coarsest level (8 x 8 = 64 cells)
// by Gaussian elimination with partial pivoting, in ONE workgroup, the matrix in workgroup memory.
// Row/column c is cell c. Inactive cells get an identity row (and have no coupling to active cells), which
// leaves the elimination of the active block identical to eliminating the active cells alone, and gives
// u = 0 there. Pivot: the LAST row of largest |a| (as `max_by` in cpu/coarse.rs); |pivot| < 1e-30: the
// column is skipped (singular direction, left at 0).
// Reads:  the stencils (`#import coarse`: records, or, when the coarsest level is level 1 (16 x 16
//         solvers), computed from the level-0 diagonal), f (coarsest level).
// Writes: u (coarsest level; also the elimination's right-hand side while it runs).
// Params: n = side of the coarsest level (must be 8; ax, ay, threshold: level 1).
// Workgroup: 64 threads; workgroup memory 64 x 64 f32 = 16384 bytes. Dispatch exactly one workgroup.
#import params
#import stencil
#import coarse

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(2) var<storage, read> f: array<f32>;
@group(0) @binding(3) var<storage, read_write> u: array<f32>;

const M: u32 = 64u;
const SIDE: u32 = 8u;
const TINY: f32 = 1e-30;

var<workgroup> a: array<f32, 4096>;

@compute @workgroup_size(64)
fn main(@builtin(local_invocation_index) t: u32) {
    // Assemble row t.
    for (var k = 0u; k < M; k++) {
        a[t * M + k] = 0.0;
    }
    var row: array<f32, 9>;
    if params.n == SIDE && st_get(t, &row) {
        let i = t % SIDE;
        let j = t / SIDE;
        for (var oy = 0u; oy < 3u; oy++) {
            for (var ox = 0u; ox < 3u; ox++) {
                let x = i + ox;
                let y = j + oy;
                if x < 1u || y < 1u || x > SIDE || y > SIDE {
                    continue;
                }
                let nb = (y - 1u) * SIDE + (x - 1u);
                if st_active(nb) {
                    a[t * M + nb] += row[oy * 3u + ox];
                }
            }
        }
        u[t] = f[t];
    } else {
        a[t * M + t] = 1.0;
        u[t] = 0.0;
    }
    workgroupBarrier();
    storageBarrier();

    for (var col = 0u; col < M; col++) {
        // Every thread finds the same pivot.
        var piv = col;
        var best = abs(a[col * M + col]);
        for (var r = col + 1u; r < M; r++) {
            let v = abs(a[r * M + col]);
            if v >= best {
                best = v;
                piv = r;
            }
        }
        let usable = best >= TINY;
        workgroupBarrier();
        if usable && piv != col {
            // Thread t swaps column t of the two rows; thread 0 swaps the right-hand side.
            let tmp = a[col * M + t];
            a[col * M + t] = a[piv * M + t];
            a[piv * M + t] = tmp;
            if t == 0u {
                let tb = u[col];
                u[col] = u[piv];
                u[piv] = tb;
            }
        }
        workgroupBarrier();
        storageBarrier();
        if usable && t > col {
            let factor = a[t * M + col] / a[col * M + col];
            if factor != 0.0 {
                for (var k = col; k < M; k++) {
                    a[t * M + k] -= factor * a[col * M + k];
                }
                u[t] -= factor * u[col];
            }
        }
        workgroupBarrier();
        storageBarrier();
    }

    // Back substitution by one thread; u[k] holds x[k] once row k is done.
    if t == 0u {
        for (var rr = 0u; rr < M; rr++) {
            let r = M - 1u - rr;
            var s = u[r];
            for (var k = r + 1u; k < M; k++) {
                s -= a[r * M + k] * u[k];
            }
            let d = a[r * M + r];
            u[r] = select(s / d, 0.0, abs(d) < TINY);
        }
    }
}
