// Pass: smooth_level0_tiles (ALGORITHM.md "Coarse sweeps in tiles"): the preconditioner's first
// red-black sweep on level 0 from x = 0 in ONE dispatch, with the cell arithmetic of
// smooth_level0.wgsl (keep `update` in sync), so the values are those of its two colour passes.
// Each workgroup owns a 16 x 16 tile: colour 0 on the tile grown by one cell, a barrier, colour 1
// on the tile, in workgroup memory; the input x = 0 is read from nowhere, so no workgroup reads what
// another writes. Every cell of the tile is written (hard cells and untouched ones stay 0).
// Reads:  rhs, diag (level 0).
// Writes: x (every cell).
// Params: n = level-0 side, ax, ay.
// Workgroup: 16 x 16 threads, one per tile cell; dispatch ceil(n / 16) x ceil(n / 16) workgroups.
#import params

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read_write> x: array<f32>;
@group(0) @binding(2) var<storage, read> rhs: array<f32>;
@group(0) @binding(3) var<storage, read> diag: array<f32>;

const TILE: u32 = 16u;
// Side of the workgroup copy: the tile and a ring of 2 cells (the grown tile's neighbours).
const S: u32 = 20u;
const RING: u32 = 2u;
const WG: u32 = 256u;

var<workgroup> sx: array<f32, 400>;

// smooth_level0.wgsl's update of cell (i, j), with x read from and written to the copy at (lx, ly).
fn update(i: u32, j: u32, lx: u32, ly: u32) {
    let n = params.n;
    let idx = j * n + i;
    let d = diag[idx];
    if d == 0.0 {
        return;
    }
    let ax = params.ax;
    let ay = params.ay;
    let b = ly * S + lx;
    var s = 0.0;
    if i > 0u && i + 1u < n && j > 0u && j + 1u < n {
        s = ax * (sx[b - 1u] + sx[b + 1u]) + ay * (sx[b - S] + sx[b + S]);
    } else {
        if i > 0u {
            s += ax * sx[b - 1u];
        }
        if i + 1u < n {
            s += ax * sx[b + 1u];
        }
        if j > 0u {
            s += ay * sx[b - S];
        }
        if j + 1u < n {
            s += ay * sx[b + S];
        }
    }
    sx[b] = (rhs[idx] + s) / d;
}

@compute @workgroup_size(16, 16)
fn main(@builtin(workgroup_id) wid: vec3<u32>, @builtin(local_invocation_index) t: u32) {
    let n = params.n;
    let x0 = i32(wid.x * TILE) - i32(RING);
    let y0 = i32(wid.y * TILE) - i32(RING);
    for (var c = t; c < S * S; c += WG) {
        sx[c] = 0.0;
    }
    workgroupBarrier();
    for (var colour = 0u; colour < 2u; colour++) {
        // Colour 0 on the tile grown by one cell, colour 1 on the tile.
        let grow = 1u - colour;
        let a = RING - grow;
        let e = RING + TILE + grow;
        for (var c = t; c < S * S; c += WG) {
            let lx = c % S;
            let ly = c / S;
            let xx = x0 + i32(lx);
            let yy = y0 + i32(ly);
            if lx < a || ly < a || lx >= e || ly >= e || xx < 0 || yy < 0 || xx >= i32(n)
                || yy >= i32(n) {
                continue;
            }
            if ((u32(xx) + u32(yy)) & 1u) == colour {
                update(u32(xx), u32(yy), lx, ly);
            }
        }
        workgroupBarrier();
    }
    let i = wid.x * TILE + t % TILE;
    let j = wid.y * TILE + t / TILE;
    if i < n && j < n {
        x[j * n + i] = sx[(RING + t / TILE) * S + RING + t % TILE];
    }
}
