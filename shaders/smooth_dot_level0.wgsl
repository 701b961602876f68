// Pass: smooth_dot_level0: the preconditioner's last red-black colour on level 0 (z = M r) and the
// first pass of the reduction after it (dot_partial.wgsl's STAGE_Z or STAGE_RZ) in one pass, so z
// is read once. Each thread strides over the cells as dot_partial's threads do, updates the cells
// of the colour with smooth_level0.wgsl's arithmetic (keep in sync) from their neighbours of the
// other colour (which no thread writes), and adds every cell's terms in dot_partial's order: the
// partials are those of the two passes.
// mode STAGE_Z: z.q -> SLOT_ZQ and r.z -> SLOT_RZ.  mode STAGE_RZ: 0 -> SLOT_ZQ and r.z -> SLOT_RZ.
// Both: z.A z -> SLOT_PQ (dot_final's STAGE_ZPQ turns it into the new direction's p.q, so no pass
// reduces p.q). Each cell adds diag z^2; a cell of the colour's parity also its edges,
// -2 a z z_nb: every edge joins one such cell and one of the other parity, whose z this pass does
// not write (z is 0 on hard cells, so their edges add 0, as their rows of A z do).
// q = A p is recomputed per cell from p and diag (`apply_p`).
// Reads:  r, diag (level 0); z (the other colour); p (STAGE_Z).
// Writes: z on the free cells of the colour; partials[slot * MAX_PARTIALS + workgroup].
// Params: n = level-0 side, colour (2: no cell is updated, the edges go with parity 0), mode =
//         stage, ax, ay, partials = workgroups dispatched.
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

// The weighted sum of the neighbours' z of cell idx = (i, j), in smooth_level0.wgsl's order.
fn neighbours(idx: u32, i: u32, j: u32) -> f32 {
    let n = params.n;
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
    return s;
}

const WG: u32 = 256u;
var<workgroup> sa: array<f32, 256>;
var<workgroup> sb: array<f32, 256>;
var<workgroup> sc: array<f32, 256>;

@compute @workgroup_size(256)
fn main(@builtin(local_invocation_index) lid: u32, @builtin(workgroup_id) wid: vec3<u32>) {
    let n = params.n;
    let cells = n * n;
    let stride = params.partials * WG;
    let both = params.mode == STAGE_Z;
    let colour = params.colour;
    var a = 0.0;
    var b = 0.0;
    var c = 0.0;
    for (var idx = wid.x * WG + lid; idx < cells; idx += stride) {
        let i = idx % n;
        let j = idx / n;
        let d = diag[idx];
        var zv = z[idx];
        var zaz = d * zv;
        if ((i + j) & 1u) == (colour & 1u) && d != 0.0 {
            // smooth_level0.wgsl's update (colour < 2), and this cell's edges.
            let s = neighbours(idx, i, j);
            if colour < 2u {
                zv = (r[idx] + s) / d;
                z[idx] = zv;
            }
            zaz = d * zv - 2.0 * s;
        }
        if both {
            a += zv * q_at(idx);
        }
        b += r[idx] * zv;
        c += zv * zaz;
    }
    sa[lid] = a;
    sb[lid] = b;
    sc[lid] = c;
    for (var s = WG / 2u; s > 0u; s = s / 2u) {
        workgroupBarrier();
        if lid < s {
            sa[lid] = sa[lid] + sa[lid + s];
            sb[lid] = sb[lid] + sb[lid + s];
            sc[lid] = sc[lid] + sc[lid + s];
        }
    }
    if lid == 0u {
        partials[SLOT_ZQ * MAX_PARTIALS + wid.x] = sa[0];
        partials[SLOT_RZ * MAX_PARTIALS + wid.x] = sb[0];
        partials[SLOT_PQ * MAX_PARTIALS + wid.x] = sc[0];
    }
}
