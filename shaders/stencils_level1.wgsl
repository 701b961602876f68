// Pass: stencils_level1 (tests and diagnostics; no solver plan runs it): level 1's Galerkin operator
// R A_0 P as every level-1 pass computes it where it reads it (`#import coarse` as `coarse_level1`:
// nothing stores level 1), written out in full. One thread per level-1 cell.
// Reads:  diag (level 0, 2n x 2n; 0 marks hard cells), through `#import coarse`.
// Writes: out (level 1, n x n cells of 10 f32: c[oy * 3 + ox], all zero for an inactive cell (as
//         `st_get` says), then 1 where `st_active` (the centre-only evaluation the prolongation and
//         the neighbour tests use) says active, else 0).
// Params: n = side of level 1, ax, ay, threshold.
// Workgroup: 8 x 8.
#import params
#import stencil
#import coarse

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(2) var<storage, read_write> out: array<f32>;

@compute @workgroup_size(8, 8)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let n = params.n;
    if gid.x >= n || gid.y >= n {
        return;
    }
    let idx = gid.y * n + gid.x;
    var row = array<f32, 9>(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    _ = st_get(idx, &row);
    for (var k = 0u; k < 9u; k++) {
        out[10u * idx + k] = row[k];
    }
    out[10u * idx + 9u] = select(0.0, 1.0, st_active(idx));
}
