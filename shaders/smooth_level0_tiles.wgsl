// Pass: smooth_level0_tiles (ALGORITHM.md "Coarse sweeps in tiles"): the preconditioner's first
// red-black sweep on level 0 from x = 0 in ONE dispatch, with the cell arithmetic of
// smooth_level0.wgsl (keep `update` in sync), so the values are those of its two colour passes.
// Each workgroup owns a 16 x 16 tile: colour 0 on the tile grown by 1 + mode cells, a barrier,
// colour 1 on the tile grown by mode cells, in workgroup memory; the input x = 0 is read from
// nowhere, so no workgroup reads what another writes. Every cell of the tile is written (hard
// cells and untouched ones stay 0).
// mode 1: then also residual_restrict_level0.wgsl's `out = R (rhs - A x)` on the tile's 8 x 8
//         level-1 cells, from the copy (its arithmetic, term for term), so no pass re-reads x.
// Reads:  rhs, diag (level 0).
// Writes: x (every cell); out (level 1, n/2 x n/2; mode 1).
// Params: n = level-0 side, mode, ax, ay.
// Workgroup: 16 x 16 threads, one per tile cell; dispatch ceil(n / 16) x ceil(n / 16) workgroups.
#import params

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read_write> x: array<f32>;
@group(0) @binding(2) var<storage, read> rhs: array<f32>;
@group(0) @binding(3) var<storage, read> diag: array<f32>;
@group(0) @binding(4) var<storage, read_write> out: array<f32>;

const TILE: u32 = 16u;
// Side of the workgroup copy: the tile and a ring of 3 cells (the grown tile's neighbours).
const S: u32 = 22u;
const RING: u32 = 3u;
const WG: u32 = 256u;

var<workgroup> sx: array<f32, 484>;
// Mode 1: the tile's residuals.
var<workgroup> sr: array<f32, 256>;

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

// residual_restrict_level0.wgsl's `residual_at` of cell (i, j), x from the copy at (lx, ly).
fn residual_at(i: u32, j: u32, lx: u32, ly: u32) -> f32 {
    let n = params.n;
    let idx = j * n + i;
    let d = diag[idx];
    if d == 0.0 {
        return 0.0;
    }
    let b = ly * S + lx;
    var s = 0.0;
    if i > 0u {
        s += params.ax * sx[b - 1u];
    }
    if i + 1u < n {
        s += params.ax * sx[b + 1u];
    }
    if j > 0u {
        s += params.ay * sx[b - S];
    }
    if j + 1u < n {
        s += params.ay * sx[b + S];
    }
    return rhs[idx] - d * sx[b] + s;
}

@compute @workgroup_size(16, 16)
fn main(@builtin(workgroup_id) wid: vec3<u32>, @builtin(local_invocation_index) t: u32) {
    let n = params.n;
    let fused = params.mode == 1u;
    let x0 = i32(wid.x * TILE) - i32(RING);
    let y0 = i32(wid.y * TILE) - i32(RING);
    for (var c = t; c < S * S; c += WG) {
        sx[c] = 0.0;
    }
    workgroupBarrier();
    for (var colour = 0u; colour < 2u; colour++) {
        // Colour 0 on the tile grown by 1 + mode cells, colour 1 on the tile grown by mode.
        let grow = 1u - colour + params.mode;
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
    let lx = RING + t % TILE;
    let ly = RING + t / TILE;
    if i < n && j < n {
        x[j * n + i] = sx[ly * S + lx];
    }
    if fused {
        if i < n && j < n {
            sr[t] = residual_at(i, j, lx, ly);
        }
        workgroupBarrier();
        // One thread per level-1 cell of the tile: the 4 children in residual_restrict_level0's
        // order.
        let half = TILE / 2u;
        let ic = wid.x * half + t % half;
        let jc = wid.y * half + t / half;
        let nc = n / 2u;
        if t < half * half && ic < nc && jc < nc {
            let b = (t / half) * 2u * TILE + (t % half) * 2u;
            out[jc * nc + ic] = sr[b] + sr[b + 1u] + sr[b + TILE] + sr[b + TILE + 1u];
        }
    }
}
