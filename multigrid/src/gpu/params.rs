//! Host mirrors of the shader structs in `shaders/shared/*.wgsl` (`#[repr(C)]`, Pod, explicit padding,
//! same field names, size checked at compile time).

use bytemuck::{Pod, Zeroable};

/// Per-pass parameters. Must be kept in sync with `struct Params` in `shaders/shared/params.wgsl`.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Default, Pod, Zeroable)]
pub struct Params {
    /// Side of the level the pass works on (each shader's header says which).
    pub n: u32,
    /// Smoothing colour: `(i + j) & 1` on level 0, `(I & 1) + 2 (J & 1)` on coarse levels.
    pub colour: u32,
    /// Kernel-specific switch (set / add, residual / product, reduction stage, ...).
    pub mode: u32,
    /// Number of workgroup partials of a reduction.
    pub partials: u32,
    /// East/west edge weight `dy / dx`.
    pub ax: f32,
    /// North/south edge weight `dx / dy`.
    pub ay: f32,
    /// Inactive threshold of Galerkin centre coefficients.
    pub threshold: f32,
    /// Element offset of the source level in a pyramid buffer.
    pub src_offset: u32,
    /// Element offset of the destination level in a pyramid buffer.
    pub dst_offset: u32,
    /// `downsample_fields`: first word of the pass's value-range slot in the stats buffer;
    /// `assemble_level0`: 1 for a cold start (`h = 0` on free cells).
    pub slot_or_cold: u32,
    /// `relax_mask`: Chebyshev radius of the local relaxation's windows.
    pub radius: u32,
    /// Cell width `dx` in metres (edge differences computed in `assemble_level0`).
    pub dx: f32,
    /// Cell height `dy` in metres.
    pub dy: f32,
    /// `downsample_fields`: 1 writes only the values (the gradient's y pass).
    pub values_only: u32,
    /// Padding.
    pub pad3: u32,
    /// Padding.
    pub pad4: u32,
}
const _: () = assert!(std::mem::size_of::<Params>() == 64);

/// FCG scalars, computed on the GPU. Must be kept in sync with `struct Scalars` in
/// `shaders/shared/scalars.wgsl`. `rmax` and `status` come first: they are the 8 bytes read per iteration.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Default, Pod, Zeroable)]
pub struct Scalars {
    /// `max |r|` (not normalised).
    pub rmax: f32,
    /// 1 when `p.q <= 0` (FCG stops), else 0.
    pub status: u32,
    /// `r.z`.
    pub rz: f32,
    /// `p.q`.
    pub pq: f32,
    /// `z.q`.
    pub zq: f32,
    /// `rz / pq`.
    pub alpha: f32,
    /// `-zq / pq`.
    pub beta: f32,
    /// FCG stops once `rmax <= stop_rmax` (the tolerance in units of `rmax`; `fcg_gate.wgsl`).
    pub stop_rmax: f32,
    /// Local relaxation: the residual `|r|` (not normalised) above which a cell seeds a window
    /// (word 8: `shaders/relax_mask.wgsl` reads the block as words).
    pub relax_limit: f32,
    /// Local relaxation: the cells of the windows, counted by `relax_mask` (word 9).
    pub relax_cells: u32,
    /// FCG iterations the gate let run since the CPU wrote this block (`fcg_gate.wgsl`).
    pub iterations: u32,
    /// FCG iterations the gate may still let run.
    pub iterations_left: u32,
    /// `rmax` when FCG's first gate ran (the residual after the local relaxation).
    pub rmax_start: f32,
    /// Local relaxation: its passes' first 16 x 16 tile column and row, `tx0 | ty0 << 16` (word
    /// 13, written by `relax_mask` mode 2).
    pub relax_origin: u32,
    /// Local relaxation: the workgroups of each of its passes (word 14), for their bytes.
    pub relax_groups: u32,
    /// The relief normalising this block's residuals (word 15): written by the CPU with the limits,
    /// or by `relief_scale` from the rasteriser's value range; 0 when neither did.
    pub relief: f32,
    /// FCG's stop-test relaxation (words [`SPIKE_WORDS`] + k): k = 8, 9, 13, 14 as
    /// `relax_limit`, `relax_cells`, `relax_origin`, `relax_groups` for its own mask and tiles;
    /// k = [`SPIKE_CELLS`], [`SPIKE_GROUPS`] the cells and tile workgroups it relaxed and
    /// k = [`SPIKE_RUNS`] the times `fcg_gate` let it run since the CPU wrote this block.
    pub spike: [u32; 16],
}
const _: () = assert!(std::mem::size_of::<Scalars>() == 128);

/// First word of [`Scalars::spike`] (keep in sync with `SPIKE_WORDS` in `shared/scalars.wgsl`).
pub const SPIKE_WORDS: usize = 16;
/// Word of [`Scalars::spike`]: cells the stop-test relaxation relaxed (sum over its runs).
pub const SPIKE_CELLS: usize = 10;
/// Word of [`Scalars::spike`]: tile workgroups of its relaxation passes (sum over its runs).
pub const SPIKE_GROUPS: usize = 11;
/// Word of [`Scalars::spike`]: the times it ran.
pub const SPIKE_RUNS: usize = 12;
/// Byte offset of [`Scalars::relax_cells`] (word 9).
pub const RELAX_CELLS_OFFSET: u64 = 36;
const _: () = assert!(std::mem::offset_of!(Scalars, relax_cells) == RELAX_CELLS_OFFSET as usize);

/// Byte offset of [`Scalars::relax_groups`] (word 14).
pub const RELAX_GROUPS_OFFSET: u64 = 56;
const _: () = assert!(std::mem::offset_of!(Scalars, relax_groups) == RELAX_GROUPS_OFFSET as usize);

/// Bytes of [`Scalars`] read back per FCG iteration (`rmax`, `status`).
pub const STATUS_BYTES: u64 = 8;
/// Byte offset of [`Scalars::iterations`] (word 10).
pub const ITERATIONS_OFFSET: u64 = 40;
const _: () = assert!(std::mem::offset_of!(Scalars, iterations) == ITERATIONS_OFFSET as usize);

/// Reduction stage `p.q` (keep in sync with `STAGE_PQ` in `shaders/shared/scalars.wgsl`).
pub const STAGE_PQ: u32 = 0;
/// Reduction stage `z.q`, `r.z` (keep in sync with `STAGE_Z`).
pub const STAGE_Z: u32 = 1;
/// Reduction stage `max |r|` (keep in sync with `STAGE_R`).
pub const STAGE_R: u32 = 2;
/// Reduction stage `r.z` alone, with zeros for `z.q` (FCG's first direction, where `p = z` follows
/// and `z.q` is unused; keep in sync with `STAGE_RZ`).
pub const STAGE_RZ: u32 = 3;
/// `dot_final` stage after `smooth_dot_level0`: [`STAGE_Z`]'s scalars, then the new direction's
/// `p.q` from its `z.A z` partials (slot `p.q`) and `alpha`, `status` as [`STAGE_PQ`] sets them
/// (keep in sync with `STAGE_ZPQ`).
pub const STAGE_ZPQ: u32 = 4;
/// Slots of the partials buffer (keep in sync with `SLOT_*`).
pub const PARTIAL_SLOTS: u64 = 4;
/// Most workgroups of a reduction (keep in sync with `MAX_PARTIALS`).
pub const MAX_PARTIALS: u32 = 1024;
/// Threads per reduction workgroup (keep in sync with `WG` in `dot_partial.wgsl` / `dot_final.wgsl`).
pub const REDUCTION_WORKGROUP: u32 = 256;
/// Side of a 2D workgroup (8 x 8) of the per-cell passes.
pub const TILE: u32 = 8;
/// Side of the `minmax_base` workgroup (16 x 16).
pub const MINMAX_TILE: u32 = 16;

/// Relative threshold under which a coarse centre coefficient marks its cell inactive.
/// Keep in sync with `INACTIVE_REL` in `cpu/coarse.rs` (the CPU uses exactly this value).
pub const INACTIVE_REL: f32 = 1e-6;

/// Words (u32) per cell of a coarse level's Galerkin operator: the record of
/// `shaders/shared/stencil.wgsl` (the 8 off-centre coefficients as 16-bit snorm over the cell's
/// scale, the row sum and the scale as f32).
pub const STENCIL_WORDS: usize = 6;

/// Byte size of one cell's stencil record.
pub const STENCIL_BYTES: u64 = 4 * STENCIL_WORDS as u64;
