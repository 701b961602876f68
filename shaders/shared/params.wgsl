// Shared include `#import params`: the per-pass parameter block of every multigrid pass.
// Must be kept in sync with `Params` in multigrid/src/gpu/params.rs (same fields, same order, 64 bytes).
// Each pass says in its header what `n`, `colour`, `mode`, ... mean for it.
struct Params {
    // Side of the level the pass works on (each shader says which one).
    n: u32,
    // Smoothing colour: (i + j) & 1 on level 0, (I & 1) + 2 (J & 1) on coarse levels.
    colour: u32,
    // Kernel-specific switch (set vs add, residual vs product, reduction stage, ...).
    mode: u32,
    // Number of workgroup partial sums of a reduction.
    partials: u32,
    // East/west edge weight dy / dx.
    ax: f32,
    // North/south edge weight dx / dy.
    ay: f32,
    // Inactive threshold of the Galerkin centre coefficient: 1e-6 (2 ax + 2 ay).
    threshold: f32,
    // Element offset of the source level in a pyramid buffer.
    src_offset: u32,
    // Element offset of the destination level in a pyramid buffer.
    dst_offset: u32,
    // Kernel-specific word (stats slot of downsample_fields, cold flag of assemble_level0).
    pad0: u32,
    pad1: u32,
    // Cell width dx and height dy in metres (edge differences computed in assemble_level0).
    dx: f32,
    dy: f32,
    // Kernel-specific word (values-only flag of downsample_fields).
    pad2: u32,
    pad3: u32,
    pad4: u32,
}
