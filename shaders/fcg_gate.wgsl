// Pass: fcg_gate: FCG's stop test on the GPU. Decides whether the next FCG stage runs and writes the
// indirect dispatch arguments of every pass in it: each size class its workgroups, or 0 x 0 x 0 so the
// stage's passes do nothing (a run of queued iterations stops where the CPU's loop would have).
// It runs when status == 0 (p.q > 0), rmax > stop_rmax and iterations_left > 0.
// mode 0: before FCG's first direction (counts nothing; a stop here leaves iterations_left at 0);
//         keeps rmax as rmax_start.
// mode 1: before an iteration; counts it (iterations += 1, iterations_left -= 1) when it runs.
// mode 2: before FCG's stop-test relaxation, after an iteration: runs it when status == 0 and
//         stop_rmax < rmax <= SPIKE_BAND stop_rmax, seeding its mask at stop_rmax (counts the run in
//         word SPIKE_WORDS + 12, clears its cell count); leaves the iteration counts alone.
// Reads:  sizes (3 words per class), scalars.
// Writes: args (3 words per class), scalars.iterations / iterations_left / rmax_start, spike.
// Params: n = number of size classes, mode.
// Workgroup: 64 (1D). Dispatch exactly one workgroup.
#import params
#import scalars

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> sizes: array<u32>;
@group(0) @binding(2) var<storage, read_write> scalars: Scalars;
@group(0) @binding(3) var<storage, read_write> args: array<u32>;

var<workgroup> go: u32;

@compute @workgroup_size(64)
fn main(@builtin(local_invocation_index) lid: u32) {
    if lid == 0u && params.mode == 2u {
        let run = scalars.status == 0u && scalars.rmax > scalars.stop_rmax
            && scalars.rmax <= SPIKE_BAND * scalars.stop_rmax;
        go = u32(run);
        if run {
            scalars.spike[8] = bitcast<u32>(scalars.stop_rmax);
            scalars.spike[9] = 0u;
            scalars.spike[12] += 1u;
        }
    } else if lid == 0u {
        if params.mode == 0u {
            scalars.rmax_start = scalars.rmax;
        }
        let run = scalars.status == 0u && scalars.rmax > scalars.stop_rmax
            && scalars.iterations_left > 0u;
        go = u32(run);
        if run && params.mode == 1u {
            scalars.iterations += 1u;
            scalars.iterations_left -= 1u;
        } else if !run {
            scalars.iterations_left = 0u;
        }
    }
    let run = workgroupUniformLoad(&go);
    for (var k = lid; k < 3u * params.n; k += 64u) {
        args[k] = select(0u, sizes[k], run == 1u);
    }
}
