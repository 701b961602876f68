// Pass: dot_final: second pass of the FCG reductions and the FCG scalars, in ONE workgroup.
// mode STAGE_PQ: pq = sum; alpha = rz / pq and status = 0, or alpha = 0 and status = 1 when pq <= 0 or is
//                not finite (as `cpu::Fcg::iterate`).
// mode STAGE_Z:  zq = sum, rz = sum; beta = -zq / pq (0 when pq <= 0). (After dot_partial's STAGE_RZ
//                the zq partials are 0: zq and beta are unused there.)
// mode STAGE_ZPQ: as STAGE_Z (beta 0 when the stop-test relaxation flagged a restart in
//                scalars.spike[15], cleared here), then pq of the new direction p = z + beta p,
//                which is A-orthogonal to the old one: p.q = z.A z + 2 beta z.q_old + beta^2
//                pq_old = z.A z + beta z.q_old (z.A z in slot SLOT_PQ, from smooth_dot_level0);
//                then alpha and status as STAGE_PQ.
// mode STAGE_R:  rmax = max.
// Reads:  partials (the stage's slots, params.partials entries each).
// Writes: scalars.
// Params: mode = stage, partials.
// Workgroup: 256 (1D). Dispatch exactly one workgroup.
#import params
#import scalars

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> partials: array<f32>;
@group(0) @binding(2) var<storage, read_write> scalars: Scalars;

const WG: u32 = 256u;
const F32_MAX: f32 = 3.40282347e38;
var<workgroup> sa: array<f32, 256>;
var<workgroup> sb: array<f32, 256>;
var<workgroup> sc: array<f32, 256>;

// alpha = rz / pq and status = 0, or alpha = 0 and status = 1 when pq <= 0 or is not finite.
fn set_alpha(pq: f32) {
    scalars.pq = pq;
    if pq > 0.0 && pq <= F32_MAX {
        scalars.alpha = scalars.rz / pq;
        scalars.status = 0u;
    } else {
        scalars.alpha = 0.0;
        scalars.status = 1u;
    }
}

@compute @workgroup_size(256)
fn main(@builtin(local_invocation_index) lid: u32) {
    let stage = params.mode;
    var slot_a = SLOT_PQ;
    var slot_b = SLOT_PQ;
    let zpq = stage == STAGE_ZPQ;
    if stage == STAGE_Z || zpq {
        slot_a = SLOT_ZQ;
        slot_b = SLOT_RZ;
    } else if stage == STAGE_R {
        slot_a = SLOT_RMAX;
        slot_b = SLOT_RMAX;
    }
    var a = 0.0;
    var b = 0.0;
    var c = 0.0;
    for (var k = lid; k < params.partials; k += WG) {
        let va = partials[slot_a * MAX_PARTIALS + k];
        let vb = partials[slot_b * MAX_PARTIALS + k];
        if stage == STAGE_R {
            a = max(a, va);
        } else {
            a += va;
            b += vb;
        }
        if zpq {
            c += partials[SLOT_PQ * MAX_PARTIALS + k];
        }
    }
    sa[lid] = a;
    sb[lid] = b;
    sc[lid] = c;
    for (var s = WG / 2u; s > 0u; s = s / 2u) {
        workgroupBarrier();
        if lid < s {
            if stage == STAGE_R {
                sa[lid] = max(sa[lid], sa[lid + s]);
            } else {
                sa[lid] = sa[lid] + sa[lid + s];
                sb[lid] = sb[lid] + sb[lid + s];
                sc[lid] = sc[lid] + sc[lid + s];
            }
        }
    }
    if lid == 0u {
        if stage == STAGE_PQ {
            set_alpha(sa[0]);
        } else if stage == STAGE_Z || zpq {
            let zq = sa[0];
            scalars.zq = zq;
            scalars.rz = sb[0];
            let pq = scalars.pq;
            // FCG restarts (beta 0) after its stop-test relaxation, which used `p` for its
            // correction (relax_mask sets the flag).
            let restart = zpq && scalars.spike[15] != 0u;
            let beta = select(select(0.0, -zq / pq, pq > 0.0), 0.0, restart);
            if restart {
                scalars.spike[15] = 0u;
            }
            scalars.beta = beta;
            if zpq {
                set_alpha(sc[0] + beta * zq);
            }
        } else {
            scalars.rmax = sa[0];
        }
    }
}
