// Shared include `#import h_read` for a solver whose solution h is mip 0 of its R32Float height
// texture: the variant of `h_buffer_read.wgsl`, at binding 1 as a sampled (unfilterable,
// `textureLoad` only) view of mip 0.

@group(0) @binding(1) var h_tex: texture_2d<f32>;

fn h_get(i: u32, j: u32) -> f32 {
    return textureLoad(h_tex, vec2<u32>(i, j), 0).x;
}
