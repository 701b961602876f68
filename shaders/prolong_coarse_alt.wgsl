// Pass: prolong_coarse_alt: prolong_coarse.wgsl into another buffer, for a tile sweep that follows
// (smooth_coarse_tiles.wgsl reads its input from a buffer no workgroup writes): alt = u + P u_{k+1}
// on the active cells of coarse level k and alt = u on the others (mode 0), or alt = P u_{k+1} with
// inactive cells 0 (mode 1, FMG interpolation). The same sums as prolong_coarse.wgsl.
// Reads:  the stencils of level k (activity; `#import coarse`: records, or level 1's computed from the
//         level-0 diagonal), u (level k, not read in mode 1), uc (level k+1, n/2 x n/2).
// Writes: alt (level k, n x n), every cell.
// Params: n = side of level k, mode (ax, ay, threshold: level 1).
// Workgroup: 8 x 8, one thread per level-k cell.
#import params
#import transfer
#import prolong
#import stencil
#import coarse

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(2) var<storage, read> u: array<f32>;
@group(0) @binding(3) var<storage, read> uc: array<f32>;
@group(0) @binding(4) var<storage, read_write> alt: array<f32>;

@compute @workgroup_size(8, 8)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let n = params.n;
    let i = gid.x;
    let j = gid.y;
    if i >= n || j >= n {
        return;
    }
    let set_mode = params.mode == 1u;
    let idx = j * n + i;
    if !st_active(idx) {
        if set_mode {
            alt[idx] = 0.0;
        } else {
            alt[idx] = u[idx];
        }
        return;
    }
    let e = prolong_e(i, j, n);
    if set_mode {
        alt[idx] = e;
    } else {
        alt[idx] = u[idx] + e;
    }
}
