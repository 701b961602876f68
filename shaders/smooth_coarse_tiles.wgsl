// Pass: smooth_coarse_tiles (ALGORITHM.md "Coarse sweeps in tiles"): up to 8 colour phases of
// four-colour Gauss-Seidel on a coarse level (one or two whole sweeps) in ONE dispatch, with the
// cell arithmetic of smooth_coarse.wgsl and its order, so the result equals the colour passes'
// bit for bit: keep `update` in sync with smooth_coarse.wgsl.
// Each workgroup owns a 16 x 16 tile. It loads the tile and a ring of `phases` cells around it into
// workgroup memory and runs phase m (colour (params.colour >> 2m) & 3) on the tile grown by
// phases - 1 - m cells: a cell's new value needs its neighbours' values after the phases before
// its own, which the ring holds (neighbour tiles compute the ring's cells the same way). Only the
// tile is written, so workgroups never read what another writes: the input is `src` (or zero).
// Mode bit 5 (restrict): the ring and every phase's cells grow by one more cell, and the tile's
// residual, restricted to its 8 x 8 cells of the next level, is written to `out` with
// residual_restrict_coarse.wgsl's arithmetic (keep `residual_at` in sync), so no pass re-reads u.
// Reads:  the stencils (this level, `#import coarse`: records, or level 1's computed from the
//         level-0 diagonal), src (the level's u before the sweeps; not read with mode bit 4), f.
// Writes: u on every cell of the tile (inactive cells keep the value read, or 0 from zero); out
//         (the next level's f, n/2 x n/2; restrict).
// Params: n = side of this level, colour = the phases' colours (2 bits each, first phase lowest),
//         mode = phases (1..=8) | 16 when the input is u = 0 | 32 to restrict the residual (ax, ay,
//         threshold: level 1).
// Workgroup: 16 x 16 threads, one per tile cell; dispatch ceil(n / 16) x ceil(n / 16) workgroups.
#import params
#import stencil
#import coarse

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(2) var<storage, read> src: array<f32>;
@group(0) @binding(3) var<storage, read> f: array<f32>;
@group(0) @binding(4) var<storage, read_write> u: array<f32>;
@group(0) @binding(5) var<storage, read_write> out: array<f32>;

const TILE: u32 = 16u;
const MAX_PHASES: u32 = 8u;
// The widest ring: MAX_PHASES cells and one for the residual.
const RING: u32 = 9u;
// Side of the workgroup copy: the tile and its ring.
const S: u32 = 34u;
const WG: u32 = 256u;

var<workgroup> su: array<f32, 1156>;
// Restrict: the tile's residuals.
var<workgroup> sr: array<f32, 256>;

// The stencil's off-diagonal sum at cell (i, j), u from the copy at (lx, ly), in smooth_coarse's
// and residual_restrict_coarse's order (shared by `update` and `residual_at`).
fn off_diagonal(i: u32, j: u32, lx: u32, ly: u32, st: array<f32, 9>) -> f32 {
    let n = params.n;
    var s = 0.0;
    let b = ly * S + lx;
    if i > 0u && j > 0u && i + 1u < n && j + 1u < n {
        s += st[0] * su[b - S - 1u] + st[1] * su[b - S] + st[2] * su[b - S + 1u];
        s += st[3] * su[b - 1u] + st[5] * su[b + 1u];
        s += st[6] * su[b + S - 1u] + st[7] * su[b + S] + st[8] * su[b + S + 1u];
    } else {
        for (var oy = 0u; oy < 3u; oy++) {
            let yy = j + oy;
            if yy < 1u || yy > n {
                continue;
            }
            for (var ox = 0u; ox < 3u; ox++) {
                let xx = i + ox;
                if (ox == 1u && oy == 1u) || xx < 1u || xx > n {
                    continue;
                }
                s += st[oy * 3u + ox] * su[(ly + oy - 1u) * S + (lx + ox - 1u)];
            }
        }
    }
    return s;
}

// smooth_coarse.wgsl's update of cell (i, j), with u read from and written to the copy at
// (lx, ly).
fn update(i: u32, j: u32, lx: u32, ly: u32) {
    let n = params.n;
    let idx = j * n + i;
    var st: array<f32, 9>;
    if !st_get(idx, &st) {
        return;
    }
    su[ly * S + lx] = (f[idx] - off_diagonal(i, j, lx, ly, st)) / st[4];
}

// residual_restrict_coarse.wgsl's `residual_at` of cell (i, j), u from the copy at (lx, ly).
fn residual_at(i: u32, j: u32, lx: u32, ly: u32) -> f32 {
    let n = params.n;
    let idx = j * n + i;
    var st: array<f32, 9>;
    if !st_get(idx, &st) {
        return 0.0;
    }
    return f[idx] - st[4] * su[ly * S + lx] - off_diagonal(i, j, lx, ly, st);
}

@compute @workgroup_size(16, 16)
fn main(@builtin(workgroup_id) wid: vec3<u32>, @builtin(local_invocation_index) t: u32) {
    let n = params.n;
    let phases = min(params.mode & 15u, MAX_PHASES);
    let from_zero = (params.mode & 16u) != 0u;
    let fused = (params.mode & 32u) != 0u;
    let extra = select(0u, 1u, fused);
    // Level cell (i, j) is copy cell (i - x0, j - y0); the copy's first RING - phases - extra rows
    // and columns are not used.
    let x0 = i32(wid.x * TILE) - i32(RING);
    let y0 = i32(wid.y * TILE) - i32(RING);
    let lo = RING - phases - extra;
    let hi = RING + TILE + phases + extra;
    for (var c = t; c < S * S; c += WG) {
        let lx = c % S;
        let ly = c / S;
        let x = x0 + i32(lx);
        let y = y0 + i32(ly);
        var v = 0.0;
        if !from_zero && lx >= lo && ly >= lo && lx < hi && ly < hi && x >= 0 && y >= 0
            && x < i32(n) && y < i32(n) {
            v = src[u32(y) * n + u32(x)];
        }
        su[c] = v;
    }
    workgroupBarrier();
    for (var m = 0u; m < phases; m++) {
        let colour = (params.colour >> (2u * m)) & 3u;
        // This phase's cells: the tile grown by `grow`.
        let grow = phases - 1u - m + extra;
        let a = RING - grow;
        let e = RING + TILE + grow;
        for (var c = t; c < S * S; c += WG) {
            let lx = c % S;
            let ly = c / S;
            let x = x0 + i32(lx);
            let y = y0 + i32(ly);
            if lx < a || ly < a || lx >= e || ly >= e || x < 0 || y < 0 || x >= i32(n)
                || y >= i32(n) {
                continue;
            }
            let i = u32(x);
            let j = u32(y);
            if (i & 1u) == (colour & 1u) && (j & 1u) == (colour >> 1u) {
                update(i, j, lx, ly);
            }
        }
        workgroupBarrier();
    }
    let i = wid.x * TILE + t % TILE;
    let j = wid.y * TILE + t / TILE;
    let lx = RING + t % TILE;
    let ly = RING + t / TILE;
    if i < n && j < n {
        u[j * n + i] = su[ly * S + lx];
    }
    if fused {
        if i < n && j < n {
            sr[t] = residual_at(i, j, lx, ly);
        }
        workgroupBarrier();
        // One thread per next-level cell of the tile: the 4 children in
        // residual_restrict_coarse's order.
        let half = TILE / 2u;
        let ic = wid.x * half + t % half;
        let jc = wid.y * half + t / half;
        let nc = n / 2u;
        if t < half * half && ic < nc && jc < nc {
            let b = (t / half) * 2u * TILE + (t % half) * 2u;
            var s = 0.0;
            s += sr[b];
            s += sr[b + 1u];
            s += sr[b + TILE];
            s += sr[b + TILE + 1u];
            out[jc * nc + ic] = s;
        }
    }
}
