// Pass: edge_differences: the height problem's edge differences d_e, d_n on level 0 from the diffused
// gradient field (gx, gy) on level 1, exactly as `fields::edge_differences` (ALGORITHM.md, "Three
// fields"): each level-1 value is interpolated to a level-0 cell with the bilinear prolongation
// weights (0.75 / 0.25, clamped at the borders); an edge with band weight beta = max of its two cells
// gets beta * cell size * g, where g is the interpolated gradient of the free cell when exactly one
// end is hard, else the mean of both ends.
// Reads:  gx, gy (level 1, (n/2)^2), band (level-0 band weight), ew (level-0 elevation weight).
// Writes: d_east, d_north (level 0; 0 on the last column / row and outside the bands).
// Params: n = level-0 side; ax = cell width dx (m); ay = cell height dy (m).
// Workgroup: 8 x 8, one thread per level-0 cell.
#import params

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> gx: array<f32>;
@group(0) @binding(2) var<storage, read> gy: array<f32>;
@group(0) @binding(3) var<storage, read> band: array<f32>;
@group(0) @binding(4) var<storage, read> ew: array<f32>;
@group(0) @binding(5) var<storage, read_write> d_east: array<f32>;
@group(0) @binding(6) var<storage, read_write> d_north: array<f32>;

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

fn sample_gx(i: u32, j: u32, nc: u32) -> f32 {
    let wx = p_weights(i, nc);
    let wy = p_weights(j, nc);
    var s = 0.0;
    s += wy.w0 * wx.w0 * gx[wy.c0 * nc + wx.c0];
    s += wy.w0 * wx.w1 * gx[wy.c0 * nc + wx.c1];
    s += wy.w1 * wx.w0 * gx[wy.c1 * nc + wx.c0];
    s += wy.w1 * wx.w1 * gx[wy.c1 * nc + wx.c1];
    return s;
}

fn sample_gy(i: u32, j: u32, nc: u32) -> f32 {
    let wx = p_weights(i, nc);
    let wy = p_weights(j, nc);
    var s = 0.0;
    s += wy.w0 * wx.w0 * gy[wy.c0 * nc + wx.c0];
    s += wy.w0 * wx.w1 * gy[wy.c0 * nc + wx.c1];
    s += wy.w1 * wx.w0 * gy[wy.c1 * nc + wx.c0];
    s += wy.w1 * wx.w1 * gy[wy.c1 * nc + wx.c1];
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

@compute @workgroup_size(8, 8)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let n = params.n;
    let i = gid.x;
    let j = gid.y;
    if i >= n || j >= n {
        return;
    }
    let nc = n / 2u;
    let idx = j * n + i;
    var de = 0.0;
    var dn = 0.0;
    if i + 1u < n {
        let beta = max(band[idx], band[idx + 1u]);
        if beta > 0.0 {
            let g = pick(sample_gx(i, j, nc), sample_gx(i + 1u, j, nc), ew[idx] >= 1.0, ew[idx + 1u] >= 1.0);
            de = beta * params.ax * g;
        }
    }
    if j + 1u < n {
        let beta = max(band[idx], band[idx + n]);
        if beta > 0.0 {
            let g = pick(sample_gy(i, j, nc), sample_gy(i, j + 1u, nc), ew[idx] >= 1.0, ew[idx + n] >= 1.0);
            dn = beta * params.ay * g;
        }
    }
    d_east[idx] = de;
    d_north[idx] = dn;
}
