//! The GPU backend (wgpu 30 compute shaders in `../shaders/*.wgsl`): the same algorithm as [`crate::cpu`],
//! `ALGORITHM.md` being the contract and the CPU backend the oracle.
//!
//! ## How it works
//! - [`GpuContext`] owns (or shares) a `wgpu::Device` and `Queue`; every public GPU call runs inside
//!   validation / out-of-memory error scopes, so a wgpu validation error is a [`GpuError`], never a silent
//!   pass.
//! - [`GpuFieldSolver`] is the GPU twin of [`crate::cpu::Hierarchy`] plus one [`crate::cpu::FieldState`]:
//!   all per-level buffers are allocated once, the level-0 operator and the Galerkin coarse operators are
//!   assembled on the GPU, and FMG / FCG run as recorded lists of passes ([`plan`]) that a thin executor
//!   encodes. FCG's scalars are computed on the GPU; the CPU reads 8 bytes per iteration for the stop test.
//!   FMG starts from the lift (`cpu/lift.rs`: push-pull extension of the constrained values, `lift_push` /
//!   `lift_pull`), whose coarse levels borrow level-0 `z` and FCG's `p` (dead during FMG; see
//!   `resources`). FCG stores no `q = A p`: the passes that read it recompute it from `p`.
//! - [`GpuMips`] turns the level-0 solution into an R32Float texture with a full mip chain (display
//!   downsample that keeps hard curves) and a small min/max pyramid; [`mips`] also holds the CPU oracle of
//!   both. A solver may keep its `h` in that texture's mip 0 ([`GpuFieldSolver::with_texture_h`], as
//!   `GpuSolver`'s heights do): then nothing is copied into mip 0.
//! - Every shader is one pass in one file; shared structs live in `shaders/shared/*.wgsl` and are pulled in
//!   with a one-line `#import name` ([`shaders::preprocess`]).

mod context;
mod error;
mod field;
pub(crate) mod kernels;
pub mod mips;
pub mod oracle;
pub mod params;
pub mod plan;
pub mod raster;
pub(crate) mod readback;
pub use raster::{GpuRaster, RasterMaps, RasterStats};
pub(crate) use readback::read_f32;
pub use readback::{TexelSet, read_texel_sets, read_texture_r32};
mod resources;
pub mod shaders;
mod slice;

pub use context::{
    ENCODE_US_PER_DISPATCH, GpuContext, GpuCounters, H100_CLASS_GPU, MID_RANGE_GPU, PassCounts,
    ReferenceGpu,
};
pub use error::GpuError;
pub(crate) use field::Queued;
pub use field::{FcgReport, GpuFieldSolver, QUEUED_REPORT_BYTES, QueuedReport};
pub use mips::GpuMips;
pub(crate) use resources::check_limits;
pub use resources::{MIN_GPU_SIDE, allocated_sizes, borrowed_level0, buffer_sizes, solve_levels};
pub(crate) use slice::Slice;
