// Pass: residual_restrict_coarse: r = f - A u on coarse level k (0 on inactive cells), restricted to level k+1
// as the sum of the 4 children. One thread per level-(k+1) cell.
// Reads:  the stencils (`#import coarse`: records, or level 1's computed from the level-0 diagonal),
//         u, f (level k, n x n).
// Writes: out (level k+1, n/2 x n/2).
// Params: n = side of level k (ax, ay, threshold: level 1).
// Workgroup: 8 x 8 over (n/2, n/2) threads.
#import params
#import stencil
#import coarse

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(2) var<storage, read> u: array<f32>;
@group(0) @binding(3) var<storage, read> f: array<f32>;
@group(0) @binding(4) var<storage, read_write> out: array<f32>;

fn residual_at(i: u32, j: u32) -> f32 {
    let n = params.n;
    let idx = j * n + i;
    var st: array<f32, 9>;
    if !st_get(idx, &st) {
        return 0.0;
    }
    let c0 = st[4];
    var s = 0.0;
    if i > 0u && j > 0u && i + 1u < n && j + 1u < n {
        let b = idx;
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
                s += st[oy * 3u + ox] * u[(yy - 1u) * n + (xx - 1u)];
            }
        }
    }
    return f[idx] - c0 * u[idx] - s;
}

@compute @workgroup_size(8, 8)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let nc = params.n / 2u;
    let ic = gid.x;
    let jc = gid.y;
    if ic >= nc || jc >= nc {
        return;
    }
    var s = 0.0;
    s += residual_at(2u * ic, 2u * jc);
    s += residual_at(2u * ic + 1u, 2u * jc);
    s += residual_at(2u * ic, 2u * jc + 1u);
    s += residual_at(2u * ic + 1u, 2u * jc + 1u);
    out[jc * nc + ic] = s;
}
