// Pass: galerkin_coarse (ALGORITHM.md "Coarse levels"): level-k operator R A_{k-1} P for k >= 2, one thread
// per level-k cell.
// Reads:  the stencils of level k-1 (n x n; an inactive cell's row and column are left out) through
//         `#import coarse`: the records of `#import stencil` for k >= 3, level 1's computed from the
//         level-0 diagonal for k = 2 (`coarse_level1`).
// Writes: out_stencil (level k, n/2 x n/2, the same records); all zero when the centre coefficient is
//         <= threshold.
// Params: n = side of level k-1, ax, ay, threshold.
// Workgroup: 8 x 8.
#import params
#import transfer
#import stencil
#import coarse

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(2) var<storage, read_write> out_stencil: array<u32>;

@compute @workgroup_size(8, 8)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let nf = params.n;
    let nc = nf / 2u;
    let ic = gid.x;
    let jc = gid.y;
    if ic >= nc || jc >= nc {
        return;
    }
    var acc = array<f32, 9>(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    for (var cy = 0u; cy < 2u; cy++) {
        for (var cx = 0u; cx < 2u; cx++) {
            let i = 2u * ic + cx;
            let j = 2u * jc + cy;
            var row: array<f32, 9>;
            if !st_get(j * nf + i, &row) {
                continue;
            }
            for (var oy = 0u; oy < 3u; oy++) {
                let yy = j + oy;
                if yy < 1u || yy > nf {
                    continue;
                }
                let y = yy - 1u;
                for (var ox = 0u; ox < 3u; ox++) {
                    let c = row[oy * 3u + ox];
                    if c == 0.0 {
                        continue;
                    }
                    let xx = i + ox;
                    if xx < 1u || xx > nf {
                        continue;
                    }
                    let x = xx - 1u;
                    if !st_active(y * nf + x) {
                        continue; // inactive fine cell: P row is zero
                    }
                    scatter(&acc, c, x, y, nc, ic, jc);
                }
            }
        }
    }
    var rec = st_record(acc, acc[4] > params.threshold);
    let out = STENCIL_WORDS * (jc * nc + ic);
    for (var w = 0u; w < STENCIL_WORDS; w++) {
        out_stencil[out + w] = rec[w];
    }
}
