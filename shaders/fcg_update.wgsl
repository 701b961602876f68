// Pass: fcg_update: the FCG vector updates with the scalars computed on the GPU. One thread per level-0 cell.
// mode 0: if status == 0: h += alpha p, r -= alpha q.
// mode 1: p = z + beta p.
// mode 2: p = z (first iteration).
// q = A p is not stored: mode 0 recomputes it per cell from p and diag (`apply_p`, the arithmetic of
// apply_level0.wgsl; mode 0 does not write p, so the neighbours' p are those of this step).
// Reads:  scalars, z, diag; h (`#import h`: a buffer, or mip 0 of the height texture), r, p as
//         updated.
// Writes: h, r (mode 0); p (modes 1, 2).
// Params: n = level-0 side, mode.
// Workgroup: 8 x 8.
#import params
#import scalars
#import h
#import apply_p

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(2) var<storage, read> scalars: Scalars;
@group(0) @binding(3) var<storage, read_write> r: array<f32>;
@group(0) @binding(4) var<storage, read> z: array<f32>;
@group(0) @binding(5) var<storage, read_write> p: array<f32>;
@group(0) @binding(6) var<storage, read> diag: array<f32>;

fn p_get(i: u32, j: u32) -> f32 {
    return p[j * params.n + i];
}

@compute @workgroup_size(8, 8)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let n = params.n;
    if gid.x >= n || gid.y >= n {
        return;
    }
    let idx = gid.y * n + gid.x;
    if params.mode == 0u {
        if scalars.status == 0u {
            let alpha = scalars.alpha;
            h_put(gid.x, gid.y, h_get(gid.x, gid.y) + alpha * p[idx]);
            r[idx] -= alpha * q_at(idx);
        }
    } else if params.mode == 1u {
        p[idx] = z[idx] + scalars.beta * p[idx];
    } else {
        p[idx] = z[idx];
    }
}
