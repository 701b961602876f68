// Pass: relax_mask (ALGORITHM.md "Local relaxation on the GPU"): the windows of the GPU's local
// relaxation, the level-0 cells within Chebyshev radius `params.radius` of a seed, where a seed is a
// cell whose residual |r| exceeds `scalars.relax_limit` (the seed threshold times `(2 ax + 2 ay)
// relief`; NaN never does), as the CPU's `Windows` (`cpu/local.rs`). Two separable passes,
// one thread per level-0 cell, then one thread:
// mode 0 (rows):    z = 1 if a cell of the row within the radius is a seed, else 0; thread (0, 0)
//                   empties the windows' box.
// mode 1 (columns): r = 1 if a cell of the column within the radius has z = 1, else 0 (the window
//                   mask; r is recomputed by FCG's start), and the mask's cells are counted into
//                   `scalars.relax_cells` (for the work units and the quarter-of-the-level rule)
//                   and bound into the box (a workgroup's bounds first, then the level's).
// mode 2 (box):     the relaxation's indirect workgroups, 16 x 16 tiles over the box grown by one
//                   cell (none when the box is empty or the windows cover more than a quarter of the level), their first
//                   tile (column, row) packed into scalars word 13 and their workgroups counted
//                   into word 14 (for the bytes they move).
// Reads:  r (mode 0), z (mode 1), scalars.relax_limit, relax_cells (mode 2), box (mode 2).
// Writes: z (mode 0), r (mode 1), scalars.relax_cells (atomic), box, scalars words 13, 14 (mode 2).
// Params: n = level-0 side, mode, radius = window radius.
// Workgroup: 8 x 8 over (n, n) threads (modes 0, 1), one workgroup (mode 2).
#import params

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read_write> r: array<f32>;
@group(0) @binding(2) var<storage, read_write> z: array<f32>;
// The scalar block (`shared/scalars.wgsl`) as words, for the atomic counter: word 8 is
// `relax_limit` (f32 bits), word 9 `relax_cells`, words 13 and 14 the relaxation passes' origin and
// workgroups.
@group(0) @binding(3) var<storage, read_write> words: array<atomic<u32>, 16>;
// The windows' box (min i, max i, min j, max j), then the indirect workgroup counts (x, y, z).
@group(0) @binding(4) var<storage, read_write> box: array<atomic<u32>, 8>;

// A workgroup's bounds of its window cells, merged into `box` once.
var<workgroup> local_box: array<atomic<u32>, 4>;

@compute @workgroup_size(8, 8)
fn main(
    @builtin(global_invocation_id) gid: vec3<u32>,
    @builtin(local_invocation_index) li: u32,
) {
    let n = params.n;
    let i = gid.x;
    let j = gid.y;
    let radius = params.radius;
    if params.mode == 2u {
        if li == 0u {
            arguments(n);
        }
        return;
    }
    if params.mode == 0u {
        // No early return before the barriers of mode 1 (uniform control flow).
        if i < n && j < n {
            rows(n, i, j, radius);
        }
        return;
    }
    // Mode 1: every thread reaches the barriers (no early return).
    if li == 0u {
        atomicStore(&local_box[0], 0xffffffffu);
        atomicStore(&local_box[1], 0u);
        atomicStore(&local_box[2], 0xffffffffu);
        atomicStore(&local_box[3], 0u);
    }
    workgroupBarrier();
    if i < n && j < n {
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
            atomicMin(&local_box[0], i);
            atomicMax(&local_box[1], i);
            atomicMin(&local_box[2], j);
            atomicMax(&local_box[3], j);
        }
    }
    workgroupBarrier();
    if li == 0u {
        let lo_i = atomicLoad(&local_box[0]);
        if lo_i != 0xffffffffu {
            atomicMin(&box[0], lo_i);
            atomicMax(&box[1], atomicLoad(&local_box[1]));
            atomicMin(&box[2], atomicLoad(&local_box[2]));
            atomicMax(&box[3], atomicLoad(&local_box[3]));
        }
    }
}

// Mode 0 at cell (i, j).
fn rows(n: u32, i: u32, j: u32, radius: u32) {
    if i == 0u && j == 0u {
        atomicStore(&box[0], 0xffffffffu);
        atomicStore(&box[1], 0u);
        atomicStore(&box[2], 0xffffffffu);
        atomicStore(&box[3], 0u);
    }
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
}

// Mode 2: `relax_tiles`'s workgroups, one per 16 x 16 tile that holds a cell of the box or of the
// ring of cells around it (the relaxed cells' neighbours, which its passes copy).
fn arguments(n: u32) {
    let lo_i = atomicLoad(&box[0]);
    let hi_i = atomicLoad(&box[1]);
    let lo_j = atomicLoad(&box[2]);
    let hi_j = atomicLoad(&box[3]);
    // More than a quarter of the level (as the CPU: cells * 4 > n * n).
    let quarter = atomicLoad(&words[9]) > (n / 2u) * (n / 2u);
    var gx = 0u;
    var gy = 0u;
    var origin = 0u;
    if lo_i <= hi_i && !quarter {
        // The 16 x 16 tiles over the box grown by one cell (the relaxed cells' neighbours).
        let tx0 = select(0u, lo_i - 1u, lo_i > 0u) / 16u;
        let ty0 = select(0u, lo_j - 1u, lo_j > 0u) / 16u;
        let tx1 = min(hi_i + 1u, n - 1u) / 16u;
        let ty1 = min(hi_j + 1u, n - 1u) / 16u;
        gx = tx1 - tx0 + 1u;
        gy = ty1 - ty0 + 1u;
        origin = tx0 | (ty0 << 16u);
    }
    atomicStore(&box[4], gx);
    atomicStore(&box[5], max(gy, 1u));
    atomicStore(&box[6], 1u);
    atomicStore(&words[13], origin);
    atomicStore(&words[14], gx * gy);
}
