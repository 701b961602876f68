// Shared include `#import h_read` (the default; `h_texture_read.wgsl` is the variant): the level-0
// vector a pass only reads, at binding 1, as a read-only storage buffer `h` (row-major, side
// params.n). Bound to the solution h, or, in the preconditioner's passes, to z.

@group(0) @binding(1) var<storage, read> h: array<f32>;

fn h_get(i: u32, j: u32) -> f32 {
    return h[j * params.n + i];
}
