// Pass: rasterize: the constraint maps of a sketch, exactly as `constraints/` (in f32): per
// texel and per stroke (in sketch order, so later strokes win exact ties), the closest point of the
// stroke's polyline (its curve's fine polyline, from the CPU) seen from above gives the distance d,
// height z, side and direction; with c the larger cell side:
//   elevation weight clamp((core - d) / c + 1.5, 0, 1) (core = width on plateaus, else 0), value from
//   the closest stroke; band weight clamp((width - d) / c + 0.5, 0, 1) outside d <= c / 2 for ridges and
//   valleys, gradient -+tan(slope) f(u) (ridge falls away, valley rises) along the direction from the
//   curve, f(u) = clamp(1 + u^2 (c2 + u (c3 + u c4)), 0, 1) the falloff at u = min(d / width, 1);
//   roughness weight max(elevation, band, d <= width) and the value of the stroke with the largest one.
// The elevation and band maps are written on level 0. The gradient and roughness maps never are:
// each workgroup keeps its 8 x 8 texels' band weight, gradient and roughness in workgroup memory and
// sums them as `fields::downsample_weighted` does (each block row by row) into the gradient-field
// problem on level 1 (2 x 2 blocks, 16 threads) and the roughness problem on level 2 (4 x 4 blocks,
// 4 threads). It also takes the value ranges the problems' reliefs come from (over the cells with
// weight > 0, as order-preserving u32 keys): per workgroup in workgroup atomics, then one global
// atomic per slot and workgroup.
// Reads:  geom (f32 words, u32 fields bit-cast): [0] stroke count; stroke records of 16 words from 4:
//         chunk_start, chunk_count, kind (0 ridge, 1 valley, 2 plateau), 1 / width_m, tan_left,
//         tan_right, width_m, roughness, reach_m, bbox x0, x1, y0, y1, c2, c3, c4; chunk records of 8
//         words from chunk_start (runs of consecutive segments, in order): bbox x0, x1, y0, y1,
//         seg_start, seg_count, -, -; segment records of 8 words from seg_start: ax, ay, az, bx, by,
//         bz, 1 / |b - a|^2 (0 for a dot), -.
// Writes: ew, ev (elevation weight and value = the height problem's weight / value), band (band
//         weight), all level 0; grad (the gradient problem, side n / 2: its weight plane, then its x
//         value plane), vy (its y values); rough (the roughness problem, side n / 4: weight plane,
//         then value plane); stats[0 .. 8] (min and max keys of elevation, gradient x, gradient y,
//         roughness; the caller resets them).
// Params: n = level-0 side (a multiple of 8); ax = cell width dx (m); ay = cell height dy (m);
//         threshold = c.
// Workgroup: 8 x 8, one thread per texel (4 x 4 level-1 and 2 x 2 level-2 cells per workgroup).
#import params
#import downsample

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> geom: array<f32>;
@group(0) @binding(2) var<storage, read_write> ew: array<f32>;
@group(0) @binding(3) var<storage, read_write> ev: array<f32>;
@group(0) @binding(4) var<storage, read_write> band: array<f32>;
@group(0) @binding(5) var<storage, read_write> grad: array<f32>;
@group(0) @binding(6) var<storage, read_write> vy: array<f32>;
@group(0) @binding(7) var<storage, read_write> rough: array<f32>;
@group(0) @binding(8) var<storage, read_write> stats: array<atomic<u32>>;

const PLATEAU: u32 = 2u;
const RIDGE: u32 = 0u;
const INF: f32 = 3.0e38;

// The workgroup's texels' roughness weight and value, band weight and gradient (texel (x, y) of
// the tile at y * 8 + x).
var<workgroup> tile_w: array<f32, 64>;
var<workgroup> tile_v: array<f32, 64>;
var<workgroup> tile_b: array<f32, 64>;
var<workgroup> tile_gx: array<f32, 64>;
var<workgroup> tile_gy: array<f32, 64>;
// The workgroup's value ranges, as `stats`: min and max key of each of the four problems.
var<workgroup> range_keys: array<atomic<u32>, 8>;

// Order-preserving key of an f32 (a larger value, a larger key).
fn key(v: f32) -> u32 {
    let b = bitcast<u32>(v);
    if (b & 0x80000000u) != 0u {
        return ~b;
    }
    return b | 0x80000000u;
}

// Counts `v` into the range of problem `slot` (0 elevation, 1 gradient x, 2 gradient y, 3 roughness).
fn count_value(slot: u32, v: f32) {
    atomicMin(&range_keys[2u * slot], key(v));
    atomicMax(&range_keys[2u * slot + 1u], key(v));
}

fn word(k: u32) -> u32 {
    return bitcast<u32>(geom[k]);
}

// The maps of one texel.
struct Texel {
    w_e: f32,
    v_e: f32,
    w_b: f32,
    g_x: f32,
    g_y: f32,
    w_r: f32,
    v_r: f32,
}

fn texel(i: u32, j: u32) -> Texel {
    let cell = params.threshold;
    let x = (f32(i) + 0.5) * params.ax;
    let y = (f32(j) + 0.5) * params.ay;
    var w_e = 0.0;
    var v_e = 0.0;
    var d_e = INF;
    var w_b = 0.0;
    var g_x = 0.0;
    var g_y = 0.0;
    var d_b = INF;
    var w_r = 0.0;
    var v_r = 0.0;
    let strokes = word(0u);
    for (var s = 0u; s < strokes; s++) {
        let h = 4u + 16u * s;
        if x < geom[h + 9u] || x > geom[h + 10u] || y < geom[h + 11u] || y > geom[h + 12u] {
            continue;
        }
        let chunk0 = word(h);
        let chunks = word(h + 1u);
        let kind = word(h + 2u);
        let width = geom[h + 6u];
        let reach = geom[h + 8u];
        // Closest point: squared distances decide, the first of equal ones wins. Chunks whose box
        // (segments' boxes, expanded by the reach) misses the texel hold no segment within reach.
        var best_d2 = reach * reach;
        var found = false;
        var bt = 0.0;
        var bvx = 0.0;
        var bvy = 0.0;
        var bseg = 0u;
        for (var c = 0u; c < chunks; c++) {
            let q = chunk0 + 8u * c;
            if x < geom[q] || x > geom[q + 1u] || y < geom[q + 2u] || y > geom[q + 3u] {
                continue;
            }
            let seg0 = word(q + 4u);
            let segs = word(q + 5u);
            for (var k = 0u; k < segs; k++) {
                let g = seg0 + 8u * k;
                let ex = geom[g + 3u] - geom[g];
                let ey = geom[g + 4u] - geom[g + 1u];
                let px = x - geom[g];
                let py = y - geom[g + 1u];
                let t = clamp((px * ex + py * ey) * geom[g + 6u], 0.0, 1.0);
                let vx = px - t * ex;
                let vy = py - t * ey;
                let d2 = vx * vx + vy * vy;
                if d2 < best_d2 || (d2 == best_d2 && !found) {
                    best_d2 = d2;
                    found = true;
                    bt = t;
                    bvx = vx;
                    bvy = vy;
                    bseg = g;
                }
            }
        }
        if !found {
            continue;
        }
        let d = sqrt(best_d2);
        let z = geom[bseg + 2u] + bt * (geom[bseg + 5u] - geom[bseg + 2u]);
        let ex = geom[bseg + 3u] - geom[bseg];
        let ey = geom[bseg + 4u] - geom[bseg + 1u];
        var dir = vec2<f32>(0.0, 0.0);
        if d > 1e-9 {
            dir = vec2<f32>(bvx / d, bvy / d);
        }
        let left = ex * bvy - ey * bvx > 0.0;
        // Elevation.
        var core = 0.0;
        if kind == PLATEAU {
            core = width;
        }
        let we = clamp((core - d) / cell + 1.5, 0.0, 1.0);
        if we > 0.0 {
            if d <= d_e {
                d_e = d;
                v_e = z;
            }
            w_e = max(w_e, we);
        }
        // Gradient band (ridges and valleys), outside the hard core.
        var wb = 0.0;
        if kind != PLATEAU && d > 0.5 * cell {
            wb = clamp((width - d) / cell + 0.5, 0.0, 1.0);
            if wb > 0.0 {
                if d <= d_b {
                    d_b = d;
                    var t = geom[h + 5u];
                    if left {
                        t = geom[h + 4u];
                    }
                    var sl = t;
                    if kind == RIDGE {
                        sl = -t;
                    }
                    // The falloff, as `constraints/texels.rs` evaluates it.
                    let u = min(d * geom[h + 3u], 1.0);
                    let f = clamp(1.0 + u * u * (geom[h + 13u] + u * (geom[h + 14u] + u * geom[h + 15u])), 0.0, 1.0);
                    let slope = sl * f;
                    g_x = slope * dir.x;
                    g_y = slope * dir.y;
                }
                w_b = max(w_b, wb);
            }
        }
        // Roughness over the footprint.
        var inside = 0.0;
        if d <= width {
            inside = 1.0;
        }
        let wr = max(max(we, wb), inside);
        if wr > 0.0 {
            if wr >= w_r {
                v_r = geom[h + 7u];
            }
            w_r = max(w_r, wr);
        }
    }
    return Texel(w_e, v_e, w_b, g_x, g_y, w_r, v_r);
}

@compute @workgroup_size(8, 8)
fn main(
    @builtin(global_invocation_id) gid: vec3<u32>,
    @builtin(local_invocation_id) lid: vec3<u32>,
    @builtin(local_invocation_index) li: u32,
    @builtin(workgroup_id) wid: vec3<u32>,
) {
    let n = params.n;
    let i = gid.x;
    let j = gid.y;
    if li < 8u {
        // Empty ranges: min keys at their largest, max keys at their smallest.
        atomicStore(&range_keys[li], select(0u, 0xffffffffu, (li & 1u) == 0u));
    }
    var t = Texel(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    if i < n && j < n {
        t = texel(i, j);
        let idx = j * n + i;
        ew[idx] = t.w_e;
        ev[idx] = t.v_e;
        band[idx] = t.w_b;
    }
    tile_w[li] = t.w_r;
    tile_v[li] = t.v_r;
    tile_b[li] = t.w_b;
    tile_gx[li] = t.g_x;
    tile_gy[li] = t.g_y;
    workgroupBarrier();
    if i < n && j < n && t.w_e > 0.0 {
        count_value(0u, t.v_e);
    }
    // Threads (x, y) < (4, 4): level-1 cell (4 wid.x + x, 4 wid.y + y), from tile texels
    // (2 x .. 2 x + 2, 2 y .. 2 y + 2), row by row.
    let n1 = n / 2u;
    let i1 = 4u * wid.x + lid.x;
    let j1 = 4u * wid.y + lid.y;
    if lid.x < 4u && lid.y < 4u && i1 < n1 && j1 < n1 {
        var sw = 0.0;
        var sx = 0.0;
        var sy = 0.0;
        for (var y = 2u * lid.y; y < 2u * lid.y + 2u; y++) {
            for (var x = 2u * lid.x; x < 2u * lid.x + 2u; x++) {
                let w = tile_b[y * 8u + x];
                sw += w;
                sx += w * tile_gx[y * 8u + x];
                sy += w * tile_gy[y * 8u + x];
            }
        }
        let c = j1 * n1 + i1;
        let w = ds_weight(sw, 2u);
        let vx = ds_value(sx, sw);
        let v_y = ds_value(sy, sw);
        grad[c] = w;
        grad[n1 * n1 + c] = vx;
        vy[c] = v_y;
        if w > 0.0 {
            count_value(1u, vx);
            count_value(2u, v_y);
        }
    }
    // Threads 0..4 of the first row: level-2 cell (2 wid.x + b, 2 wid.y + a) for b = lid.x & 1,
    // a = lid.x >> 1, from tile texels (4 b .. 4 b + 4, 4 a .. 4 a + 4), row by row.
    let nc = n / 4u;
    let ic = 2u * wid.x + (lid.x & 1u);
    let jc = 2u * wid.y + (lid.x >> 1u);
    if lid.y == 0u && lid.x < 4u && ic < nc && jc < nc {
        let x0 = 4u * (lid.x & 1u);
        let y0 = 4u * (lid.x >> 1u);
        var sw = 0.0;
        var sv = 0.0;
        for (var y = y0; y < y0 + 4u; y++) {
            for (var x = x0; x < x0 + 4u; x++) {
                let w = tile_w[y * 8u + x];
                sw += w;
                sv += w * tile_v[y * 8u + x];
            }
        }
        let c = jc * nc + ic;
        let w = ds_weight(sw, 4u);
        let v = ds_value(sv, sw);
        rough[c] = w;
        rough[nc * nc + c] = v;
        if w > 0.0 {
            count_value(3u, v);
        }
    }
    workgroupBarrier();
    if li < 8u {
        let k = atomicLoad(&range_keys[li]);
        if (li & 1u) == 0u {
            if k != 0xffffffffu {
                atomicMin(&stats[li], k);
            }
        } else if k != 0u {
            atomicMax(&stats[li], k);
        }
    }
}
