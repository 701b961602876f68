// Pass: relax_tiles (ALGORITHM.md "Local relaxation on the GPU"): up to 5 red-black Gauss-Seidel
// sweeps of the local relaxation of the level-0 solution h in ONE dispatch, in the windows
// `relax_mask` left in z, unless they cover more than a quarter of the level (then the cycles do it
// better: no cell is touched), as the CPU's `relax_windows` (`cpu/local.rs`): x_i = (f_i + sum_j
// a_ij x_j) / diag_i on the free cells of the windows (hard cells, diag == 0, are never touched),
// colour (i + j) & 1, colour 0 first in every sweep.
// Each workgroup owns a 16 x 16 tile of the tiles over the windows' box grown by one cell (origin
// in scalars word 13, `relax_mask` mode 2 writes the indirect workgroups). It copies the tile and a
// ring of 2 x sweeps cells into workgroup memory and runs colour phase m on the tile grown by
// phases - 1 - m cells, with a barrier between phases, so a cell sees its neighbours as the colour
// passes would: the same values, bit for bit. Only the tile is written, into the other buffer than
// the one read (neighbouring tiles read the ring): mode 0 reads h and writes `scratch` (the solver's
// r), mode 1 reads `scratch` and writes h, so the relaxation is two passes
// (`plan::local_relaxation`); r and z are scratch until FCG's start rewrites them. Cells of the grown box that are not relaxed are copied unchanged.
// Windows over more than a quarter of the level get no workgroups (`relax_mask` mode 2).
// FCG's stop-test relaxation (`plan::spike_relaxation`, tile origin in word SPIKE_WORDS + 13)
// binds FCG's r as `f` and p as `scratch` for mode 2: the same sweeps of the correction d
// (A d = r) from d = 0, without reading h, d into scratch (spike_update.wgsl applies it).
// Reads:  f, diag (level 0), mask (the window mask, the solver's z), scalars word 13 (or
//         SPIKE_WORDS + 13); h (mode 0; `#import h`: a buffer, or mip 0 of the height texture)
//         or scratch (mode 1).
// Writes: scratch (modes 0, 2) or h (mode 1) on every cell of the tile.
// Params: n = level-0 side, mode, colour = sweeps of this pass (0 ..= 5: 0 copies), ax, ay.
// Workgroup: 16 x 16 threads, one per tile cell.
#import params
#import scalars
#import h

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(2) var<storage, read> f: array<f32>;
@group(0) @binding(3) var<storage, read> diag: array<f32>;
@group(0) @binding(4) var<storage, read> mask: array<f32>;
// The scalar block (`shared/scalars.wgsl`) as words: word 13 (or SPIKE_WORDS + 13) is the first
// tile's column and row (`tx0 | ty0 << 16`).
@group(0) @binding(5) var<storage, read> words: array<u32, 32>;
@group(0) @binding(6) var<storage, read_write> scratch: array<f32>;

const TILE: u32 = 16u;
// Two phases per sweep, at most 5 sweeps.
const MAX_PHASES: u32 = 10u;
// Side of the workgroup copy: the tile and a ring of MAX_PHASES cells.
const S: u32 = 36u;
const WG: u32 = 256u;

var<workgroup> sh: array<f32, 1296>;

// The CPU's update of cell (i, j) (`relax_windows`, f32, the same order of terms), with h read
// from and written to the copy at (lx, ly).
fn relax(i: u32, j: u32, lx: u32, ly: u32) {
    let n = params.n;
    let idx = j * n + i;
    let d = diag[idx];
    if mask[idx] == 0.0 || d == 0.0 {
        return;
    }
    let ax = params.ax;
    let ay = params.ay;
    let b = ly * S + lx;
    var s = 0.0;
    if i > 0u {
        s += ax * sh[b - 1u];
    }
    if i + 1u < n {
        s += ax * sh[b + 1u];
    }
    if j > 0u {
        s += ay * sh[b - S];
    }
    if j + 1u < n {
        s += ay * sh[b + S];
    }
    sh[b] = (f[idx] + s) / d;
}

@compute @workgroup_size(16, 16)
fn main(@builtin(workgroup_id) wid: vec3<u32>, @builtin(local_invocation_index) t: u32) {
    let n = params.n;
    let from_scratch = params.mode == 1u;
    let from_zero = params.mode == 2u;
    let phases = min(2u * params.colour, MAX_PHASES);
    let origin = words[select(0u, SPIKE_WORDS, params.mode >= 2u) + 13u];
    let tx = (origin & 0xffffu) + wid.x;
    let ty = (origin >> 16u) + wid.y;
    // Level cell (i, j) is copy cell (i - x0, j - y0).
    let x0 = i32(tx * TILE) - i32(MAX_PHASES);
    let y0 = i32(ty * TILE) - i32(MAX_PHASES);
    let lo = MAX_PHASES - phases;
    let hi = MAX_PHASES + TILE + phases;
    for (var c = t; c < S * S; c += WG) {
        let lx = c % S;
        let ly = c / S;
        let x = x0 + i32(lx);
        let y = y0 + i32(ly);
        var v = 0.0;
        if lx >= lo && ly >= lo && lx < hi && ly < hi && x >= 0 && y >= 0 && x < i32(n)
            && y < i32(n) {
            if from_scratch {
                v = scratch[u32(y) * n + u32(x)];
            } else if !from_zero {
                v = h_get(u32(x), u32(y));
            }
        }
        sh[c] = v;
    }
    workgroupBarrier();
    for (var m = 0u; m < phases; m++) {
        let colour = m & 1u;
        // This phase's cells: the tile grown by `grow`.
        let grow = phases - 1u - m;
        let a = MAX_PHASES - grow;
        let e = MAX_PHASES + TILE + grow;
        for (var c = t; c < S * S; c += WG) {
            let lx = c % S;
            let ly = c / S;
            let x = x0 + i32(lx);
            let y = y0 + i32(ly);
            if lx < a || ly < a || lx >= e || ly >= e || x < 0 || y < 0 || x >= i32(n)
                || y >= i32(n) {
                continue;
            }
            if ((u32(x) + u32(y)) & 1u) == colour {
                relax(u32(x), u32(y), lx, ly);
            }
        }
        workgroupBarrier();
    }
    let i = tx * TILE + t % TILE;
    let j = ty * TILE + t / TILE;
    if i < n && j < n {
        let v = sh[(MAX_PHASES + t / TILE) * S + MAX_PHASES + t % TILE];
        if from_scratch {
            h_put(i, j, v);
        } else {
            scratch[j * n + i] = v;
        }
    }
}
