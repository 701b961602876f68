// Shared include `#import h` for a solver whose solution h is mip 0 of its R32Float height texture
// (`GpuSolver`'s heights: the displayed mip 0 is h itself, no copy): the variant of `h_buffer.wgsl`,
// with the same functions, at binding 1 as a read-write storage texture (texel (i, j) = cell (i, j)).

@group(0) @binding(1) var h_tex: texture_storage_2d<r32float, read_write>;

fn h_get(i: u32, j: u32) -> f32 {
    return textureLoad(h_tex, vec2<u32>(i, j)).x;
}

fn h_put(i: u32, j: u32, v: f32) {
    textureStore(h_tex, vec2<u32>(i, j), vec4<f32>(v, 0.0, 0.0, 1.0));
}
