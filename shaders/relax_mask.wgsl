// Pass: relax_mask (ALGORITHM.md "Local relaxation on the GPU"): the windows of the GPU's local
// relaxation, the level-0 cells within Chebyshev radius `params.radius` of a seed, where a seed is a
// cell whose residual |r| exceeds `scalars.relax_limit` (the seed threshold times `(2 ax + 2 ay)
// relief`; NaN never does), as the CPU's `Windows` (`cpu/local.rs`). Modes 0 and 1 use the block's
// words 8-14 (the local relaxation after FMG or on a warm start); modes 2 and 3 are the same passes
// for FCG's stop-test relaxation on words SPIKE_WORDS + 8-14, whose box pass (3) allows windows of
// at most (n / 16)^2 cells instead of a quarter of the level, adds the cells and tile workgroups
// of a relaxation that runs to words SPIKE_WORDS + 10 and + 11 and sets SPIKE_WORDS + 15 (FCG's
// restart, read by dot_final):
// mode 0 (mask, and 2):  one 16 x 16 workgroup per tile: the seeds of the tile and a ring of `radius` cells
//                 into workgroup memory (cells past the border are no seeds), dilated along rows,
//                 then along columns; z = 1 on the tile's window cells, else 0 (the window mask; z
//                 is scratch until FCG's start rewrites it). The mask's cells are counted into
//                 `scalars.relax_cells` (for the work units and the quarter-of-the-level rule) and
//                 bound into the box (a workgroup's count and bounds first, then the level's).
// mode 1 (box, and 3):   one thread: the relaxation's indirect workgroups, 16 x 16 tiles over the box grown
//                 by one cell (none when the box is empty or the windows cover more than a quarter
//                 of the level), their first tile (column, row) packed into scalars word 13 and their
//                 workgroups counted into word 14 (for the bytes they move); then the box emptied for
//                 the next relaxation (the buffer starts empty).
// Reads:  r (modes 0, 2), scalars.relax_limit, relax_cells (modes 1, 3), box (modes 1, 3).
// Writes: z (modes 0, 2), scalars.relax_cells (atomic), box, scalars words 13, 14 (modes 1, 3);
//         words SPIKE_WORDS + 10, 11, 15 (mode 3).
// Params: n = level-0 side, mode, radius = window radius (<= MAX_RADIUS).
// Workgroup: 16 x 16, over (n / 16, n / 16) tiles (modes 0, 2), one workgroup (modes 1, 3).
#import params
#import scalars

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> r: array<f32>;
@group(0) @binding(2) var<storage, read_write> z: array<f32>;
// The scalar block (`shared/scalars.wgsl`) as words, for the atomic counter: word base + 8 is
// `relax_limit` (f32 bits), base + 9 `relax_cells`, base + 13 and 14 the relaxation passes' origin
// and workgroups (base 0, or SPIKE_WORDS in modes 2 and 3).
@group(0) @binding(3) var<storage, read_write> words: array<atomic<u32>, 32>;
// The windows' box (min i, max i, min j, max j), then the indirect workgroup counts (x, y, z).
@group(0) @binding(4) var<storage, read_write> box: array<atomic<u32>, 8>;

const TILE: u32 = 16u;
const WG: u32 = 256u;
const MAX_RADIUS: u32 = 8u;
// Side of the seed copy: the tile and its ring.
const MAX_SIDE: u32 = 32u;

// Seeds of the tile and its ring (side TILE + 2 radius, row-major), then their dilation along rows
// over the tile's columns (rows of TILE).
var<workgroup> seeds: array<u32, 1024>;
var<workgroup> rows: array<u32, 512>;
// A workgroup's count and bounds of its window cells, merged into `words` and `box` once.
var<workgroup> local_box: array<atomic<u32>, 5>;

@compute @workgroup_size(16, 16)
fn main(
    @builtin(local_invocation_id) lid: vec3<u32>,
    @builtin(local_invocation_index) li: u32,
    @builtin(workgroup_id) wid: vec3<u32>,
) {
    let base = select(0u, SPIKE_WORDS, params.mode >= 2u);
    if (params.mode & 1u) == 1u {
        if li == 0u {
            arguments(params.n, base, params.mode == 3u);
        }
        return;
    }
    // Mode 0: every thread reaches the barriers (no early return).
    let n = params.n;
    let radius = min(params.radius, MAX_RADIUS);
    let side = TILE + 2u * radius;
    let x0 = i32(wid.x * TILE) - i32(radius);
    let y0 = i32(wid.y * TILE) - i32(radius);
    let limit = bitcast<f32>(atomicLoad(&words[base + 8u]));
    if li == 0u {
        atomicStore(&local_box[0], 0xffffffffu);
        atomicStore(&local_box[1], 0u);
        atomicStore(&local_box[2], 0xffffffffu);
        atomicStore(&local_box[3], 0u);
        atomicStore(&local_box[4], 0u);
    }
    for (var k = li; k < side * side; k += WG) {
        let x = x0 + i32(k % side);
        let y = y0 + i32(k / side);
        var seed = 0u;
        if x >= 0 && y >= 0 && x < i32(n) && y < i32(n) && abs(r[u32(y) * n + u32(x)]) > limit {
            seed = 1u;
        }
        seeds[k] = seed;
    }
    workgroupBarrier();
    // Row dilation: copy row `row`, tile column `c` (copy column c + radius) sees copy columns
    // c .. c + 2 radius.
    for (var k = li; k < side * TILE; k += WG) {
        let row = k / TILE;
        let c = k % TILE;
        var hit = 0u;
        for (var d = 0u; d <= 2u * radius; d++) {
            hit |= seeds[row * side + c + d];
        }
        rows[k] = hit;
    }
    workgroupBarrier();
    // Column dilation at tile cell (lx, ly) (copy row ly + radius): copy rows ly .. ly + 2 radius.
    let i = wid.x * TILE + lid.x;
    let j = wid.y * TILE + lid.y;
    if i < n && j < n {
        var hit = 0u;
        for (var d = 0u; d <= 2u * radius; d++) {
            hit |= rows[(lid.y + d) * TILE + lid.x];
        }
        z[j * n + i] = f32(hit);
        if hit != 0u {
            atomicAdd(&local_box[4], 1u);
            atomicMin(&local_box[0], i);
            atomicMax(&local_box[1], i);
            atomicMin(&local_box[2], j);
            atomicMax(&local_box[3], j);
        }
    }
    workgroupBarrier();
    if li == 0u {
        let cells = atomicLoad(&local_box[4]);
        if cells != 0u {
            atomicAdd(&words[base + 9u], cells);
            atomicMin(&box[0], atomicLoad(&local_box[0]));
            atomicMax(&box[1], atomicLoad(&local_box[1]));
            atomicMin(&box[2], atomicLoad(&local_box[2]));
            atomicMax(&box[3], atomicLoad(&local_box[3]));
        }
    }
}

// Mode 1: `relax_tiles`'s workgroups, one per 16 x 16 tile that holds a cell of the box or of the
// ring of cells around it (the relaxed cells' neighbours, which its passes copy); then the box
// emptied.
fn arguments(n: u32, base: u32, spike: bool) {
    let lo_i = atomicLoad(&box[0]);
    let hi_i = atomicLoad(&box[1]);
    let lo_j = atomicLoad(&box[2]);
    let hi_j = atomicLoad(&box[3]);
    // More than a quarter of the level (as the CPU: cells * 4 > n * n), or for the stop-test
    // relaxation more than (n / 16)^2 cells (cells * SPIKE_SHARE > n * n).
    let side = select(n / 2u, n / 16u, spike);
    let cells = atomicLoad(&words[base + 9u]);
    let quarter = cells > side * side;
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
    atomicStore(&words[base + 13u], origin);
    atomicStore(&words[base + 14u], gx * gy);
    if spike && gx != 0u {
        atomicAdd(&words[SPIKE_WORDS + 10u], cells);
        atomicAdd(&words[SPIKE_WORDS + 11u], gx * gy);
        // The correction goes through `p`: FCG's next direction restarts (dot_final).
        atomicStore(&words[SPIKE_WORDS + 15u], 1u);
    }
    atomicStore(&box[0], 0xffffffffu);
    atomicStore(&box[1], 0u);
    atomicStore(&box[2], 0xffffffffu);
    atomicStore(&box[3], 0u);
}
