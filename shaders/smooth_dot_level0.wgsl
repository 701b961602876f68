// Pass: smooth_dot_level0: the preconditioner's last red-black colour on level 0 (z = M r) and the
// first pass of the reduction after it (dot_partial.wgsl's STAGE_Z or STAGE_RZ) in one pass, so z
// is read once. Each thread strides over the cells as dot_partial's threads do, updates the cells
// of the colour with smooth_level0.wgsl's arithmetic (keep in sync) from their neighbours of the
// other colour (which no thread writes), and adds every cell's terms in dot_partial's order: the
// partials are those of the two passes.
// mode STAGE_Z: z.q -> SLOT_ZQ and r.z -> SLOT_RZ.  mode STAGE_RZ: 0 -> SLOT_ZQ and r.z -> SLOT_RZ.
// q = A p is recomputed per cell from p and diag (`apply_p`).
// Reads:  r, diag (level 0); z (the other colour); p (STAGE_Z).
// Writes: z on the free cells of the colour; partials[slot * MAX_PARTIALS + workgroup].
// Params: n = level-0 side, colour, mode = stage, ax, ay, partials = workgroups dispatched.
// Workgroup: 256 (1D); each thread strides over the cells by partials * 256.
#import params
#import scalars
#import apply_p

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> r: array<f32>;
@group(0) @binding(2) var<storage, read_write> z: array<f32>;
@group(0) @binding(3) var<storage, read> p: array<f32>;
@group(0) @binding(4) var<storage, read> diag: array<f32>;
@group(0) @binding(5) var<storage, read_write> partials: array<f32>;

fn p_get(i: u32, j: u32) -> f32 {
    return p[j * params.n + i];
}

// z at cell idx = (i, j) after the colour: smooth_level0.wgsl's update on the colour's free cells.
fn z_after(idx: u32, i: u32, j: u32) -> f32 {
    let n = params.n;
    if ((i + j) & 1u) != params.colour {
        return z[idx];
    }
    let d = diag[idx];
    if d == 0.0 {
        return z[idx];
    }
    let ax = params.ax;
    let ay = params.ay;
    var s = 0.0;
    if i > 0u && i + 1u < n && j > 0u && j + 1u < n {
        s = ax * (z[idx - 1u] + z[idx + 1u]) + ay * (z[idx - n] + z[idx + n]);
    } else {
        if i > 0u {
            s += ax * z[idx - 1u];
        }
        if i + 1u < n {
            s += ax * z[idx + 1u];
        }
        if j > 0u {
            s += ay * z[idx - n];
        }
        if j + 1u < n {
            s += ay * z[idx + n];
        }
    }
    let v = (r[idx] + s) / d;
    z[idx] = v;
    return v;
}

const WG: u32 = 256u;
var<workgroup> sa: array<f32, 256>;
var<workgroup> sb: array<f32, 256>;

@compute @workgroup_size(256)
fn main(@builtin(local_invocation_index) lid: u32, @builtin(workgroup_id) wid: vec3<u32>) {
    let n = params.n;
    let cells = n * n;
    let stride = params.partials * WG;
    let both = params.mode == STAGE_Z;
    var a = 0.0;
    var b = 0.0;
    for (var idx = wid.x * WG + lid; idx < cells; idx += stride) {
        let zv = z_after(idx, idx % n, idx / n);
        if both {
            a += zv * q_at(idx);
        }
        b += r[idx] * zv;
    }
    sa[lid] = a;
    sb[lid] = b;
    for (var s = WG / 2u; s > 0u; s = s / 2u) {
        workgroupBarrier();
        if lid < s {
            sa[lid] = sa[lid] + sa[lid + s];
            sb[lid] = sb[lid] + sb[lid + s];
        }
    }
    if lid == 0u {
        partials[SLOT_ZQ * MAX_PARTIALS + wid.x] = sa[0];
        partials[SLOT_RZ * MAX_PARTIALS + wid.x] = sb[0];
    }
}
