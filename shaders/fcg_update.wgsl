// Pass: fcg_update: the FCG vector updates with the scalars computed on the GPU, and (mode 0) the
// first pass of the max |r| reduction.
// mode 0: if status == 0: h += alpha p, r -= alpha q; then max |r| (the new r, or the unchanged r
//         when stopped) -> partials slot SLOT_RMAX, one partial per workgroup, as dot_partial's
//         STAGE_R writes it: dot_final STAGE_R follows directly, with no pass re-reading r.
// mode 1: p = z + beta p.
// mode 2: p = z (first iteration).
// q = A p is not stored: mode 0 recomputes it per cell from p and diag (`apply_p`, the arithmetic of
// apply_level0.wgsl; mode 0 does not write p, so the neighbours' p are those of this step).
// Reads:  scalars; mode 0: diag, h (`#import h`: a buffer, or mip 0 of the height texture), r, p as
//         updated; modes 1, 2: z, p.
// Writes: h, r, partials[SLOT_RMAX * MAX_PARTIALS + workgroup] (mode 0); p (modes 1, 2).
// Params: n = level-0 side, mode, partials = number of workgroups dispatched (<= MAX_PARTIALS).
// Workgroup: 256 (1D); each thread strides over the cells by partials * 256, the cells and order of
// dot_partial's threads, so the partials (and the max) are those dot_partial would compute.
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
@group(0) @binding(7) var<storage, read_write> partials: array<f32>;

fn p_get(i: u32, j: u32) -> f32 {
    return p[j * params.n + i];
}

const WG: u32 = 256u;
var<workgroup> sa: array<f32, 256>;

@compute @workgroup_size(256)
fn main(@builtin(local_invocation_index) lid: u32, @builtin(workgroup_id) wid: vec3<u32>) {
    let n = params.n;
    let cells = n * n;
    let stride = params.partials * WG;
    var idx = wid.x * WG + lid;
    if params.mode == 0u {
        let go = scalars.status == 0u;
        let alpha = scalars.alpha;
        var a = 0.0;
        for (; idx < cells; idx += stride) {
            var rv = r[idx];
            if go {
                let i = idx % n;
                let j = idx / n;
                h_put(i, j, h_get(i, j) + alpha * p[idx]);
                rv -= alpha * q_at(idx);
                r[idx] = rv;
            }
            a = max(a, abs(rv));
        }
        // The tree of dot_partial's STAGE_R (params.mode is uniform: the barriers are too).
        sa[lid] = a;
        for (var s = WG / 2u; s > 0u; s = s / 2u) {
            workgroupBarrier();
            if lid < s {
                sa[lid] = max(sa[lid], sa[lid + s]);
            }
        }
        if lid == 0u {
            partials[SLOT_RMAX * MAX_PARTIALS + wid.x] = sa[0];
        }
    } else if params.mode == 1u {
        let beta = scalars.beta;
        for (; idx < cells; idx += stride) {
            p[idx] = z[idx] + beta * p[idx];
        }
    } else {
        for (; idx < cells; idx += stride) {
            p[idx] = z[idx];
        }
    }
}
