// Pass: assemble_level0 (ALGORITHM.md "Level 0"). One thread per level-0 cell.
// Reads:  weight, value (level 0, n x n, row 0 = south) and, by mode, the edge differences:
//         mode 0: none (d = 0; east, north and band are not read, any buffer fills them);
//         mode 1: uploaded, east = d_east, north = d_north (level 0; band not read);
//         mode 2: computed here from the diffused gradient field, east = gx, north = gy (level 1,
//         (n/2)^2), band = the level-0 band weight, exactly as `fields::edge_differences`
//         (ALGORITHM.md, "Three fields"): each level-1 value is interpolated to a level-0 cell with the
//         bilinear prolongation weights (0.75 / 0.25, clamped at the borders); an edge with band weight
//         beta = max of its two cells gets beta * cell size * g, where g is the interpolated gradient of
//         the free cell when exactly one end is hard (elevation weight >= 1), else the mean of both ends.
// Writes: diag = sum a + sigma on free cells, exactly 0 on hard cells;
//         f = sigma E - sum a dd on free cells, 0 on hard cells;
//         h (`#import h`: a buffer, or mip 0 of the height texture) = E on hard cells; on free cells
//         0 with slot_or_cold = 1 (a cold start), else untouched (the warm start keeps them).
// Params: n = level-0 side, ax, ay; mode (above); dx, dy = cell width and height in metres (mode 2);
//         slot_or_cold = 1: cold.
// Workgroup: 8 x 8.
#import params
#import h

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(2) var<storage, read> weight: array<f32>;
@group(0) @binding(3) var<storage, read> value: array<f32>;
@group(0) @binding(4) var<storage, read> east: array<f32>;
@group(0) @binding(5) var<storage, read> north: array<f32>;
@group(0) @binding(6) var<storage, read> band: array<f32>;
@group(0) @binding(7) var<storage, read_write> diag: array<f32>;
@group(0) @binding(8) var<storage, read_write> f: array<f32>;

// Keep in sync with HARD_WEIGHT / MAX_SOFT_WEIGHT in multigrid/src/problem.rs.
const HARD_WEIGHT: f32 = 1.0;
const MAX_SOFT_WEIGHT: f32 = 0.999;

const MODE_UPLOADED: u32 = 1u;
const MODE_GRADIENT: u32 = 2u;

// Parent and side cell of level-0 coordinate x on a level of side nc, with their weights.
struct PW {
    c0: u32,
    w0: f32,
    c1: u32,
    w1: f32,
}

fn p_weights(x: u32, nc: u32) -> PW {
    let parent = x / 2u;
    var side: u32;
    if (x & 1u) == 1u {
        side = min(parent + 1u, nc - 1u);
    } else {
        side = select(parent - 1u, 0u, parent == 0u);
    }
    if side == parent {
        return PW(parent, 1.0, parent, 0.0);
    }
    return PW(parent, 0.75, side, 0.25);
}

// gx (in `east`) interpolated to level-0 cell (i, j).
fn sample_gx(i: u32, j: u32, nc: u32) -> f32 {
    let wx = p_weights(i, nc);
    let wy = p_weights(j, nc);
    var s = 0.0;
    s += wy.w0 * wx.w0 * east[wy.c0 * nc + wx.c0];
    s += wy.w0 * wx.w1 * east[wy.c0 * nc + wx.c1];
    s += wy.w1 * wx.w0 * east[wy.c1 * nc + wx.c0];
    s += wy.w1 * wx.w1 * east[wy.c1 * nc + wx.c1];
    return s;
}

// gy (in `north`) interpolated to level-0 cell (i, j).
fn sample_gy(i: u32, j: u32, nc: u32) -> f32 {
    let wx = p_weights(i, nc);
    let wy = p_weights(j, nc);
    var s = 0.0;
    s += wy.w0 * wx.w0 * north[wy.c0 * nc + wx.c0];
    s += wy.w0 * wx.w1 * north[wy.c0 * nc + wx.c1];
    s += wy.w1 * wx.w0 * north[wy.c1 * nc + wx.c0];
    s += wy.w1 * wx.w1 * north[wy.c1 * nc + wx.c1];
    return s;
}

// One end hard and the other free: the free end's value; otherwise the mean.
fn pick(a: f32, b: f32, hard_a: bool, hard_b: bool) -> f32 {
    if hard_a && !hard_b {
        return b;
    }
    if hard_b && !hard_a {
        return a;
    }
    return 0.5 * (a + b);
}

// d_e of the edge (i, j)-(i+1, j) (i + 1 < n).
fn d_east(i: u32, j: u32, n: u32) -> f32 {
    let idx = j * n + i;
    if params.mode == MODE_UPLOADED {
        return east[idx];
    }
    let beta = max(band[idx], band[idx + 1u]);
    if beta > 0.0 {
        let nc = n / 2u;
        let g = pick(sample_gx(i, j, nc), sample_gx(i + 1u, j, nc), weight[idx] >= 1.0, weight[idx + 1u] >= 1.0);
        return beta * params.dx * g;
    }
    return 0.0;
}

// d_n of the edge (i, j)-(i, j+1) (j + 1 < n).
fn d_north(i: u32, j: u32, n: u32) -> f32 {
    let idx = j * n + i;
    if params.mode == MODE_UPLOADED {
        return north[idx];
    }
    let beta = max(band[idx], band[idx + n]);
    if beta > 0.0 {
        let nc = n / 2u;
        let g = pick(sample_gy(i, j, nc), sample_gy(i, j + 1u, nc), weight[idx] >= 1.0, weight[idx + n] >= 1.0);
        return beta * params.dy * g;
    }
    return 0.0;
}

@compute @workgroup_size(8, 8)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let n = params.n;
    let i = gid.x;
    let j = gid.y;
    if i >= n || j >= n {
        return;
    }
    let ax = params.ax;
    let ay = params.ay;
    let idx = j * n + i;
    let w = weight[idx];
    let e = value[idx];
    if w >= HARD_WEIGHT {
        diag[idx] = 0.0;
        f[idx] = 0.0;
        h_put(i, j, e);
        return;
    }
    if params.slot_or_cold == 1u {
        h_put(i, j, 0.0);
    }
    var sigma = 0.0;
    if w > 0.0 {
        let ws = min(w, MAX_SOFT_WEIGHT);
        sigma = (2.0 * ax + 2.0 * ay) * ws / (1.0 - ws);
    }
    var deg = 0.0;
    // Sum of a_ij * dd_ij, dd = wanted h_j - h_i.
    var flux = 0.0;
    let edges = params.mode == MODE_UPLOADED || params.mode == MODE_GRADIENT;
    if i + 1u < n {
        deg += ax;
        if edges {
            flux += ax * d_east(i, j, n);
        }
    }
    if i > 0u {
        deg += ax;
        if edges {
            flux -= ax * d_east(i - 1u, j, n);
        }
    }
    if j + 1u < n {
        deg += ay;
        if edges {
            flux += ay * d_north(i, j, n);
        }
    }
    if j > 0u {
        deg += ay;
        if edges {
            flux -= ay * d_north(i, j - 1u, n);
        }
    }
    diag[idx] = deg + sigma;
    f[idx] = sigma * e - flux;
}
