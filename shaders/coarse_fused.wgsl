// Pass: coarse_fused (ALGORITHM.md "Coarse levels in one dispatch"): every pass on the levels from
// the first fused one (side params.n <= 64) down to the coarsest, in ONE workgroup, one program step
// after the other with a barrier after each. Each step is the per-cell arithmetic of its own pass
// file (smooth_coarse, residual_restrict_coarse, prolong_coarse, restrict_sum, coarsest_solve), in
// the same order, so the bits are those of the unfused passes: keep the cell bodies in sync.
// Reads:  program (step words `kind | level << 4 | colour << 8`, levels relative to the first fused
//         level; `plan::fused_program`), the stencil records of the fused levels (one binding per
//         level, the last repeated when there are fewer than four levels).
// Writes: u, f of the fused levels, packed level after level from the first (offsets from params.n).
// Params: n = side of the first fused level, src_offset / dst_offset = first word / words of the
//         program.
// Workgroup: 256 threads, dispatch exactly one workgroup; workgroup memory 64 x 64 f32 = 16384 bytes
// (the coarsest solve's matrix).
#import params
#import transfer
#import stencil

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> program: array<u32>;
@group(0) @binding(2) var<storage, read> st0: array<u32>;
@group(0) @binding(3) var<storage, read> st1: array<u32>;
@group(0) @binding(4) var<storage, read> st2: array<u32>;
@group(0) @binding(5) var<storage, read> st3: array<u32>;
@group(0) @binding(6) var<storage, read_write> u: array<f32>;
@group(0) @binding(7) var<storage, read_write> f: array<f32>;

// Step kinds: keep in sync with `plan::fused_kind`.
const K_SMOOTH: u32 = 0u;
const K_RESIDUAL_RESTRICT: u32 = 1u;
const K_CLEAR_U: u32 = 2u;
const K_PROLONG_ADD: u32 = 3u;
const K_PROLONG_SET: u32 = 4u;
const K_RESTRICT_SUM: u32 = 5u;
const K_COARSEST_SOLVE: u32 = 6u;

const WG: u32 = 256u;
const M: u32 = 64u;
const SIDE: u32 = 8u;
const TINY: f32 = 1e-30;

var<workgroup> a: array<f32, 4096>;

// Word `w` of level `lvl`'s stencil records.
fn rec(lvl: u32, w: u32) -> u32 {
    switch lvl {
        case 0u: {
            return st0[w];
        }
        case 1u: {
            return st1[w];
        }
        case 2u: {
            return st2[w];
        }
        default: {
            return st3[w];
        }
    }
}

// `st_active` / `st_get` of `shared/coarse_records.wgsl` on level `lvl`.
fn level_active(lvl: u32, idx: u32) -> bool {
    let b = STENCIL_WORDS * idx;
    return rec(lvl, b + 4u) != 0u || rec(lvl, b + 5u) != 0u;
}

fn level_get(lvl: u32, idx: u32, row: ptr<function, array<f32, 9>>) -> bool {
    if !level_active(lvl, idx) {
        return false;
    }
    let b = STENCIL_WORDS * idx;
    *row = st_decode(array<u32, 6>(rec(lvl, b), rec(lvl, b + 1u), rec(lvl, b + 2u), rec(lvl, b + 3u),
        rec(lvl, b + 4u), rec(lvl, b + 5u)));
    return true;
}

// Side and first element (in u and f) of level `lvl`.
fn side(lvl: u32) -> u32 {
    return params.n >> lvl;
}

fn offset(lvl: u32) -> u32 {
    var o = 0u;
    for (var l = 0u; l < lvl; l++) {
        o += side(l) * side(l);
    }
    return o;
}

// smooth_coarse.wgsl, thread (gx, gy).
fn smooth_cell(lvl: u32, colour: u32, gx: u32, gy: u32) {
    let n = side(lvl);
    let o = offset(lvl);
    let i = 2u * gx + (colour & 1u);
    let j = 2u * gy + (colour >> 1u);
    let idx = j * n + i;
    var st: array<f32, 9>;
    if !level_get(lvl, idx, &st) {
        return;
    }
    let c0 = st[4];
    var s = 0.0;
    if i > 0u && j > 0u && i + 1u < n && j + 1u < n {
        let b = o + idx;
        s += st[0] * u[b - n - 1u] + st[1] * u[b - n] + st[2] * u[b - n + 1u];
        s += st[3] * u[b - 1u] + st[5] * u[b + 1u];
        s += st[6] * u[b + n - 1u] + st[7] * u[b + n] + st[8] * u[b + n + 1u];
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
                s += st[oy * 3u + ox] * u[o + (yy - 1u) * n + (xx - 1u)];
            }
        }
    }
    u[o + idx] = (f[o + idx] - s) / c0;
}

// residual_restrict_coarse.wgsl's residual_at.
fn residual_at(lvl: u32, i: u32, j: u32) -> f32 {
    let n = side(lvl);
    let o = offset(lvl);
    let idx = j * n + i;
    var st: array<f32, 9>;
    if !level_get(lvl, idx, &st) {
        return 0.0;
    }
    let c0 = st[4];
    var s = 0.0;
    if i > 0u && j > 0u && i + 1u < n && j + 1u < n {
        let b = o + idx;
        s += st[0] * u[b - n - 1u] + st[1] * u[b - n] + st[2] * u[b - n + 1u];
        s += st[3] * u[b - 1u] + st[5] * u[b + 1u];
        s += st[6] * u[b + n - 1u] + st[7] * u[b + n] + st[8] * u[b + n + 1u];
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
                s += st[oy * 3u + ox] * u[o + (yy - 1u) * n + (xx - 1u)];
            }
        }
    }
    return f[o + idx] - c0 * u[o + idx] - s;
}

// residual_restrict_coarse.wgsl, thread (ic, jc).
fn residual_restrict(lvl: u32, ic: u32, jc: u32) {
    let nc = side(lvl) / 2u;
    var s = 0.0;
    s += residual_at(lvl, 2u * ic, 2u * jc);
    s += residual_at(lvl, 2u * ic + 1u, 2u * jc);
    s += residual_at(lvl, 2u * ic, 2u * jc + 1u);
    s += residual_at(lvl, 2u * ic + 1u, 2u * jc + 1u);
    f[offset(lvl + 1u) + jc * nc + ic] = s;
}

// prolong_coarse.wgsl, thread (i, j).
fn prolong(lvl: u32, set_mode: bool, i: u32, j: u32) {
    let n = side(lvl);
    let o = offset(lvl);
    let oc = offset(lvl + 1u);
    let idx = j * n + i;
    if !level_active(lvl, idx) {
        if set_mode {
            u[o + idx] = 0.0;
        }
        return;
    }
    let nc = n / 2u;
    let wy = p_weights(j, nc);
    let wx = p_weights(i, nc);
    var e = 0.0;
    for (var ya = 0u; ya < 2u; ya++) {
        for (var xb = 0u; xb < 2u; xb++) {
            e += wx.w[xb] * wy.w[ya] * u[oc + wy.idx[ya] * nc + wx.idx[xb]];
        }
    }
    if set_mode {
        u[o + idx] = e;
    } else {
        u[o + idx] += e;
    }
}

// restrict_sum.wgsl, thread (ic, jc).
fn restrict_sum(lvl: u32, ic: u32, jc: u32) {
    let nf = side(lvl);
    let nc = nf / 2u;
    let b = offset(lvl) + 2u * jc * nf + 2u * ic;
    f[offset(lvl + 1u) + jc * nc + ic] = f[b] + f[b + 1u] + f[b + nf] + f[b + nf + 1u];
}

// coarsest_solve.wgsl's assembly of row t (t < 64) of the 8 x 8 level `lvl`.
fn solve_assemble(lvl: u32, t: u32) {
    let o = offset(lvl);
    for (var k = 0u; k < M; k++) {
        a[t * M + k] = 0.0;
    }
    var row: array<f32, 9>;
    if side(lvl) == SIDE && level_get(lvl, t, &row) {
        let i = t % SIDE;
        let j = t / SIDE;
        for (var oy = 0u; oy < 3u; oy++) {
            for (var ox = 0u; ox < 3u; ox++) {
                let x = i + ox;
                let y = j + oy;
                if x < 1u || y < 1u || x > SIDE || y > SIDE {
                    continue;
                }
                let nb = (y - 1u) * SIDE + (x - 1u);
                if level_active(lvl, nb) {
                    a[t * M + nb] += row[oy * 3u + ox];
                }
            }
        }
        u[o + t] = f[o + t];
    } else {
        a[t * M + t] = 1.0;
        u[o + t] = 0.0;
    }
}

@compute @workgroup_size(256)
fn main(@builtin(local_invocation_index) t: u32) {
    for (var pc = 0u; pc < params.dst_offset; pc++) {
        let w = program[params.src_offset + pc];
        let kind = w & 15u;
        let lvl = (w >> 4u) & 15u;
        let colour = (w >> 8u) & 15u;
        let n = side(lvl);
        let h = n / 2u;
        if kind == K_SMOOTH {
            for (var c = t; c < h * h; c += WG) {
                smooth_cell(lvl, colour, c % h, c / h);
            }
        } else if kind == K_RESIDUAL_RESTRICT {
            for (var c = t; c < h * h; c += WG) {
                residual_restrict(lvl, c % h, c / h);
            }
        } else if kind == K_CLEAR_U {
            let o = offset(lvl);
            for (var c = t; c < n * n; c += WG) {
                u[o + c] = 0.0;
            }
        } else if kind == K_PROLONG_ADD || kind == K_PROLONG_SET {
            for (var c = t; c < n * n; c += WG) {
                prolong(lvl, kind == K_PROLONG_SET, c % n, c / n);
            }
        } else if kind == K_RESTRICT_SUM {
            for (var c = t; c < h * h; c += WG) {
                restrict_sum(lvl, c % h, c / h);
            }
        } else if kind == K_COARSEST_SOLVE && t < M {
            solve_assemble(lvl, t);
        }
        workgroupBarrier();
        storageBarrier();

        // The coarsest solve's elimination (coarsest_solve.wgsl): its column loop runs for the
        // solve step only (every thread reads the same step word, so the barriers inside are
        // reached by the whole workgroup).
        let o = offset(lvl);
        let columns = select(0u, M, kind == K_COARSEST_SOLVE);
        for (var col = 0u; col < columns; col++) {
            // Every thread finds the same pivot.
            var piv = col;
            var best = abs(a[col * M + col]);
            for (var r = col + 1u; r < M; r++) {
                let v = abs(a[r * M + col]);
                if v >= best {
                    best = v;
                    piv = r;
                }
            }
            let usable = best >= TINY;
            workgroupBarrier();
            if usable && piv != col && t < M {
                // Thread t swaps column t of the two rows; thread 0 swaps the right-hand side.
                let tmp = a[col * M + t];
                a[col * M + t] = a[piv * M + t];
                a[piv * M + t] = tmp;
                if t == 0u {
                    let tb = u[o + col];
                    u[o + col] = u[o + piv];
                    u[o + piv] = tb;
                }
            }
            workgroupBarrier();
            storageBarrier();
            if usable && t > col && t < M {
                let factor = a[t * M + col] / a[col * M + col];
                if factor != 0.0 {
                    for (var k = col; k < M; k++) {
                        a[t * M + k] -= factor * a[col * M + k];
                    }
                    u[o + t] -= factor * u[o + col];
                }
            }
            workgroupBarrier();
            storageBarrier();
        }
        // Back substitution by one thread; u[k] holds x[k] once row k is done.
        if kind == K_COARSEST_SOLVE && t == 0u {
            for (var rr = 0u; rr < M; rr++) {
                let r = M - 1u - rr;
                var s = u[o + r];
                for (var k = r + 1u; k < M; k++) {
                    s -= a[r * M + k] * u[o + k];
                }
                let d = a[r * M + r];
                u[o + r] = select(s / d, 0.0, abs(d) < TINY);
            }
        }
        workgroupBarrier();
        storageBarrier();
    }
}
