//! The WGSL sources (embedded at compile time from `shaders/`), the `#import` include mechanism and each
//! kernel's binding layout.
//!
//! A line `#import name` is replaced by `shaders/shared/name.wgsl`, or, for a *slot* name ([`SLOTS`]),
//! by the file the kernel chooses for it ([`Kernel::imports`]): one pass file serves several kernels,
//! a base kernel and its variants ([`Kernel::base`]). `smooth_coarse.wgsl` is [`Kernel::SmoothCoarse`],
//! reading stored stencil records, and [`Kernel::SmoothLevel1`], computing level 1's stencils from the
//! level-0 diagonal (slot `coarse`); `fcg_update.wgsl` is [`Kernel::FcgUpdate`], updating `h` in a
//! buffer, and [`Kernel::FcgUpdateTextureH`], updating `h` in mip 0 of the height texture (slots `h`,
//! `h_read`). Each pass file declares binding 0 as `var<uniform> params: Params` and then its
//! resources in the order of [`Kernel::bindings`]; a slot file declares binding 1.

/// One compute pass: a `.wgsl` file ([`Kernel::file`]) with its slot imports ([`Kernel::imports`]),
/// entry point `main`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Kernel {
    /// Level-0 operator from the problem (edge differences uploaded, none, or computed from the
    /// level-1 gradient field).
    AssembleLevel0,
    /// [`Kernel::AssembleLevel0`] with `h` in the height texture.
    AssembleLevel0TextureH,
    /// Level 1's Galerkin stencils, computed from level 0 as the level-1 passes compute them, written
    /// out as 9 f32 per cell (tests: no plan runs it, nothing stores level 1).
    StencilsLevel1,
    /// Level-k Galerkin operator from the records of level k-1 (k >= 3).
    GalerkinCoarse,
    /// Level-2 Galerkin operator from level 1's stencils computed from the level-0 diagonal.
    GalerkinLevel2,
    /// One red-black colour on level 0.
    SmoothLevel0,
    /// The first red-black sweep on level 0 from zero, in 16 x 16 tiles, one dispatch.
    SmoothLevel0Tiles,
    /// The last red-black colour of the preconditioner on level 0 and the reduction's first pass
    /// after it.
    SmoothDotLevel0,
    /// One of four colours on a coarse level >= 2 (stencil records).
    SmoothCoarse,
    /// One of four colours on level 1 (stencils computed from the level-0 diagonal).
    SmoothLevel1,
    /// Up to 8 colour phases (one or two sweeps) on a coarse level >= 2 in 16 x 16 tiles, one
    /// dispatch.
    SmoothCoarseTiles,
    /// [`Kernel::SmoothCoarseTiles`] on level 1.
    SmoothLevel1Tiles,
    /// The windows of the local relaxation (seeds by residual, dilated in 16 x 16 tiles), counted.
    RelaxMask,
    /// Up to 5 red-black sweeps of the local relaxation of `h` in its windows, in 16 x 16 tiles.
    RelaxTiles,
    /// [`Kernel::RelaxTiles`] of `h` in the height texture.
    RelaxTilesTextureH,
    /// The update of FCG's stop-test relaxation: `h += d`, `r -= A d` over its tiles.
    SpikeUpdate,
    /// [`Kernel::SpikeUpdate`] of `h` in the height texture.
    SpikeUpdateTextureH,
    /// Level-0 residual restricted to level 1.
    ResidualRestrictLevel0,
    /// [`Kernel::ResidualRestrictLevel0`] of `h` in the height texture.
    ResidualRestrictLevel0TextureH,
    /// Coarse residual (level >= 2) restricted to the next level.
    ResidualRestrictCoarse,
    /// Level-1 residual restricted to level 2.
    ResidualRestrictLevel1,
    /// Level 1 interpolated onto level 0.
    ProlongLevel0,
    /// [`Kernel::ProlongLevel0`] onto `h` in the height texture.
    ProlongLevel0TextureH,
    /// Level k+1 interpolated onto level k >= 2.
    ProlongCoarse,
    /// Level 2 interpolated onto level 1.
    ProlongLevel1,
    /// Level k+1 interpolated onto level k >= 2 into another buffer (a tile sweep's input).
    ProlongCoarseAlt,
    /// [`Kernel::ProlongCoarseAlt`] onto level 1.
    ProlongLevel1Alt,
    /// Sum of 4 children.
    RestrictSum,
    /// Exact coarsest solve in one workgroup (coarsest level >= 2).
    CoarsestSolve,
    /// Every pass on the levels of side <= 64 (from level 2) in one workgroup, a program of steps.
    CoarseFused,
    /// Exact coarsest solve when the coarsest level is level 1 (16 x 16 solvers).
    CoarsestSolveLevel1,
    /// `rhs - A h` on level 0.
    ApplyLevel0,
    /// [`Kernel::ApplyLevel0`] of `h` in the height texture.
    ApplyLevel0TextureH,
    /// Reduction, first pass.
    DotPartial,
    /// Reduction, second pass and FCG scalars.
    DotFinal,
    /// FCG axpys.
    FcgUpdate,
    /// FCG's stop test on the GPU: the indirect arguments of the next stage's passes.
    FcgGate,
    /// [`Kernel::FcgUpdate`] with `h` in the height texture.
    FcgUpdateTextureH,
    /// One push step of the FMG lift.
    LiftPush,
    /// One pull step of the FMG lift.
    LiftPull,
    /// [`Kernel::LiftPull`] with `h` in the height texture.
    LiftPullTextureH,
    /// One mip level: its hard count / E-sum pyramid level and its display downsample.
    MipLevel,
    /// Up to four mip levels of side <= 32 in one workgroup.
    MipTail,
    /// Mip 0 from `h` (a solver whose `h` is a buffer).
    MipLevel0,
    /// Finest stored min/max level from level 0.
    MinmaxBase,
    /// [`Kernel::MinmaxBase`] from `h` in the height texture.
    MinmaxBaseTextureH,
    /// Next min/max level.
    MinmaxReduce,
    /// Level-0 elevation and band maps from stroke geometry, the level-1 gradient-field and level-2
    /// roughness problems, and their value ranges.
    Rasterize,
    /// A problem's relief from the rasteriser's value range, scaling its scalar block's limits.
    ReliefScale,
}

/// What a binding (after binding 0, the params uniform) is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Binding {
    /// `var<storage, read>`.
    Read,
    /// `var<storage, read_write>`.
    ReadWrite,
    /// `texture_2d<f32>` (unfilterable float, `textureLoad` only).
    Texture,
    /// `texture_storage_2d<r32float, write>`.
    StorageTextureR32Write,
    /// `texture_storage_2d<r32float, read_write>`.
    StorageTextureR32ReadWrite,
}

use Binding::{Read as R, ReadWrite as W};

/// How a variant differs from its base kernel ([`Kernel::base`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Variant {
    /// The base kernel itself.
    Base,
    /// Level 1's stencils computed from the level-0 diagonal at binding 1 (slot `coarse`).
    Level1,
    /// The level-0 solution `h` at binding 1 is mip 0 of the height texture (slots `h`, `h_read`):
    /// a sampled view where the base reads a buffer, a read-write storage view where it writes one.
    TextureH,
}

impl Kernel {
    /// Every kernel.
    pub const ALL: [Kernel; 49] = [
        Kernel::AssembleLevel0,
        Kernel::AssembleLevel0TextureH,
        Kernel::StencilsLevel1,
        Kernel::GalerkinCoarse,
        Kernel::GalerkinLevel2,
        Kernel::SmoothLevel0,
        Kernel::SmoothLevel0Tiles,
        Kernel::SmoothDotLevel0,
        Kernel::SmoothCoarse,
        Kernel::SmoothLevel1,
        Kernel::SmoothCoarseTiles,
        Kernel::SmoothLevel1Tiles,
        Kernel::RelaxMask,
        Kernel::RelaxTiles,
        Kernel::RelaxTilesTextureH,
        Kernel::SpikeUpdate,
        Kernel::SpikeUpdateTextureH,
        Kernel::ResidualRestrictLevel0,
        Kernel::ResidualRestrictLevel0TextureH,
        Kernel::ResidualRestrictCoarse,
        Kernel::ResidualRestrictLevel1,
        Kernel::ProlongLevel0,
        Kernel::ProlongLevel0TextureH,
        Kernel::ProlongCoarse,
        Kernel::ProlongLevel1,
        Kernel::ProlongCoarseAlt,
        Kernel::ProlongLevel1Alt,
        Kernel::RestrictSum,
        Kernel::CoarsestSolve,
        Kernel::CoarsestSolveLevel1,
        Kernel::CoarseFused,
        Kernel::ApplyLevel0,
        Kernel::ApplyLevel0TextureH,
        Kernel::DotPartial,
        Kernel::DotFinal,
        Kernel::FcgUpdate,
        Kernel::FcgUpdateTextureH,
        Kernel::FcgGate,
        Kernel::LiftPush,
        Kernel::LiftPull,
        Kernel::LiftPullTextureH,
        Kernel::MipLevel,
        Kernel::MipTail,
        Kernel::MipLevel0,
        Kernel::MinmaxBase,
        Kernel::MinmaxBaseTextureH,
        Kernel::MinmaxReduce,
        Kernel::Rasterize,
        Kernel::ReliefScale,
    ];

    /// The kernel whose file this one uses, and how it differs from it.
    pub fn base(self) -> (Kernel, Variant) {
        use Variant::{Level1, TextureH};
        match self {
            Kernel::AssembleLevel0TextureH => (Kernel::AssembleLevel0, TextureH),
            Kernel::StencilsLevel1 => (Kernel::StencilsLevel1, Level1),
            Kernel::GalerkinLevel2 => (Kernel::GalerkinCoarse, Level1),
            Kernel::SmoothLevel1 => (Kernel::SmoothCoarse, Level1),
            Kernel::SmoothLevel1Tiles => (Kernel::SmoothCoarseTiles, Level1),
            Kernel::ProlongLevel1Alt => (Kernel::ProlongCoarseAlt, Level1),
            Kernel::RelaxTilesTextureH => (Kernel::RelaxTiles, TextureH),
            Kernel::SpikeUpdateTextureH => (Kernel::SpikeUpdate, TextureH),
            Kernel::ResidualRestrictLevel0TextureH => (Kernel::ResidualRestrictLevel0, TextureH),
            Kernel::ResidualRestrictLevel1 => (Kernel::ResidualRestrictCoarse, Level1),
            Kernel::ProlongLevel0TextureH => (Kernel::ProlongLevel0, TextureH),
            Kernel::ProlongLevel1 => (Kernel::ProlongCoarse, Level1),
            Kernel::CoarsestSolveLevel1 => (Kernel::CoarsestSolve, Level1),
            Kernel::ApplyLevel0TextureH => (Kernel::ApplyLevel0, TextureH),
            Kernel::FcgUpdateTextureH => (Kernel::FcgUpdate, TextureH),
            Kernel::LiftPullTextureH => (Kernel::LiftPull, TextureH),
            Kernel::MinmaxBaseTextureH => (Kernel::MinmaxBase, TextureH),
            k => (k, Variant::Base),
        }
    }

    /// This kernel's variant with `h` in the height texture, if it has one (the kernels that bind
    /// the level-0 solution `h` at binding 1).
    pub fn with_texture_h(self) -> Option<Kernel> {
        Kernel::ALL
            .into_iter()
            .find(|k| k.base() == (self, Variant::TextureH))
    }

    /// Unique name (the pipeline label after `multigrid.`): the file stem, with the variant for
    /// the kernels that share a file with another.
    pub fn name(self) -> String {
        match self.base() {
            (_, Variant::Base) | (Kernel::StencilsLevel1, _) => self.file().to_string(),
            (_, Variant::Level1) => format!("{}.level1", self.file()),
            (_, Variant::TextureH) => format!("{}.texture_h", self.file()),
        }
    }

    /// File stem in `shaders/` (and the pass labels after `multigrid.`).
    pub fn file(self) -> &'static str {
        match self.base().0 {
            Kernel::AssembleLevel0 => "assemble_level0",
            Kernel::StencilsLevel1 => "stencils_level1",
            Kernel::GalerkinCoarse => "galerkin_coarse",
            Kernel::SmoothLevel0 => "smooth_level0",
            Kernel::SmoothLevel0Tiles => "smooth_level0_tiles",
            Kernel::SmoothDotLevel0 => "smooth_dot_level0",
            Kernel::SmoothCoarse => "smooth_coarse",
            Kernel::SmoothCoarseTiles => "smooth_coarse_tiles",
            Kernel::ProlongCoarseAlt => "prolong_coarse_alt",
            Kernel::RelaxMask => "relax_mask",
            Kernel::RelaxTiles => "relax_tiles",
            Kernel::SpikeUpdate => "spike_update",
            Kernel::ResidualRestrictLevel0 => "residual_restrict_level0",
            Kernel::ResidualRestrictCoarse => "residual_restrict_coarse",
            Kernel::ProlongLevel0 => "prolong_level0",
            Kernel::ProlongCoarse => "prolong_coarse",
            Kernel::RestrictSum => "restrict_sum",
            Kernel::CoarsestSolve => "coarsest_solve",
            Kernel::CoarseFused => "coarse_fused",
            Kernel::ApplyLevel0 => "apply_level0",
            Kernel::DotPartial => "dot_partial",
            Kernel::DotFinal => "dot_final",
            Kernel::FcgUpdate => "fcg_update",
            Kernel::FcgGate => "fcg_gate",
            Kernel::LiftPush => "lift_push",
            Kernel::LiftPull => "lift_pull",
            Kernel::MipLevel => "mip_level",
            Kernel::MipTail => "mip_tail",
            Kernel::MipLevel0 => "mip_level0",
            Kernel::MinmaxBase => "minmax_base",
            Kernel::MinmaxReduce => "minmax_reduce",
            Kernel::Rasterize => "rasterize",
            Kernel::ReliefScale => "relief_scale",
            // Variants are never their own base.
            _ => unreachable!("{self:?} is a variant"),
        }
    }

    /// The files this kernel puts in the [`SLOTS`] its file imports (the slots' defaults for the
    /// others).
    pub fn imports(self) -> &'static [(&'static str, &'static str)] {
        match self.base().1 {
            Variant::Base => &[],
            Variant::Level1 => &[("coarse", "coarse_level1")],
            Variant::TextureH => &[("h", "h_texture"), ("h_read", "h_texture_read")],
        }
    }

    /// The raw file contents (before `#import`).
    pub fn raw_source(self) -> &'static str {
        macro_rules! wgsl {
            ($name:literal) => {
                include_str!(concat!(
                    env!("CARGO_MANIFEST_DIR"),
                    "/../shaders/",
                    $name,
                    ".wgsl"
                ))
            };
        }
        match self.base().0 {
            Kernel::AssembleLevel0 => wgsl!("assemble_level0"),
            Kernel::StencilsLevel1 => wgsl!("stencils_level1"),
            Kernel::GalerkinCoarse => wgsl!("galerkin_coarse"),
            Kernel::SmoothLevel0 => wgsl!("smooth_level0"),
            Kernel::SmoothLevel0Tiles => wgsl!("smooth_level0_tiles"),
            Kernel::SmoothDotLevel0 => wgsl!("smooth_dot_level0"),
            Kernel::SmoothCoarse => wgsl!("smooth_coarse"),
            Kernel::SmoothCoarseTiles => wgsl!("smooth_coarse_tiles"),
            Kernel::ProlongCoarseAlt => wgsl!("prolong_coarse_alt"),
            Kernel::RelaxMask => wgsl!("relax_mask"),
            Kernel::RelaxTiles => wgsl!("relax_tiles"),
            Kernel::SpikeUpdate => wgsl!("spike_update"),
            Kernel::ResidualRestrictLevel0 => wgsl!("residual_restrict_level0"),
            Kernel::ResidualRestrictCoarse => wgsl!("residual_restrict_coarse"),
            Kernel::ProlongLevel0 => wgsl!("prolong_level0"),
            Kernel::ProlongCoarse => wgsl!("prolong_coarse"),
            Kernel::RestrictSum => wgsl!("restrict_sum"),
            Kernel::CoarsestSolve => wgsl!("coarsest_solve"),
            Kernel::CoarseFused => wgsl!("coarse_fused"),
            Kernel::ApplyLevel0 => wgsl!("apply_level0"),
            Kernel::DotPartial => wgsl!("dot_partial"),
            Kernel::DotFinal => wgsl!("dot_final"),
            Kernel::FcgUpdate => wgsl!("fcg_update"),
            Kernel::FcgGate => wgsl!("fcg_gate"),
            Kernel::LiftPush => wgsl!("lift_push"),
            Kernel::LiftPull => wgsl!("lift_pull"),
            Kernel::MipLevel => wgsl!("mip_level"),
            Kernel::MipTail => wgsl!("mip_tail"),
            Kernel::MipLevel0 => wgsl!("mip_level0"),
            Kernel::MinmaxBase => wgsl!("minmax_base"),
            Kernel::MinmaxReduce => wgsl!("minmax_reduce"),
            Kernel::Rasterize => wgsl!("rasterize"),
            Kernel::ReliefScale => wgsl!("relief_scale"),
            _ => unreachable!("{self:?} is a variant"),
        }
    }

    /// The source with its imports resolved (slots as [`Self::imports`] says).
    pub fn source(self) -> String {
        preprocess_with(self.raw_source(), self.imports())
            .unwrap_or_else(|e| panic!("{}.wgsl ({}): {e}", self.file(), self.name()))
    }

    /// Bindings 1.. of the kernel, in order (binding 0 is always the `Params` uniform). Must match the
    /// declarations in the `.wgsl` file (a mismatch is a validation error caught by every GPU test).
    /// A [`Variant::TextureH`] kernel binds the height texture's mip 0 where its base binds `h`
    /// (binding 1): sampled where the base reads, read-write storage where it writes.
    pub fn bindings(self) -> Vec<Binding> {
        let (base, variant) = self.base();
        let mut b = base.base_bindings().to_vec();
        if variant == Variant::TextureH {
            b[0] = match b[0] {
                W => Binding::StorageTextureR32ReadWrite,
                _ => Binding::Texture,
            };
        }
        b
    }

    /// [`Self::bindings`] of a base kernel.
    fn base_bindings(self) -> &'static [Binding] {
        match self {
            // Binding 1 is `h`'s (the `h` / `h_read` slots) where a kernel binds the level-0
            // solution, `coarse`'s (stencil records, or, for level 1, the level-0 diagonal) in
            // the coarse kernels.
            Kernel::AssembleLevel0 => &[W, R, R, R, R, R, W, W],
            Kernel::StencilsLevel1 | Kernel::GalerkinCoarse => &[R, W],
            // `x`, `rhs`, `diag`, `u1` (the prolongation's level-1 input, mode 1).
            Kernel::SmoothLevel0 => &[W, R, R, R],
            // `x`, `rhs`, `diag`, `out` (level 1, mode 1).
            Kernel::SmoothLevel0Tiles => &[W, R, R, W],
            // `r`, `z`, `p`, `diag`, the partials.
            Kernel::SmoothDotLevel0 => &[R, W, R, R, W],
            Kernel::SmoothCoarse => &[R, W, R],
            // The stencils, `src`, `f`, `u`, `out` (the next level's `f`).
            Kernel::SmoothCoarseTiles => &[R, R, R, W, W],
            // The stencils, `u`, `uc`, `alt`.
            Kernel::ProlongCoarseAlt => &[R, R, R, W],
            // `r`, `z` (the mask), the scalar words, the box.
            Kernel::RelaxMask => &[R, W, W, W],
            // `h`, `f`, `diag`, the mask, the scalar words, `z`.
            Kernel::RelaxTiles => &[W, R, R, R, R, W],
            // `h`, `r`, `p` (read only; see the shader), the mask, `diag`, the scalar words.
            Kernel::SpikeUpdate => &[W, W, W, R, R, R],
            Kernel::ResidualRestrictLevel0 => &[R, R, R, W],
            Kernel::ResidualRestrictCoarse => &[R, R, R, W],
            Kernel::ProlongLevel0 => &[W, R, R],
            Kernel::ProlongCoarse => &[R, W, R],
            Kernel::RestrictSum => &[R, W],
            Kernel::CoarsestSolve => &[R, R, W],
            // Program, the stencil records of four levels, `u`, `f`.
            Kernel::CoarseFused => &[R, R, R, R, R, W, W],
            Kernel::ApplyLevel0 => &[R, R, R, W],
            Kernel::DotPartial => &[R, R, R, R, W],
            Kernel::DotFinal => &[R, W],
            Kernel::FcgUpdate => &[W, R, W, R, W, R, W],
            Kernel::FcgGate => &[R, W, W],
            Kernel::LiftPush => &[R, R, W, W],
            Kernel::LiftPull => &[W, R, R, R, W],
            // `src` (mip k-1), `dst` (mip k), the level-0 diagonal, the constraint pyramid.
            Kernel::MipLevel => &[Binding::Texture, Binding::StorageTextureR32Write, R, W],
            // `src`, four destination mips, the level-0 diagonal, the constraint pyramid.
            Kernel::MipTail => &[
                Binding::Texture,
                Binding::StorageTextureR32Write,
                Binding::StorageTextureR32Write,
                Binding::StorageTextureR32Write,
                Binding::StorageTextureR32Write,
                R,
                W,
            ],
            Kernel::MipLevel0 => &[R, Binding::StorageTextureR32Write],
            Kernel::MinmaxBase => &[R, W],
            Kernel::MinmaxReduce => &[W],
            // `geom`, `ew`, `ev`, `band`, the gradient problem, `vy`, the roughness problem, the
            // value ranges.
            Kernel::Rasterize => &[R, W, W, W, W, W, W, W],
            Kernel::ReliefScale => &[R, W],
            // `bindings` asks base kernels only.
            _ => unreachable!("{self:?} is a variant"),
        }
    }
}

/// Slot imports and their default files ([`Kernel::imports`] puts others there): `#import coarse` is
/// `coarse_records` (stencil records at binding 1) or `coarse_level1`; `#import h` / `#import
/// h_read` are `h_buffer` / `h_buffer_read` (the level-0 vector at binding 1 in a storage buffer) or
/// `h_texture` / `h_texture_read` (mip 0 of the height texture).
pub const SLOTS: [(&str, &str); 3] = [
    ("coarse", "coarse_records"),
    ("h", "h_buffer"),
    ("h_read", "h_buffer_read"),
];

/// The shared include files: `#import name` -> `shaders/shared/name.wgsl`.
pub const SHARED: [(&str, &str); 15] = [
    (
        "params",
        include_str!(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../shaders/shared/params.wgsl"
        )),
    ),
    (
        "scalars",
        include_str!(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../shaders/shared/scalars.wgsl"
        )),
    ),
    (
        "prolong",
        include_str!(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../shaders/shared/prolong.wgsl"
        )),
    ),
    (
        "transfer",
        include_str!(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../shaders/shared/transfer.wgsl"
        )),
    ),
    (
        "lift",
        include_str!(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../shaders/shared/lift.wgsl"
        )),
    ),
    (
        "apply_p",
        include_str!(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../shaders/shared/apply_p.wgsl"
        )),
    ),
    (
        "stencil",
        include_str!(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../shaders/shared/stencil.wgsl"
        )),
    ),
    (
        "downsample",
        include_str!(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../shaders/shared/downsample.wgsl"
        )),
    ),
    (
        "mip_cell",
        include_str!(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../shaders/shared/mip_cell.wgsl"
        )),
    ),
    (
        "h_buffer",
        include_str!(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../shaders/shared/h_buffer.wgsl"
        )),
    ),
    (
        "h_buffer_read",
        include_str!(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../shaders/shared/h_buffer_read.wgsl"
        )),
    ),
    (
        "h_texture",
        include_str!(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../shaders/shared/h_texture.wgsl"
        )),
    ),
    (
        "h_texture_read",
        include_str!(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../shaders/shared/h_texture_read.wgsl"
        )),
    ),
    (
        "coarse_records",
        include_str!(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../shaders/shared/coarse_records.wgsl"
        )),
    ),
    (
        "coarse_level1",
        include_str!(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../shaders/shared/coarse_level1.wgsl"
        )),
    ),
];

/// Resolves `#import name` lines with the slots' default files ([`SLOTS`]).
pub fn preprocess(source: &str) -> Result<String, String> {
    preprocess_with(source, &[])
}

/// Resolves `#import name` lines (one level deep: shared files import nothing), a slot name to the
/// file `slots` gives for it, else to its default. Unknown names and repeated imports are errors.
pub fn preprocess_with(source: &str, slots: &[(&str, &str)]) -> Result<String, String> {
    let mut out = String::with_capacity(source.len() + 2048);
    let mut seen: Vec<&str> = Vec::new();
    for (line_no, line) in source.lines().enumerate() {
        if let Some(rest) = line.trim_start().strip_prefix("#import") {
            let name = rest.trim();
            let file = slots
                .iter()
                .chain(SLOTS.iter())
                .find(|(slot, _)| *slot == name)
                .map_or(name, |(_, file)| *file);
            let Some((_, text)) = SHARED.iter().find(|(n, _)| *n == file) else {
                return Err(format!("line {}: unknown import `{name}`", line_no + 1));
            };
            if seen.contains(&name) {
                return Err(format!("line {}: `{name}` imported twice", line_no + 1));
            }
            seen.push(name);
            out.push_str(text);
        } else {
            out.push_str(line);
        }
        out.push('\n');
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn preprocess_resolves_and_rejects() {
        let s = preprocess("#import params\nfn f() {}\n").unwrap();
        assert!(s.contains("struct Params"));
        assert!(preprocess("#import nope\n").is_err());
        assert!(preprocess("#import params\n#import params\n").is_err());
    }

    #[test]
    fn kernel_names_are_unique() {
        let mut names: Vec<_> = Kernel::ALL.iter().map(|k| k.name()).collect();
        names.sort();
        names.dedup();
        assert_eq!(names.len(), Kernel::ALL.len());
    }

    /// A slot resolves to the kernel's file, else to its default; the level-1 variants read the
    /// level-0 diagonal at binding 1 instead of stencil records.
    #[test]
    fn slots_choose_the_coarse_stencils() {
        let rec = preprocess("#import coarse\n").unwrap();
        assert!(rec.contains("var<storage, read> stencil: array<u32>"));
        let l1 = preprocess_with("#import coarse\n", &[("coarse", "coarse_level1")]).unwrap();
        assert!(l1.contains("var<storage, read> diag0: array<f32>"));
        for k in Kernel::ALL {
            let level1 = k.imports().contains(&("coarse", "coarse_level1"));
            let src = k.source();
            assert_eq!(src.contains("diag0"), level1, "{}", k.name());
            if src.contains("fn st_get") && !level1 {
                assert!(src.contains("stencil: array<u32>"), "{}", k.name());
            }
        }
        assert!(preprocess_with("#import coarse\n", &[("coarse", "nope")]).is_err());
    }
}
