//! The solver's GPU resources: the buffer list (sizes checked against the device limits before anything
//! is allocated), the buffers themselves, and each pass's parameters and bindings.

use super::kernels::{PassSpec, Res};
use super::params::{MAX_PARTIALS, PARTIAL_SLOTS, Params, STENCIL_BYTES, Scalars};
use super::plan::{self, Op};
use super::{GpuContext, GpuError};
use crate::grid::{COARSEST_SIDE, MAX_SIDE};

/// Smallest side the GPU solver takes: level 1 must be the coarsest (8 x 8) or finer.
pub const MIN_GPU_SIDE: usize = 2 * COARSEST_SIDE;

/// Level-0 buffers of every solver, in allocation order (`d_east`, `d_north` follow them when the
/// solver takes uploaded edge differences).
const LEVEL0: [&str; 9] = ["weight", "value", "diag", "f", "h", "r", "z", "p", "q"];

/// Every buffer of one solver of side `n`, with its label and size (the allocation list and the limit
/// check). `edge_buffers`: the solver takes edge differences uploaded with the problem and keeps them
/// in level-0 buffers `d_east`, `d_north`; without them it has none (problems with `d = 0`, and the
/// heights of `GpuSolver`, whose edge differences the assembly computes from the gradient field).
pub fn buffer_sizes(n: usize, edge_buffers: bool) -> Vec<(String, u64)> {
    let cells = (n * n) as u64;
    let edges: &[&str] = if edge_buffers {
        &["d_east", "d_north"]
    } else {
        &[]
    };
    let mut out: Vec<(String, u64)> = LEVEL0
        .iter()
        .chain(edges)
        .map(|name| (format!("multigrid.{name}.l0"), cells * 4))
        .collect();
    let mut side = n / 2;
    let mut level = 1;
    while side >= COARSEST_SIDE {
        let c = (side * side) as u64;
        out.push((format!("multigrid.stencil.l{level}"), c * STENCIL_BYTES));
        out.push((format!("multigrid.u.l{level}"), c * 4));
        out.push((format!("multigrid.f.l{level}"), c * 4));
        side /= 2;
        level += 1;
    }
    out.push((
        "multigrid.partials".into(),
        PARTIAL_SLOTS * MAX_PARTIALS as u64 * 4,
    ));
    out.push((
        "multigrid.scalars".into(),
        std::mem::size_of::<Scalars>() as u64,
    ));
    out
}

/// Whether `label` (from [`buffer_sizes`]) is a coarse-level buffer (stencils, `u`, `f` of level >= 1).
fn is_coarse(label: &str) -> bool {
    ["multigrid.stencil.", "multigrid.u.", "multigrid.f."]
        .iter()
        .any(|p| label.starts_with(p))
        && !label.ends_with(".l0")
}

/// The buffers a solver of side `n` allocates itself: [`buffer_sizes`], without the coarse levels
/// when `shares_coarse` (they are those of a finer solver's levels, see [`Buffers`]). `gpu_budget`
/// and the allocation both use this list.
pub fn allocated_sizes(n: usize, edge_buffers: bool, shares_coarse: bool) -> Vec<(String, u64)> {
    buffer_sizes(n, edge_buffers)
        .into_iter()
        .filter(|(label, _)| !(shares_coarse && is_coarse(label)))
        .collect()
}

/// Number of solver levels of side `n` (n down to 8).
pub fn solve_levels(n: usize) -> usize {
    (n / COARSEST_SIDE).trailing_zeros() as usize + 1
}

/// Refuses a side the device cannot hold, before anything is allocated (the buffer sizes are those of
/// a solver with edge-difference buffers: the largest list).
pub(crate) fn check_limits(n: usize, limits: &wgpu::Limits) -> Result<(), GpuError> {
    if !n.is_power_of_two() || !(MIN_GPU_SIDE..=MAX_SIDE).contains(&n) {
        return Err(GpuError::BadSize {
            n,
            min: MIN_GPU_SIDE,
            max: MAX_SIDE,
        });
    }
    let too = |what: String, needed: u64, limit: u64, limit_name: &'static str| {
        if needed > limit {
            Err(GpuError::TooLarge {
                n,
                what,
                needed,
                limit,
                limit_name,
            })
        } else {
            Ok(())
        }
    };
    for (label, bytes) in buffer_sizes(n, true) {
        too(
            format!("buffer {label}"),
            bytes,
            limits.max_storage_buffer_binding_size,
            "max_storage_buffer_binding_size",
        )?;
        too(
            format!("buffer {label}"),
            bytes,
            limits.max_buffer_size,
            "max_buffer_size",
        )?;
    }
    for op in plan::all_ops(solve_levels(n)) {
        let g = op.workgroups(n).into_iter().max().unwrap_or(1) as u64;
        too(
            op.label(solve_levels(n) - 1),
            g,
            limits.max_compute_workgroups_per_dimension as u64,
            "max_compute_workgroups_per_dimension",
        )?;
    }
    let needs: [(&str, u64, u64, &'static str); 4] = [
        (
            "workgroup memory (coarsest_solve)",
            16384,
            limits.max_compute_workgroup_storage_size as u64,
            "max_compute_workgroup_storage_size",
        ),
        (
            "invocations per workgroup",
            256,
            limits.max_compute_invocations_per_workgroup as u64,
            "max_compute_invocations_per_workgroup",
        ),
        (
            "workgroup size x",
            256,
            limits.max_compute_workgroup_size_x as u64,
            "max_compute_workgroup_size_x",
        ),
        (
            // `assemble_level0` (and the rasteriser) bind 8: the WebGPU default.
            "storage buffers per stage",
            8,
            limits.max_storage_buffers_per_shader_stage as u64,
            "max_storage_buffers_per_shader_stage",
        ),
    ];
    for (what, needed, limit, name) in needs {
        too(what.to_string(), needed, limit, name)?;
    }
    Ok(())
}

/// Where a solver's level-0 assembly takes its edge differences from.
pub(crate) enum Edges {
    /// None: `d = 0` (the gradient field and roughness), no buffers.
    None,
    /// Uploaded with the problem into `(d_east, d_north)`.
    Uploaded(wgpu::Buffer, wgpu::Buffer),
    /// Computed inside the assembly from the level-1 gradient field `gx`, `gy` (owned by `GpuSolver`),
    /// the band weight in `r` (left there by the rasteriser; a plain upload clears it: `d = 0`) and
    /// the elevation weight, with cells of `cell_m = [dx, dy]` metres (the heights of `GpuSolver`).
    Gradient {
        gx: wgpu::Buffer,
        gy: wgpu::Buffer,
        cell_m: [f32; 2],
    },
}

/// The solver's buffers (fields as in [`buffer_sizes`]; `stencil[k - 1]`, `u[k - 1]`, `fc[k - 1]` are level k).
///
/// Aliasing: during FMG the lift (`plan::lift`, levels 1 ..= log2 n packed, [`plan::lift_len`] =
/// `(n^2 - 1) / 3` values each) keeps its push weights `W` in `q` and its values `V` / `g` in `p`. FCG
/// recomputes both before reading them (`fcg_init`: `p = z`; every step: `q = A p`), so FMG needs no
/// buffer of its own; `g_k` stays readable in `p` from the end of FMG until FCG starts. (The rasteriser
/// also writes `diag`, `r`, `z`, `p`, `q` of the height solver before the solve: `gpu::raster`; the
/// band weight it leaves in `r` is read by the height assembly, [`Edges::Gradient`], before FCG's
/// first pass rewrites `r`.)
///
/// Sharing between solvers: the gradient field (side n/2) and roughness (side n/4) of `GpuSolver`
/// own no coarse levels: their level `k >= 1` stencils, `u` and `f` are the height solver's level
/// `k + 1` (gradient field) and `k + 2` (roughness) buffers, of exactly their sizes
/// ([`GpuFieldSolver::sharing_coarse_levels`](super::GpuFieldSolver::sharing_coarse_levels)). Each is
/// dead whenever another solver runs: every assembly rebuilds all Galerkin levels (`plan::assemble`)
/// and every plan writes a coarse `u` / `f` before reading it (restriction, `ClearU`, prolongation
/// with `set`), and `GpuSolver::begin` runs the two field solves (gradient, then roughness) one after
/// the other before the height assembly, while the heights' coarse levels are used only from their
/// assembly until the next `begin`. The rasteriser writes only the fields' level-0 problems.
pub(crate) struct Buffers {
    pub weight: wgpu::Buffer,
    pub value: wgpu::Buffer,
    /// Where the level-0 assembly takes the edge differences from.
    pub edges: Edges,
    pub diag: wgpu::Buffer,
    pub f: wgpu::Buffer,
    pub h: wgpu::Buffer,
    pub r: wgpu::Buffer,
    pub z: wgpu::Buffer,
    pub p: wgpu::Buffer,
    pub q: wgpu::Buffer,
    /// `stencil[k - 1]`, `u[k - 1]`, `fc[k - 1]`: level k.
    pub stencil: Vec<wgpu::Buffer>,
    pub u: Vec<wgpu::Buffer>,
    pub fc: Vec<wgpu::Buffer>,
    pub partials: wgpu::Buffer,
    pub scalars: wgpu::Buffer,
}

impl Buffers {
    /// `gradient`: the level-1 gradient field `(gx, gy)` and the cell size `[dx, dy]` in metres, from
    /// which the assembly computes the edge differences (no edge buffers); else with or without
    /// uploaded edge differences by `edge_buffers`. `host`: a solver of side `n << shift` whose
    /// levels `shift + 1 ..` serve as this solver's coarse levels (see above; the caller checks the
    /// sides).
    pub fn new(
        ctx: &GpuContext,
        n: usize,
        edge_buffers: bool,
        gradient: Option<(&wgpu::Buffer, &wgpu::Buffer, [f32; 2])>,
        host: Option<(&Buffers, usize)>,
    ) -> (Buffers, u64) {
        let edge_buffers = edge_buffers && gradient.is_none();
        let mut all: Vec<wgpu::Buffer> = allocated_sizes(n, edge_buffers, host.is_some())
            .into_iter()
            .map(|(label, size)| {
                ctx.device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some(&label),
                    size,
                    usage: wgpu::BufferUsages::STORAGE
                        | wgpu::BufferUsages::COPY_DST
                        | wgpu::BufferUsages::COPY_SRC,
                    mapped_at_creation: false,
                })
            })
            .collect();
        let bytes = all.iter().map(|b| b.size()).sum();
        let scalars = all.pop().expect("scalars");
        let partials = all.pop().expect("partials");
        let coarse = all.split_off(LEVEL0.len() + if edge_buffers { 2 } else { 0 });
        let mut l0 = all.into_iter();
        let mut next = || l0.next().expect("level-0 buffer");
        let (weight, value, diag, f, h) = (next(), next(), next(), next(), next());
        let (r, z, p, q) = (next(), next(), next(), next());
        let edges = match gradient {
            Some((gx, gy, cell_m)) => Edges::Gradient {
                gx: gx.clone(),
                gy: gy.clone(),
                cell_m,
            },
            None if edge_buffers => Edges::Uploaded(next(), next()),
            None => Edges::None,
        };
        let (mut stencil, mut u, mut fc) = (Vec::new(), Vec::new(), Vec::new());
        if let Some((hb, shift)) = host {
            let levels = solve_levels(n) - 1;
            let take = |v: &[wgpu::Buffer]| -> Vec<wgpu::Buffer> {
                v.iter().skip(shift).take(levels).cloned().collect()
            };
            (stencil, u, fc) = (take(&hb.stencil), take(&hb.u), take(&hb.fc));
        }
        for (i, b) in coarse.into_iter().enumerate() {
            match i % 3 {
                0 => stencil.push(b),
                1 => u.push(b),
                _ => fc.push(b),
            }
        }
        let bufs = Buffers {
            weight,
            value,
            edges,
            diag,
            f,
            h,
            r,
            z,
            p,
            q,
            stencil,
            u,
            fc,
            partials,
            scalars,
        };
        (bufs, bytes)
    }
}

/// Parameters and resources of one op (bindings in the order of the kernel's `.wgsl` declarations).
pub(crate) fn pass_spec<'a>(
    op: Op,
    n: usize,
    levels: usize,
    ax: f32,
    ay: f32,
    threshold: f32,
    b: &'a Buffers,
) -> PassSpec<'a, Op> {
    use Res::Buffer as B;
    let kc = levels - 1;
    let side = |k: usize| (n >> k) as u32;
    let mut params = Params {
        n: n as u32,
        ax,
        ay,
        threshold,
        ..Params::default()
    };
    let resources = match op {
        // Mode 0 reads no edge differences and mode 1 no band: `weight` fills the unread slots.
        Op::Assemble => {
            let (east, north, band) = match &b.edges {
                Edges::None => (&b.weight, &b.weight, &b.weight),
                Edges::Uploaded(de, dn) => {
                    params.mode = 1;
                    (de, dn, &b.weight)
                }
                Edges::Gradient { gx, gy, cell_m } => {
                    params.mode = 2;
                    [params.dx, params.dy] = *cell_m;
                    (gx, gy, &b.r)
                }
            };
            vec![
                B(&b.weight),
                B(&b.value),
                B(east),
                B(north),
                B(band),
                B(&b.diag),
                B(&b.f),
                B(&b.h),
            ]
        }
        Op::GalerkinLevel0 => vec![B(&b.diag), B(&b.stencil[0])],
        Op::GalerkinCoarse { level } => {
            params.n = side(level - 1);
            vec![B(&b.stencil[level - 2]), B(&b.stencil[level - 1])]
        }
        Op::SmoothLevel0 { colour } => {
            params.colour = colour;
            vec![B(&b.z), B(&b.r), B(&b.diag)]
        }
        Op::SmoothCoarse { level, colour } => {
            params.n = side(level);
            params.colour = colour;
            vec![
                B(&b.stencil[level - 1]),
                B(&b.u[level - 1]),
                B(&b.fc[level - 1]),
            ]
        }
        Op::ResidualRestrictLevel0 { solution } => {
            let (x, rhs) = if solution { (&b.h, &b.f) } else { (&b.z, &b.r) };
            vec![B(x), B(rhs), B(&b.diag), B(&b.fc[0])]
        }
        Op::ResidualRestrictCoarse { level } => {
            params.n = side(level);
            vec![
                B(&b.stencil[level - 1]),
                B(&b.u[level - 1]),
                B(&b.fc[level - 1]),
                B(&b.fc[level]),
            ]
        }
        Op::ProlongLevel0 { solution } => {
            let x = if solution { &b.h } else { &b.z };
            vec![B(x), B(&b.u[0]), B(&b.diag)]
        }
        Op::ProlongCoarse { level, set } => {
            params.n = side(level);
            params.mode = set as u32;
            vec![B(&b.stencil[level - 1]), B(&b.u[level - 1]), B(&b.u[level])]
        }
        Op::RestrictSum { level } => {
            params.n = side(level);
            vec![B(&b.fc[level - 1]), B(&b.fc[level])]
        }
        Op::CoarsestSolve => {
            params.n = side(kc);
            vec![B(&b.stencil[kc - 1]), B(&b.fc[kc - 1]), B(&b.u[kc - 1])]
        }
        Op::ApplyLevel0 { residual } => {
            params.mode = residual as u32;
            if residual {
                vec![B(&b.h), B(&b.f), B(&b.diag), B(&b.r)]
            } else {
                vec![B(&b.p), B(&b.f), B(&b.diag), B(&b.q)]
            }
        }
        Op::DotPartial { stage } => {
            params.mode = stage;
            params.partials = plan::partial_groups(n * n);
            vec![B(&b.r), B(&b.z), B(&b.p), B(&b.q), B(&b.partials)]
        }
        Op::DotFinal { stage } => {
            params.mode = stage;
            params.partials = plan::partial_groups(n * n);
            vec![B(&b.partials), B(&b.scalars)]
        }
        Op::FcgUpdate { mode } => {
            params.mode = mode;
            vec![B(&b.scalars), B(&b.h), B(&b.r), B(&b.z), B(&b.p), B(&b.q)]
        }
        // The lift's packed storage aliases FCG's `q` (weights W) and `p` (values V, then g): both are
        // dead from the end of a solve until `fcg_init` recomputes them (see `Buffers`).
        Op::LiftPush { level } => {
            params.n = side(level - 1);
            params.mode = (level > 1) as u32;
            params.src_offset = if level > 1 {
                plan::lift_offset(n, level - 1) as u32
            } else {
                0
            };
            params.dst_offset = plan::lift_offset(n, level) as u32;
            vec![B(&b.diag), B(&b.value), B(&b.q), B(&b.p)]
        }
        Op::LiftPull { level } => {
            params.n = side(level);
            params.mode = (level == 0) as u32;
            params.src_offset = plan::lift_offset(n, level + 1) as u32;
            params.dst_offset = if level > 0 {
                plan::lift_offset(n, level) as u32
            } else {
                0
            };
            vec![B(&b.diag), B(&b.value), B(&b.q), B(&b.p), B(&b.h)]
        }
    };
    PassSpec {
        key: op,
        kernel: op.kernel(),
        params,
        resources,
        workgroups: op.workgroups(n),
        label: op.label(kc),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_and_levels() {
        assert_eq!(solve_levels(16), 2);
        assert_eq!(solve_levels(256), 6);
        let s = buffer_sizes(256, true);
        assert_eq!(s.len(), 11 + 3 * 5 + 2);
        assert_eq!(buffer_sizes(256, false).len(), 9 + 3 * 5 + 2);
        assert!(
            !buffer_sizes(256, false)
                .iter()
                .any(|(l, _)| l.contains("d_east") || l.contains("d_north"))
        );
        assert_eq!(
            s.iter()
                .find(|(l, _)| l == "multigrid.stencil.l1")
                .unwrap()
                .1,
            128 * 128 * 36
        );
        // The FMG lift's packed levels fit in the FCG vectors it borrows (`p`, `q`).
        for n in [16, 256, 4096, MAX_SIDE] {
            let s = buffer_sizes(n, false);
            for name in ["multigrid.p.l0", "multigrid.q.l0"] {
                let bytes = s.iter().find(|(l, _)| l == name).unwrap().1;
                assert!(4 * plan::lift_len(n) as u64 <= bytes, "{name} at n = {n}");
            }
        }
    }

    #[test]
    fn limits_refuse_before_allocating() {
        let small = wgpu::Limits {
            max_storage_buffer_binding_size: 128 << 20,
            ..wgpu::Limits::default()
        };
        assert!(check_limits(2048, &small).is_ok());
        let e = check_limits(4096, &small).unwrap_err();
        assert!(matches!(e, GpuError::TooLarge { .. }), "{e}");
        assert!(e.to_string().contains("multigrid.stencil.l1"), "{e}");
        assert!(matches!(
            check_limits(100, &small),
            Err(GpuError::BadSize { .. })
        ));
        assert!(matches!(
            check_limits(8, &small),
            Err(GpuError::BadSize { .. })
        ));
    }
}
