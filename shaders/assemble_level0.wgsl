// Pass: assemble_level0 (ALGORITHM.md "Level 0"). One thread per level-0 cell.
// Reads:  weight, value, d_east, d_north (level 0, n x n, row 0 = south; d_east / d_north only with
//         mode 1: with mode 0 the problem has no edge differences, d = 0, and any buffer fills them).
// Writes: diag = sum a + sigma on free cells, exactly 0 on hard cells;
//         f = sigma E - sum a dd on free cells, 0 on hard cells;
//         h = E on hard cells (free cells untouched: the warm start keeps them).
// Params: n = level-0 side, ax, ay; mode = 1 with edge differences, 0 without.
// Workgroup: 8 x 8.
#import params

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> weight: array<f32>;
@group(0) @binding(2) var<storage, read> value: array<f32>;
@group(0) @binding(3) var<storage, read> d_east: array<f32>;
@group(0) @binding(4) var<storage, read> d_north: array<f32>;
@group(0) @binding(5) var<storage, read_write> diag: array<f32>;
@group(0) @binding(6) var<storage, read_write> f: array<f32>;
@group(0) @binding(7) var<storage, read_write> h: array<f32>;

// Keep in sync with HARD_WEIGHT / MAX_SOFT_WEIGHT in multigrid/src/problem.rs.
const HARD_WEIGHT: f32 = 1.0;
const MAX_SOFT_WEIGHT: f32 = 0.999;

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
        h[idx] = e;
        return;
    }
    var sigma = 0.0;
    if w > 0.0 {
        let ws = min(w, MAX_SOFT_WEIGHT);
        sigma = (2.0 * ax + 2.0 * ay) * ws / (1.0 - ws);
    }
    var deg = 0.0;
    // Sum of a_ij * dd_ij, dd = wanted h_j - h_i.
    var flux = 0.0;
    let edges = params.mode == 1u;
    if i + 1u < n {
        deg += ax;
        if edges {
            flux += ax * d_east[idx];
        }
    }
    if i > 0u {
        deg += ax;
        if edges {
            flux -= ax * d_east[idx - 1u];
        }
    }
    if j + 1u < n {
        deg += ay;
        if edges {
            flux += ay * d_north[idx];
        }
    }
    if j > 0u {
        deg += ay;
        if edges {
            flux -= ay * d_north[idx - n];
        }
    }
    diag[idx] = deg + sigma;
    f[idx] = sigma * e - flux;
}
