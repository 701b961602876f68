// Pass: prolong_coarse: u_k += P u_{k+1} on the active cells of coarse level k (mode 0), or u_k = P u_{k+1}
// with inactive cells set to 0 (mode 1, FMG interpolation).
// Reads:  the stencils of level k (activity; `#import coarse`: records, or level 1's computed from the
//         level-0 diagonal), uc (level k+1, n/2 x n/2).
// Writes: u (level k, n x n).
// Params: n = side of level k, mode (ax, ay, threshold: level 1).
// Workgroup: 8 x 8, one thread per level-k cell.
#import params
#import transfer
#import prolong
#import stencil
#import coarse

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(2) var<storage, read_write> u: array<f32>;
@group(0) @binding(3) var<storage, read> uc: array<f32>;

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
            u[idx] = 0.0;
        }
        return;
    }
    let e = prolong_e(i, j, n);
    if set_mode {
        u[idx] = e;
    } else {
        u[idx] += e;
    }
}
