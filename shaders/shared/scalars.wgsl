// Shared include `#import scalars`: the FCG scalar block and the reduction slots.
// Must be kept in sync with `Scalars` and `SLOT_*` / `STAGE_*` in multigrid/src/gpu/params.rs.
struct Scalars {
    // max |r| over level 0 (not normalised), written by the R stage.
    rmax: f32,
    // 1 when p.q <= 0 (FCG must stop), else 0; written by the PQ stage.
    status: u32,
    // r.z of the current iteration.
    rz: f32,
    // p.q of the current iteration.
    pq: f32,
    // z.q of the current iteration.
    zq: f32,
    // rz / pq.
    alpha: f32,
    // -zq / pq.
    beta: f32,
    // fcg_gate: FCG stops once rmax <= stop_rmax (the tolerance in units of rmax; written by the CPU).
    stop_rmax: f32,
    // Local relaxation (relax_mask.wgsl, relax_tiles.wgsl, which see this block as words):
    // the residual |r| above which a cell seeds a window (written by the CPU) ...
    relax_limit: f32,
    // ... and the cells of the windows (counted by relax_mask).
    relax_cells: u32,
    // fcg_gate: iterations run since the CPU wrote this block, and how many more may run.
    iterations: u32,
    iterations_left: u32,
    // fcg_gate: rmax when FCG's first gate ran (the residual after the local relaxation).
    rmax_start: f32,
    // Local relaxation (relax_mask mode 2): its passes' first 16 x 16 tile column and row
    // (`tx0 | ty0 << 16`) and workgroups.
    relax_origin: u32,
    relax_groups: u32,
    // The relief that normalises this block's residuals (written by the CPU, or by relief_scale
    // from the rasteriser's value range; 0: the CPU's own).
    relief: f32,
    // FCG's stop-test relaxation (words SPIKE_WORDS + k): k = 8, 9, 13, 14 as relax_limit,
    // relax_cells, relax_origin, relax_groups above for its own mask and tiles; k = 10, 11 the cells
    // and tile workgroups it relaxed, k = 12 the times fcg_gate let it run, since the CPU wrote
    // this block.
    spike: array<u32, 16>,
}

// First word of `Scalars.spike` (relax_mask.wgsl and relax_tiles.wgsl see the block as words).
const SPIKE_WORDS: u32 = 16u;
// The stop-test relaxation runs after an iteration that left stop_rmax < rmax <= SPIKE_BAND
// stop_rmax (keep in sync with `SPIKE_BAND` in multigrid/src/cycle.rs).
const SPIKE_BAND: f32 = 2.0;

// Reduction stages (`Params.mode` of dot_partial / dot_final).
const STAGE_PQ: u32 = 0u;
const STAGE_Z: u32 = 1u;
const STAGE_R: u32 = 2u;
// r.z alone, z.q partials written as 0 (FCG's first direction: p = z follows, z.q is unused).
const STAGE_RZ: u32 = 3u;
// dot_final after smooth_dot_level0: STAGE_Z's scalars, then p.q of p = z + beta p from the z.A z
// partials (slot SLOT_PQ), alpha and status.
const STAGE_ZPQ: u32 = 4u;

// Slots of the partials buffer: slot s holds partial s * MAX_PARTIALS + workgroup.
const SLOT_PQ: u32 = 0u;
const SLOT_ZQ: u32 = 1u;
const SLOT_RZ: u32 = 2u;
const SLOT_RMAX: u32 = 3u;
const MAX_PARTIALS: u32 = 1024u;
