// Shared include `#import h` (the default; `h_texture.wgsl` is the variant, with the same functions):
// the level-0 vector a pass updates, at binding 1, as a storage buffer `h` (row-major, side params.n).
// Bound to the solution h, or, in the preconditioner's passes, to z.

@group(0) @binding(1) var<storage, read_write> h: array<f32>;

fn h_get(i: u32, j: u32) -> f32 {
    return h[j * params.n + i];
}

fn h_put(i: u32, j: u32, v: f32) {
    h[j * params.n + i] = v;
}
