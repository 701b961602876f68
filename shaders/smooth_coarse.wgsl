// Pass: smooth_coarse (ALGORITHM.md "Smoothers"): one colour of four-colour Gauss-Seidel on a coarse level.
// Keep the cell update in sync with `update` in smooth_coarse_tiles.wgsl (whole sweeps in tiles).
// Thread (t, s) updates cell (2t + (colour & 1), 2s + (colour >> 1)): u_I = (f_I - sum_{o != 0} c_o u_{I+o}) / c_0.
// Reads:  the stencils (this level, `#import coarse`: records, or level 1's computed from the level-0
//         diagonal), f (this level); u (neighbours, of other colours).
// Writes: u on the active cells of this colour (inactive cells, c_0 == 0, are never touched).
// Params: n = side of this level, colour in 0..4 (ax, ay, threshold: level 1).
// Workgroup: 8 x 8 over (n/2, n/2) threads.
#import params
#import stencil
#import coarse

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(2) var<storage, read_write> u: array<f32>;
@group(0) @binding(3) var<storage, read> f: array<f32>;

@compute @workgroup_size(8, 8)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let n = params.n;
    if gid.x >= n / 2u || gid.y >= n / 2u {
        return;
    }
    let i = 2u * gid.x + (params.colour & 1u);
    let j = 2u * gid.y + (params.colour >> 1u);
    let idx = j * n + i;
    var st: array<f32, 9>;
    if !st_get(idx, &st) {
        return;
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
    u[idx] = (f[idx] - s) / c0;
}
