// Pass: spike_update: the update of FCG's stop-test relaxation (`plan::spike_relaxation`), after
// relax_tiles' mode 2 left the correction d (A d = r on the window cells, from d = 0) in p:
// h += d on the window cells, r -= A d (`A` as shared/apply_p.wgsl) on every cell of the tiles
// over the windows' box grown by one (A d reaches one cell past the windows). d is read only on
// window cells (0 elsewhere: p holds FCG's old direction there). Hard cells (diag 0) are left.
// Reads:  p (d), mask (the window mask, the solver's z), diag (level 0), scalars word
//         SPIKE_WORDS + 13 (the tiles' origin); h (`#import h`: a buffer, or mip 0 of the height
//         texture).
// Writes: h on the window cells, r on every cell of the tile.
// Params: n = level-0 side, ax, ay.
// Workgroup: 16 x 16 threads, one per cell of a 16 x 16 tile; dispatched over relax_mask mode 3's
// indirect workgroups.
#import params
#import scalars
#import h
#import apply_p

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(2) var<storage, read_write> r: array<f32>;
// Read only, but bound read-write: a field's `p` may share a buffer with its `h` (resources'
// `GUEST_LEVEL0`), and one buffer cannot be bound both ways in one dispatch.
@group(0) @binding(3) var<storage, read_write> p: array<f32>;
@group(0) @binding(4) var<storage, read> mask: array<f32>;
@group(0) @binding(5) var<storage, read> diag: array<f32>;
@group(0) @binding(6) var<storage, read> words: array<u32, 32>;

const TILE: u32 = 16u;

// The correction at cell (i, j): p there on window cells, else 0 (`apply_p`'s vector).
fn p_get(i: u32, j: u32) -> f32 {
    let idx = j * params.n + i;
    return select(0.0, p[idx], mask[idx] != 0.0);
}

@compute @workgroup_size(16, 16)
fn main(@builtin(workgroup_id) wid: vec3<u32>, @builtin(local_invocation_index) t: u32) {
    let n = params.n;
    let origin = words[SPIKE_WORDS + 13u];
    let i = ((origin & 0xffffu) + wid.x) * TILE + t % TILE;
    let j = ((origin >> 16u) + wid.y) * TILE + t / TILE;
    if i >= n || j >= n {
        return;
    }
    let idx = j * n + i;
    let d = diag[idx];
    if d == 0.0 {
        return;
    }
    if mask[idx] != 0.0 {
        h_put(i, j, h_get(i, j) + p_get(i, j));
    }
    r[idx] = r[idx] - apply_p(i, j, d);
}
