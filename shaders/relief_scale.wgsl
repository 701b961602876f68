// Pass: relief_scale: a problem's relief from the rasteriser's value range, on the GPU, so no read
// waits for it. The relief is `max - min` of the range (at least 1; 1 when the range is empty), as
// `FieldProblem::relief`. The scalar block's `relax_limit` and `stop_rmax`, written by the CPU as
// normalised residuals, become residuals in units of `rmax`: times `(2 ax + 2 ay) relief`, the inverse
// of the normalisation the CPU applies to what it reads back. The relief itself goes into the block,
// so every copy of it (a report) carries its own normalisation.
// Reads:  stats[slot_or_cold], stats[slot_or_cold + 1] (order-preserving keys of min and max, as
//         `downsample_fields` writes them; min = 0xffffffff: no weighted cell).
// Writes: scalars.relief, scalars.relax_limit, scalars.stop_rmax.
// Params: ax, ay = the solver's axis weights; slot_or_cold = the range's first stats word.
// Workgroup: 1. Dispatch exactly one workgroup.
#import params
#import scalars

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> stats: array<u32>;
@group(0) @binding(2) var<storage, read_write> scalars: Scalars;

fn from_key(k: u32) -> f32 {
    if (k & 0x80000000u) != 0u {
        return bitcast<f32>(k & 0x7fffffffu);
    }
    return bitcast<f32>(~k);
}

@compute @workgroup_size(1)
fn main() {
    let lo_key = stats[params.slot_or_cold];
    var relief = 1.0;
    if lo_key != 0xffffffffu {
        let lo = from_key(lo_key);
        let hi = from_key(stats[params.slot_or_cold + 1u]);
        if hi > lo {
            relief = max(hi - lo, 1.0);
        }
    }
    let norm = (2.0 * params.ax + 2.0 * params.ay) * relief;
    scalars.relief = relief;
    scalars.relax_limit = scalars.relax_limit * norm;
    scalars.stop_rmax = scalars.stop_rmax * norm;
}
