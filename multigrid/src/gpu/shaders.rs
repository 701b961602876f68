//! The WGSL sources (embedded at compile time from `shaders/`), the `#import` include mechanism and each
//! kernel's binding layout.
//!
//! A line `#import name` is replaced by `shaders/shared/name.wgsl`. Each pass file declares binding 0 as
//! `var<uniform> params: Params` and then its resources in the order of [`Kernel::bindings`].

/// One compute pass = one `.wgsl` file named after it, entry point `main`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Kernel {
    /// Level-0 operator from the problem (edge differences uploaded, none, or computed from the
    /// level-1 gradient field).
    AssembleLevel0,
    /// Level-1 Galerkin operator from level 0.
    GalerkinLevel0,
    /// Level-k Galerkin operator from level k-1 (k >= 2).
    GalerkinCoarse,
    /// One red-black colour on level 0.
    SmoothLevel0,
    /// One of four colours on a coarse level.
    SmoothCoarse,
    /// Level-0 residual restricted to level 1.
    ResidualRestrictLevel0,
    /// Coarse residual restricted to the next level.
    ResidualRestrictCoarse,
    /// Level 1 interpolated onto level 0.
    ProlongLevel0,
    /// Level k+1 interpolated onto level k.
    ProlongCoarse,
    /// Sum of 4 children.
    RestrictSum,
    /// Exact coarsest solve in one workgroup.
    CoarsestSolve,
    /// `A x` or `rhs - A x` on level 0.
    ApplyLevel0,
    /// Reduction, first pass.
    DotPartial,
    /// Reduction, second pass and FCG scalars.
    DotFinal,
    /// FCG axpys.
    FcgUpdate,
    /// One push step of the FMG lift.
    LiftPush,
    /// One pull step of the FMG lift.
    LiftPull,
    /// Hard count / E-sum pyramid of the mip chain.
    MipConstraints,
    /// Mip 0 from `h`.
    MipLevel0,
    /// Display downsample of one mip.
    MipDownsample,
    /// Finest stored min/max level from level 0.
    MinmaxBase,
    /// Next min/max level.
    MinmaxReduce,
    /// Level-0 constraint maps from stroke geometry.
    Rasterize,
    /// Gradient-field / roughness problems from the level-0 maps.
    DownsampleFields,
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
}

use Binding::{Read as R, ReadWrite as W};

impl Kernel {
    /// Every kernel.
    pub const ALL: [Kernel; 24] = [
        Kernel::AssembleLevel0,
        Kernel::GalerkinLevel0,
        Kernel::GalerkinCoarse,
        Kernel::SmoothLevel0,
        Kernel::SmoothCoarse,
        Kernel::ResidualRestrictLevel0,
        Kernel::ResidualRestrictCoarse,
        Kernel::ProlongLevel0,
        Kernel::ProlongCoarse,
        Kernel::RestrictSum,
        Kernel::CoarsestSolve,
        Kernel::ApplyLevel0,
        Kernel::DotPartial,
        Kernel::DotFinal,
        Kernel::FcgUpdate,
        Kernel::LiftPush,
        Kernel::LiftPull,
        Kernel::MipConstraints,
        Kernel::MipLevel0,
        Kernel::MipDownsample,
        Kernel::MinmaxBase,
        Kernel::MinmaxReduce,
        Kernel::Rasterize,
        Kernel::DownsampleFields,
    ];

    /// File stem in `shaders/` (and the pipeline label after `multigrid.`).
    pub fn name(self) -> &'static str {
        match self {
            Kernel::AssembleLevel0 => "assemble_level0",
            Kernel::GalerkinLevel0 => "galerkin_level0",
            Kernel::GalerkinCoarse => "galerkin_coarse",
            Kernel::SmoothLevel0 => "smooth_level0",
            Kernel::SmoothCoarse => "smooth_coarse",
            Kernel::ResidualRestrictLevel0 => "residual_restrict_level0",
            Kernel::ResidualRestrictCoarse => "residual_restrict_coarse",
            Kernel::ProlongLevel0 => "prolong_level0",
            Kernel::ProlongCoarse => "prolong_coarse",
            Kernel::RestrictSum => "restrict_sum",
            Kernel::CoarsestSolve => "coarsest_solve",
            Kernel::ApplyLevel0 => "apply_level0",
            Kernel::DotPartial => "dot_partial",
            Kernel::DotFinal => "dot_final",
            Kernel::FcgUpdate => "fcg_update",
            Kernel::LiftPush => "lift_push",
            Kernel::LiftPull => "lift_pull",
            Kernel::MipConstraints => "mip_constraints",
            Kernel::MipLevel0 => "mip_level0",
            Kernel::MipDownsample => "mip_downsample",
            Kernel::MinmaxBase => "minmax_base",
            Kernel::MinmaxReduce => "minmax_reduce",
            Kernel::Rasterize => "rasterize",
            Kernel::DownsampleFields => "downsample_fields",
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
        match self {
            Kernel::AssembleLevel0 => wgsl!("assemble_level0"),
            Kernel::GalerkinLevel0 => wgsl!("galerkin_level0"),
            Kernel::GalerkinCoarse => wgsl!("galerkin_coarse"),
            Kernel::SmoothLevel0 => wgsl!("smooth_level0"),
            Kernel::SmoothCoarse => wgsl!("smooth_coarse"),
            Kernel::ResidualRestrictLevel0 => wgsl!("residual_restrict_level0"),
            Kernel::ResidualRestrictCoarse => wgsl!("residual_restrict_coarse"),
            Kernel::ProlongLevel0 => wgsl!("prolong_level0"),
            Kernel::ProlongCoarse => wgsl!("prolong_coarse"),
            Kernel::RestrictSum => wgsl!("restrict_sum"),
            Kernel::CoarsestSolve => wgsl!("coarsest_solve"),
            Kernel::ApplyLevel0 => wgsl!("apply_level0"),
            Kernel::DotPartial => wgsl!("dot_partial"),
            Kernel::DotFinal => wgsl!("dot_final"),
            Kernel::FcgUpdate => wgsl!("fcg_update"),
            Kernel::LiftPush => wgsl!("lift_push"),
            Kernel::LiftPull => wgsl!("lift_pull"),
            Kernel::MipConstraints => wgsl!("mip_constraints"),
            Kernel::MipLevel0 => wgsl!("mip_level0"),
            Kernel::MipDownsample => wgsl!("mip_downsample"),
            Kernel::MinmaxBase => wgsl!("minmax_base"),
            Kernel::MinmaxReduce => wgsl!("minmax_reduce"),
            Kernel::Rasterize => wgsl!("rasterize"),
            Kernel::DownsampleFields => wgsl!("downsample_fields"),
        }
    }

    /// The source with its imports resolved.
    pub fn source(self) -> String {
        preprocess(self.raw_source()).unwrap_or_else(|e| panic!("{}.wgsl: {e}", self.name()))
    }

    /// Bindings 1.. of the kernel, in order (binding 0 is always the `Params` uniform). Must match the
    /// declarations in the `.wgsl` file (a mismatch is a validation error caught by every GPU test).
    pub fn bindings(self) -> &'static [Binding] {
        match self {
            Kernel::AssembleLevel0 => &[R, R, R, R, R, W, W, W],
            Kernel::GalerkinLevel0 | Kernel::GalerkinCoarse => &[R, W],
            Kernel::SmoothLevel0 => &[W, R, R],
            Kernel::SmoothCoarse => &[R, W, R],
            Kernel::ResidualRestrictLevel0 => &[R, R, R, W],
            Kernel::ResidualRestrictCoarse => &[R, R, R, W],
            Kernel::ProlongLevel0 => &[W, R, R],
            Kernel::ProlongCoarse => &[R, W, R],
            Kernel::RestrictSum => &[R, W],
            Kernel::CoarsestSolve => &[R, R, W],
            Kernel::ApplyLevel0 => &[R, R, R, W],
            Kernel::DotPartial => &[R, R, R, R, W],
            Kernel::DotFinal => &[R, W],
            Kernel::FcgUpdate => &[R, W, W, R, W, R],
            Kernel::LiftPush => &[R, R, W, W],
            Kernel::LiftPull => &[R, R, R, W, W],
            Kernel::MipConstraints => &[R, R, W],
            Kernel::MipLevel0 => &[R, Binding::StorageTextureR32Write],
            Kernel::MipDownsample => &[Binding::Texture, Binding::StorageTextureR32Write, R],
            Kernel::MinmaxBase => &[R, W],
            Kernel::MinmaxReduce => &[W],
            Kernel::Rasterize => &[R, W, W, W, W, W, W],
            Kernel::DownsampleFields => &[R, R, R, W, W, W, W],
        }
    }
}

/// The shared include files: `#import name` -> `shaders/shared/name.wgsl`.
pub const SHARED: [(&str, &str); 6] = [
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
];

/// Resolves `#import name` lines (one level deep: shared files import nothing). Unknown names and
/// repeated imports are errors.
pub fn preprocess(source: &str) -> Result<String, String> {
    let mut out = String::with_capacity(source.len() + 2048);
    let mut seen: Vec<&str> = Vec::new();
    for (line_no, line) in source.lines().enumerate() {
        if let Some(rest) = line.trim_start().strip_prefix("#import") {
            let name = rest.trim();
            let Some((_, text)) = SHARED.iter().find(|(n, _)| *n == name) else {
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
}
