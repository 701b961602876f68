// Pass: galerkin_level0 (ALGORITHM.md "Coarse levels"): level-1 operator R A_0 P, one thread per level-1 cell.
// Reads:  diag (level 0, n x n; 0 marks hard cells, whose rows and columns are left out).
// Writes: stencil (level 1, n/2 x n/2, the records of `#import stencil`); all zero when the
//         centre coefficient is <= threshold (inactive cell).
// Params: n = level-0 side, ax, ay, threshold.
// Workgroup: 8 x 8.
#import params
#import transfer
#import stencil

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> diag: array<f32>;
@group(0) @binding(2) var<storage, read_write> stencil: array<u32>;

@compute @workgroup_size(8, 8)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let nf = params.n;
    let nc = nf / 2u;
    let ic = gid.x;
    let jc = gid.y;
    if ic >= nc || jc >= nc {
        return;
    }
    let ax = params.ax;
    let ay = params.ay;
    var acc = array<f32, 9>(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    for (var cy = 0u; cy < 2u; cy++) {
        for (var cx = 0u; cx < 2u; cx++) {
            let i = 2u * ic + cx;
            let j = 2u * jc + cy;
            let idx = j * nf + i;
            let d = diag[idx];
            if d == 0.0 {
                continue; // hard row: not part of A_ff
            }
            scatter(&acc, d, i, j, nc, ic, jc);
            if i > 0u && diag[idx - 1u] != 0.0 {
                scatter(&acc, -ax, i - 1u, j, nc, ic, jc);
            }
            if i + 1u < nf && diag[idx + 1u] != 0.0 {
                scatter(&acc, -ax, i + 1u, j, nc, ic, jc);
            }
            if j > 0u && diag[idx - nf] != 0.0 {
                scatter(&acc, -ay, i, j - 1u, nc, ic, jc);
            }
            if j + 1u < nf && diag[idx + nf] != 0.0 {
                scatter(&acc, -ay, i, j + 1u, nc, ic, jc);
            }
        }
    }
    var rec = st_record(acc, acc[4] > params.threshold);
    let out = STENCIL_WORDS * (jc * nc + ic);
    for (var w = 0u; w < STENCIL_WORDS; w++) {
        stencil[out + w] = rec[w];
    }
}
