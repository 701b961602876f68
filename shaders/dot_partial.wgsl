// Pass: dot_partial: first pass of the FCG reductions, one f32 partial per workgroup and quantity.
// mode STAGE_PQ: p.q -> slot SLOT_PQ.  mode STAGE_Z: z.q -> SLOT_ZQ and r.z -> SLOT_RZ.
// mode STAGE_R: max |r| -> SLOT_RMAX.
// mode STAGE_RZ: 0 -> SLOT_ZQ and r.z -> SLOT_RZ (FCG's first direction: p = z follows, so z.q is
//                unused; r.z is STAGE_Z's, summed in the same order).
// q = A p is not stored: it is recomputed per cell from p and diag (`apply_p`, the arithmetic of
// apply_level0.wgsl), p unchanged since the FCG step that used it.
// Reads:  r, z, p, diag (level 0, n x n), as the stage needs them.
// Writes: partials[slot * MAX_PARTIALS + workgroup] for workgroup < params.partials.
// Params: n = level-0 side, mode = stage, partials = number of workgroups dispatched (<= MAX_PARTIALS).
// Workgroup: 256 (1D); each thread strides over the cells by partials * 256.
#import params
#import scalars
#import apply_p

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> r: array<f32>;
@group(0) @binding(2) var<storage, read> z: array<f32>;
@group(0) @binding(3) var<storage, read> p: array<f32>;
@group(0) @binding(4) var<storage, read> diag: array<f32>;
@group(0) @binding(5) var<storage, read_write> partials: array<f32>;

fn p_get(i: u32, j: u32) -> f32 {
    return p[j * params.n + i];
}

const WG: u32 = 256u;
var<workgroup> sa: array<f32, 256>;
var<workgroup> sb: array<f32, 256>;

@compute @workgroup_size(256)
fn main(@builtin(local_invocation_index) lid: u32, @builtin(workgroup_id) wid: vec3<u32>) {
    let cells = params.n * params.n;
    let stride = params.partials * WG;
    let stage = params.mode;
    var a = 0.0;
    var b = 0.0;
    var idx = wid.x * WG + lid;
    if stage == STAGE_PQ {
        for (; idx < cells; idx += stride) {
            a += p[idx] * q_at(idx);
        }
    } else if stage == STAGE_Z {
        for (; idx < cells; idx += stride) {
            a += z[idx] * q_at(idx);
            b += r[idx] * z[idx];
        }
    } else if stage == STAGE_RZ {
        for (; idx < cells; idx += stride) {
            b += r[idx] * z[idx];
        }
    } else {
        for (; idx < cells; idx += stride) {
            a = max(a, abs(r[idx]));
        }
    }
    sa[lid] = a;
    sb[lid] = b;
    for (var s = WG / 2u; s > 0u; s = s / 2u) {
        workgroupBarrier();
        if lid < s {
            if stage == STAGE_R {
                sa[lid] = max(sa[lid], sa[lid + s]);
            } else {
                sa[lid] = sa[lid] + sa[lid + s];
                sb[lid] = sb[lid] + sb[lid + s];
            }
        }
    }
    if lid == 0u {
        if stage == STAGE_PQ {
            partials[SLOT_PQ * MAX_PARTIALS + wid.x] = sa[0];
        } else if stage == STAGE_Z || stage == STAGE_RZ {
            partials[SLOT_ZQ * MAX_PARTIALS + wid.x] = sa[0];
            partials[SLOT_RZ * MAX_PARTIALS + wid.x] = sb[0];
        } else {
            partials[SLOT_RMAX * MAX_PARTIALS + wid.x] = sa[0];
        }
    }
}
