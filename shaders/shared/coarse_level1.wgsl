// Shared include `#import coarse` for a pass on level 1 (the variant of `coarse_records.wgsl`, with
// the same functions): level 1's Galerkin stencils A_1 = R A_0 P are not stored but computed where
// they are read, from the level-0 diagonal bound at binding 1 (0 marks hard cells, whose rows and
// columns are left out; the off-diagonals are the constant edge weights ax, ay, absent across the
// border). A level-1 cell's stencil depends on the diagonals of its 4 children and of their
// in-domain 4-neighbours: 12 values.
// The sums are those of the CPU's `cell_from_level0` (cpu/galerkin.rs) in f32, term for term:
// that function scatters, per child (south row first, west first) with diag d != 0, d * P(child)
// and -a * P(neighbour) for its west, east, south and north neighbours that are in the domain and
// not hard; one scatter adds coeff * wx * wy to entry (oy, ox) for the prolongation weights wx, wy
// of the fine cell's column and row, at most one term per entry. Here every scatter is an outer
// product of two weight vectors over the offsets -1, 0, +1 (`l1_weights`), added to all 9 entries
// in the same order, absent terms as exact zeros (which leave an f32 sum unchanged): the same
// roundings, so the coefficients equal the CPU's bit for bit when the compiler does not fuse
// multiply-adds. Branch-free, constant indices only (no dynamically indexed local array).
// A cell is inactive when its centre coefficient is <= params.threshold (ALGORITHM.md).
// The importing pass must import `params`; params.n = side of level 1, ax, ay, threshold.

@group(0) @binding(1) var<storage, read> diag0: array<f32>;

// Rows oy = 0 (south), 1, 2 of a stencil, entries ox = 0, 1, 2 (west to east).
struct L1Rows {
    s: vec3<f32>,
    m: vec3<f32>,
    n: vec3<f32>,
}

// rows += (c * wx) * wy, or only the centre entry with `centre_only` (the same products).
fn l1_add(rows: ptr<function, L1Rows>, centre_only: bool, c: f32, wx: vec3<f32>, wy: vec3<f32>) {
    let t = c * wx;
    if centre_only {
        (*rows).m.y += t.y * wy.y;
        return;
    }
    (*rows).s += t * wy.x;
    (*rows).m += t * wy.y;
    (*rows).n += t * wy.z;
}

// Prolongation weights (`p_weights`) of the level-0 coordinates 2I - 1, 2I, 2I + 1, 2I + 2 around
// coarse index I of a level of side nc, over the coarse offsets -1, 0, +1 (clamped at the border:
// the parent's weight is then 1).
struct L1Weights {
    before: vec3<f32>,
    low: vec3<f32>,
    high: vec3<f32>,
    after: vec3<f32>,
}

fn l1_weights(c: u32, nc: u32) -> L1Weights {
    return L1Weights(
        vec3<f32>(0.75, 0.25, 0.0),
        select(vec3<f32>(0.0, 1.0, 0.0), vec3<f32>(0.25, 0.75, 0.0), c > 0u),
        select(vec3<f32>(0.0, 1.0, 0.0), vec3<f32>(0.0, 0.75, 0.25), c + 1u < nc),
        vec3<f32>(0.0, 0.25, 0.75),
    );
}

// The diagonal of level-0 cell (x, y) of side nf, 0 outside the level (like a hard cell: no term).
fn l1_diag(x: i32, y: i32, nf: i32) -> f32 {
    if x < 0 || y < 0 || x >= nf || y >= nf {
        return 0.0;
    }
    return diag0[u32(y) * u32(nf) + u32(x)];
}

// One child's terms: its diagonal d (at weights wx, wy) and its west, east, south, north
// neighbours' -a (diagonals dw, de, ds, dn at the shifted weights), none when the child is hard.
fn l1_child(rows: ptr<function, L1Rows>, centre_only: bool, d: f32, dw: f32, de: f32, ds: f32,
    dn: f32, wx: vec3<f32>, wxw: vec3<f32>, wxe: vec3<f32>, wy: vec3<f32>, wys: vec3<f32>,
    wyn: vec3<f32>) {
    let free = d != 0.0;
    let ax = params.ax;
    let ay = params.ay;
    l1_add(rows, centre_only, d, wx, wy);
    l1_add(rows, centre_only, select(0.0, -ax, free && dw != 0.0), wxw, wy);
    l1_add(rows, centre_only, select(0.0, -ax, free && de != 0.0), wxe, wy);
    l1_add(rows, centre_only, select(0.0, -ay, free && ds != 0.0), wx, wys);
    l1_add(rows, centre_only, select(0.0, -ay, free && dn != 0.0), wx, wyn);
}

// The coefficients of level-1 cell `idx` (only the centre with `centre_only`), before the inactive
// test.
fn l1_stencil(idx: u32, centre_only: bool) -> L1Rows {
    let nc = params.n;
    let nf = i32(2u * nc);
    let ic = idx % nc;
    let jc = idx / nc;
    let wx = l1_weights(ic, nc);
    let wy = l1_weights(jc, nc);
    // Level-0 columns x0 - 1 .. x0 + 2 and rows y0 - 1 .. y0 + 2 (the children at x0, x0 + 1).
    let x0 = i32(2u * ic);
    let y0 = i32(2u * jc);
    let d00 = l1_diag(x0, y0, nf);
    let d10 = l1_diag(x0 + 1, y0, nf);
    let d01 = l1_diag(x0, y0 + 1, nf);
    let d11 = l1_diag(x0 + 1, y0 + 1, nf);
    var rows = L1Rows(vec3<f32>(0.0), vec3<f32>(0.0), vec3<f32>(0.0));
    // Children (0, 0), (1, 0), (0, 1), (1, 1), as the CPU visits them.
    l1_child(&rows, centre_only, d00, l1_diag(x0 - 1, y0, nf), d10, l1_diag(x0, y0 - 1, nf), d01,
        wx.low, wx.before, wx.high, wy.low, wy.before, wy.high);
    l1_child(&rows, centre_only, d10, d00, l1_diag(x0 + 2, y0, nf), l1_diag(x0 + 1, y0 - 1, nf),
        d11, wx.high, wx.low, wx.after, wy.low, wy.before, wy.high);
    l1_child(&rows, centre_only, d01, l1_diag(x0 - 1, y0 + 1, nf), d11, d00,
        l1_diag(x0, y0 + 2, nf), wx.low, wx.before, wx.high, wy.high, wy.low, wy.after);
    l1_child(&rows, centre_only, d11, d01, l1_diag(x0 + 2, y0 + 1, nf), d10,
        l1_diag(x0 + 1, y0 + 2, nf), wx.high, wx.low, wx.after, wy.high, wy.low, wy.after);
    return rows;
}

// Whether level-1 cell `idx` is active (computes only its centre coefficient).
fn st_active(idx: u32) -> bool {
    return l1_stencil(idx, true).m.y > params.threshold;
}

// Whether level-1 cell `idx` is active and, if so, its 9 coefficients c[oy * 3 + ox] in `row`
// (untouched otherwise).
fn st_get(idx: u32, row: ptr<function, array<f32, 9>>) -> bool {
    let r = l1_stencil(idx, false);
    if !(r.m.y > params.threshold) {
        return false;
    }
    *row = array<f32, 9>(r.s.x, r.s.y, r.s.z, r.m.x, r.m.y, r.m.z, r.n.x, r.n.y, r.n.z);
    return true;
}
