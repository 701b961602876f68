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
    // downsample_fields: first word of the pass's value-range slot; assemble_level0: 1 = cold start.
    slot_or_cold: u32,
    // relax_mask: Chebyshev radius of the local relaxation's windows.
    radius: u32,
    // Cell width dx and height dy in metres (edge differences computed in assemble_level0).
    dx: f32,
    dy: f32,
    // downsample_fields: 1 writes only the values (the gradient's y pass).
    values_only: u32,
    pad3: u32,
    pad4: u32,
}
