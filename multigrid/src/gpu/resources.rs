//! The solver's GPU resources: the buffer list (sizes checked against the device limits before anything
//! is allocated), the buffers themselves, and each pass's parameters and bindings.

use super::kernels::{PassSpec, Res};
use super::params::{
    MAX_PARTIALS, PARTIAL_SLOTS, Params, STAGE_PQ, STAGE_R, STAGE_Z, STENCIL_BYTES, Scalars,
};
use super::plan::{self, Op};
pub(crate) use super::slice::Slice;
use super::{GpuContext, GpuError};
use crate::grid::{COARSEST_SIDE, MAX_SIDE};
use sharing::GUEST_LEVEL0;
pub use sharing::borrowed_level0;
pub(crate) use sharing::{Host, Level0Buf, VY_HOME};

mod sharing;

/// Smallest side the GPU solver takes: level 1 must be the coarsest (8 x 8) or finer.
pub const MIN_GPU_SIDE: usize = 2 * COARSEST_SIDE;

/// Level-0 buffers of every solver, in allocation order (`d_east`, `d_north` follow them when the
/// solver takes uploaded edge differences). FCG's `q = A p` has none: the passes that read it
/// recompute it from `p` and `diag` (`shaders/shared/apply_p.wgsl`).
const LEVEL0: [&str; 8] = ["weight", "value", "diag", "f", "h", "r", "z", "p"];

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
    let levels = solve_levels(n);
    let fused = plan::fused_from(levels, plan::FUSED_SIDE);
    while side >= COARSEST_SIDE {
        let c = (side * side) as u64;
        // Level 1's stencils are computed from the level-0 diagonal where they are read.
        if level >= 2 {
            out.push((format!("multigrid.stencil.l{level}"), c * STENCIL_BYTES));
        }
        if Some(level) == fused {
            // The fused levels' `u` and `f` each in one buffer, level after level (the fused
            // pass binds them as one range: `Buffers::fused_run`).
            let cells = fused_cells(n, level);
            out.push((format!("multigrid.u.l{level}{FUSED_SUFFIX}"), cells * 4));
            out.push((format!("multigrid.f.l{level}{FUSED_SUFFIX}"), cells * 4));
        } else if fused.is_none_or(|kf| level < kf) {
            out.push((format!("multigrid.u.l{level}"), c * 4));
            out.push((format!("multigrid.f.l{level}"), c * 4));
        }
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

/// Label suffix of the buffers holding the fused levels' `u` or `f` (after the first level's).
const FUSED_SUFFIX: &str = "_down";

/// Cells of levels `from ..` of a solver of side `n` (down to the coarsest).
fn fused_cells(n: usize, from: usize) -> u64 {
    (from..solve_levels(n))
        .map(|k| ((n >> k) * (n >> k)) as u64)
        .sum()
}

/// Whether `label` (from [`buffer_sizes`]) is a coarse-level buffer (stencils, `u`, `f` of level >= 1).
fn is_coarse(label: &str) -> bool {
    ["multigrid.stencil.", "multigrid.u.", "multigrid.f."]
        .iter()
        .any(|p| label.starts_with(p))
        && !label.ends_with(".l0")
}

/// The buffers a solver of side `n` allocates itself: [`buffer_sizes`], without the coarse levels
/// when `shares_coarse` (they are those of a finer solver's levels, see [`Buffers`]) and without the
/// level-0 buffers named in `borrowed` (e.g. `"diag"`; they are ranges of a finer solver's level-0
/// buffers: [`borrowed_level0`]). `gpu_budget` and the allocation both use this list.
pub fn allocated_sizes(
    n: usize,
    edge_buffers: bool,
    shares_coarse: bool,
    borrowed: &[&str],
) -> Vec<(String, u64)> {
    buffer_sizes(n, edge_buffers)
        .into_iter()
        .filter(|(label, _)| !(shares_coarse && is_coarse(label)))
        .filter(|(label, _)| {
            !borrowed.iter().any(|name| {
                if name.contains('.') {
                    *label == format!("multigrid.{name}")
                } else {
                    *label == format!("multigrid.{name}.l0")
                }
            })
        })
        .collect()
}

/// Where a solver keeps its level-0 solution `h`.
pub(crate) enum HStore {
    /// A storage buffer (or a range of one).
    Buffer(Slice),
    /// Mip 0 of an R32Float texture (`GpuSolver`'s heights: the height texture of `GpuMips`, so
    /// that the displayed mip 0 is `h` itself); `view` shows mip 0 alone (bound as read-write
    /// storage or sampled, by the kernels' `TextureH` variants).
    Texture {
        texture: wgpu::Texture,
        view: wgpu::TextureView,
    },
}

impl HStore {
    /// `h` as a pass resource.
    pub fn res(&self) -> Res<'_> {
        match self {
            HStore::Buffer(s) => Res::Slice(s),
            HStore::Texture { view, .. } => Res::View(view),
        }
    }

    /// Whether `h` is mip 0 of a texture.
    pub fn in_texture(&self) -> bool {
        matches!(self, HStore::Texture { .. })
    }

    /// The buffer range holding `h`, if `h` is in a buffer.
    pub fn buffer(&self) -> Option<&Slice> {
        match self {
            HStore::Buffer(s) => Some(s),
            HStore::Texture { .. } => None,
        }
    }

    /// `h` in mip 0 of `texture`, which must be an `n x n` R32Float texture that can be bound as
    /// storage and sampled, and copied from.
    fn texture(texture: &wgpu::Texture, n: usize) -> Result<HStore, GpuError> {
        let usage = wgpu::TextureUsages::STORAGE_BINDING
            | wgpu::TextureUsages::TEXTURE_BINDING
            | wgpu::TextureUsages::COPY_SRC;
        let size = texture.size();
        if texture.format() != wgpu::TextureFormat::R32Float
            || texture.dimension() != wgpu::TextureDimension::D2
            || (size.width, size.height) != (n as u32, n as u32)
            || !texture.usage().contains(usage)
        {
            return Err(GpuError::ProblemMismatch(format!(
                "h of a {n} x {n} solver needs an {n} x {n} R32Float texture with {usage:?}"
            )));
        }
        let view = texture.create_view(&wgpu::TextureViewDescriptor {
            label: Some("multigrid.h.mip0"),
            base_mip_level: 0,
            mip_level_count: Some(1),
            ..Default::default()
        });
        Ok(HStore::Texture {
            texture: texture.clone(),
            view,
        })
    }
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

/// Bytes of [`Buffers::relax_box`]: the windows' bounds (4 words) and three workgroup counts.
pub(crate) const RELAX_BOX_BYTES: u64 = 32;
/// Byte offset of the local relaxation's indirect workgroup counts in [`Buffers::relax_box`].
pub(crate) const RELAX_ARGS_OFFSET: u64 = 16;

/// The solver's buffers (fields as in [`buffer_sizes`]; `stencil[k - 2]` (k >= 2), `u[k - 1]`,
/// `fc[k - 1]` are level k).
///
/// Stored nowhere: level 1's Galerkin stencils (every pass that reads them computes them from the
/// level-0 `diag`, `shaders/shared/coarse_level1.wgsl`, bound where other levels bind their records:
/// [`Buffers::stencils`]) and FCG's `q = A p` (recomputed from `p` and `diag` where it is read,
/// `shaders/shared/apply_p.wgsl`; `plan`'s `p_is_unchanged_while_q_is_read`).
///
/// Shared ranges, each dead while another tenant uses it:
/// - FMG's lift keeps its weights in level-0 `z` and its values in [`Buffers::lift_values`].
/// - `GpuSolver`'s heights (`f_in_p`) keep `f` in their `p`, `h` in mip 0 of the height texture
///   ([`HStore::Texture`]: the displayed mip 0 is `h` itself; a cold start writes `h = 0` in the
///   assembly pass, textures having no clear), level 1's `u` in the first quarter of their
///   `value` and its `f` in the last quarter of their `weight`, past the mips' constraint pyramid
///   (`GpuMips::in_weight_of`).
/// - The gradient field and roughness use the heights' levels `k + 1` and `k + 2` as their level
///   `k >= 1` ([`GpuFieldSolver::sharing_coarse_levels`](super::GpuFieldSolver::sharing_coarse_levels)),
///   and keep their level-0 buffers (roughness but its `h`) and the rasteriser's `vy` in ranges of
///   the heights' `p`, `diag`, `z` and level-2 stencils ([`GUEST_LEVEL0`], [`VY_HOME`]).
///
/// The unit test `aliased_ranges_are_not_read_after_another_tenant_wrote_them` walks the plans in
/// the order of `GpuSolver::begin` (rasterise, downsample, gradient x and y, roughness, heights,
/// then FCG and publishing) with what each step reads and writes, and fails if a range is read
/// after another tenant wrote it; `lent_ranges_fit_and_do_not_overlap` checks the layout and that
/// no pass binds one host both read-only and read-write (wgpu forbids it within a dispatch: so a
/// field's `z` needs a host of its own, the level-2 stencils). Not walked: `rasterize_and_read`
/// rasterises without downsampling, so the gradient maps it reads back stay intact.
pub(crate) struct Buffers {
    /// `f` is `p` (`GpuSolver`'s heights): FMG's lift keeps its values in `r` instead of `p`.
    pub f_in_p: bool,
    pub weight: Slice,
    pub value: Slice,
    /// Where the level-0 assembly takes the edge differences from.
    pub edges: Edges,
    pub diag: Slice,
    pub f: Slice,
    pub h: HStore,
    pub r: Slice,
    pub z: Slice,
    pub p: Slice,
    /// `stencil[k - 2]` (k >= 2; level 1's are computed from `diag`), `u[k - 1]`, `fc[k - 1]`:
    /// level k.
    pub stencil: Vec<wgpu::Buffer>,
    pub u: Vec<Slice>,
    pub fc: Vec<Slice>,
    pub partials: wgpu::Buffer,
    pub scalars: wgpu::Buffer,
    /// The local relaxation's box: the bounds of its windows (`relax_mask` modes 1, 2), then the
    /// indirect workgroup counts of its colour passes (at [`RELAX_ARGS_OFFSET`]).
    pub relax_box: wgpu::Buffer,
    /// The programs of the [`Op::CoarseFused`] passes (`plan::fused_program`: the cycle's, then
    /// FMG's), when the solver has fused levels; written by the solver once its shape is known.
    pub fused_program: Option<wgpu::Buffer>,
    /// The first level of this solver's own coarse levels kept in the fused buffers (`None` for a
    /// solver using another's coarse levels, or without fused levels).
    pub fused_from: Option<usize>,
}

impl Buffers {
    /// `gradient`: the level-1 gradient field `(gx, gy)` and the cell size `[dx, dy]` in metres, from
    /// which the assembly computes the edge differences (no edge buffers); else with or without
    /// uploaded edge differences by `edge_buffers`. `host`: a solver of side `n << shift` whose
    /// levels `shift + 1 ..` serve as this solver's coarse levels and, with `level0`, whose level-0
    /// buffers hold this solver's [`borrowed_level0`] buffers at the offsets of `GUEST_LEVEL0` (see
    /// above; the caller checks the sides). `h_texture`: `h` is mip 0 of that texture (required
    /// with `gradient`: `GpuSolver`'s heights), not a buffer.
    pub fn new(
        ctx: &GpuContext,
        n: usize,
        edge_buffers: bool,
        gradient: Option<(&wgpu::Buffer, &wgpu::Buffer, [f32; 2])>,
        host: Option<(&Buffers, usize, bool)>,
        h_texture: Option<&wgpu::Texture>,
    ) -> Result<(Buffers, u64), GpuError> {
        let edge_buffers = edge_buffers && gradient.is_none();
        // `GpuSolver`'s heights (gradient edges) keep `f` in their own `p` and `h` in the height
        // texture.
        let f_in_p = gradient.is_some();
        let h_store = h_texture.map(|t| HStore::texture(t, n)).transpose()?;
        if f_in_p && h_store.is_none() {
            return Err(GpuError::ProblemMismatch(
                "the heights of GpuSolver keep h in the height texture".into(),
            ));
        }
        let borrowed = match host {
            Some((_, shift, true)) => borrowed_level0(shift),
            _ if f_in_p => borrowed_level0(0),
            _ if h_store.is_some() => vec!["h"],
            _ => Vec::new(),
        };
        let listed = allocated_sizes(n, edge_buffers, host.is_some(), &borrowed);
        let mut all: Vec<wgpu::Buffer> = listed
            .iter()
            .map(|(label, size)| {
                ctx.device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some(label),
                    size: *size,
                    usage: wgpu::BufferUsages::STORAGE
                        | wgpu::BufferUsages::COPY_DST
                        | wgpu::BufferUsages::COPY_SRC,
                    mapped_at_creation: false,
                })
            })
            .collect();
        let bytes: u64 = all.iter().map(|b| b.size()).sum();
        let missing = || GpuError::ProblemMismatch("buffer list shorter than expected".into());
        let scalars = all.pop().ok_or_else(missing)?;
        let partials = all.pop().ok_or_else(missing)?;
        let own_level0 = LEVEL0.len() - borrowed.iter().filter(|b| !b.contains('.')).count()
            + if edge_buffers { 2 } else { 0 };
        if all.len() < own_level0 {
            return Err(missing());
        }
        let coarse = all.split_off(own_level0);
        let mut l0 = all.into_iter();
        let cells_bytes = (n * n * 4) as u64;
        let align = ctx.device.limits().min_storage_buffer_offset_alignment as u64;
        let mut level0 = Vec::with_capacity(LEVEL0.len());
        for buf in Level0Buf::ALL {
            let name = buf.name();
            let home = match host {
                Some((hb, shift, true)) => GUEST_LEVEL0
                    .iter()
                    .find(|g| g.shift == shift && g.buf == buf)
                    .map(|g| {
                        let host_cells = (n << shift) as u64 * (n << shift) as u64;
                        (hb, g.host, g.at * host_cells / 4)
                    }),
                _ => None,
            };
            let slice = match home {
                Some((hb, host_name, offset)) => hb
                    .host_range(host_name)
                    .and_then(|s| s.part(offset, cells_bytes))
                    .filter(|s| s.offset % align.max(1) == 0)
                    .ok_or_else(|| {
                        GpuError::ProblemMismatch(format!(
                            "a {n} x {n} solver's {name} does not fit at byte {offset} of the \
                             host's {host_name} (offsets aligned to {align} bytes)"
                        ))
                    })?,
                // Filled with `p` and the texture below.
                None if f_in_p && buf == Level0Buf::F => continue,
                None if h_store.is_some() && buf == Level0Buf::H => continue,
                None => Slice::whole(l0.next().ok_or_else(missing)?),
            };
            level0.push(slice);
        }
        let mut level0 = level0.into_iter();
        let mut next = || level0.next().ok_or_else(missing);
        let (weight, value, diag) = (next()?, next()?, next()?);
        let f = if f_in_p { None } else { Some(next()?) };
        let h = match h_store {
            Some(h) => h,
            None => HStore::Buffer(next()?),
        };
        let (r, z, p) = (next()?, next()?, next()?);
        let f = f.unwrap_or_else(|| p.clone());
        let edges = match gradient {
            Some((gx, gy, cell_m)) => Edges::Gradient {
                gx: gx.clone(),
                gy: gy.clone(),
                cell_m,
            },
            None if edge_buffers => {
                let de = l0.next().ok_or_else(missing)?;
                Edges::Uploaded(de, l0.next().ok_or_else(missing)?)
            }
            None => Edges::None,
        };
        let (mut stencil, mut u, mut fc) = (Vec::new(), Vec::new(), Vec::new());
        if let Some((hb, shift, _)) = host {
            let levels = solve_levels(n) - 1;
            // This solver's level k >= 2 is the host's level k + shift (`stencil[k + shift - 2]`).
            stencil = hb
                .stencil
                .iter()
                .skip(shift)
                .take(levels - 1)
                .cloned()
                .collect();
            u = hb.u.iter().skip(shift).take(levels).cloned().collect();
            fc = hb.fc.iter().skip(shift).take(levels).cloned().collect();
        }
        if f_in_p {
            // Level 1's `u` and `f`: in `value` (from 0) and `weight` (from 3/4 of it; the mips'
            // constraint pyramid takes its first 2/3), both dead from FMG's lift on.
            let c1 = (n * n) as u64;
            let no_room = || GpuError::ProblemMismatch("no room for level 1 in level 0".into());
            u.push(value.part(0, c1).ok_or_else(no_room)?);
            fc.push(weight.part(3 * c1, c1).ok_or_else(no_room)?);
        }
        let fused = plan::fused_from(solve_levels(n), plan::FUSED_SIDE);
        for ((label, _), b) in listed[own_level0..].iter().zip(coarse) {
            let into = if label.starts_with("multigrid.stencil.") {
                stencil.push(b);
                continue;
            } else if label.starts_with("multigrid.u.") {
                &mut u
            } else {
                &mut fc
            };
            match fused {
                // One range per fused level, level after level.
                Some(kf) if label.ends_with(FUSED_SUFFIX) => {
                    let whole = Slice::whole(b);
                    let mut at = 0;
                    for k in kf..solve_levels(n) {
                        let bytes = ((n >> k) * (n >> k) * 4) as u64;
                        into.push(whole.part(at, bytes).ok_or_else(missing)?);
                        at += bytes;
                    }
                }
                _ => into.push(Slice::whole(b)),
            }
        }
        let bufs = Buffers {
            f_in_p,
            weight,
            value,
            edges,
            diag,
            f,
            h,
            r,
            z,
            p,
            stencil,
            u,
            fc,
            partials,
            scalars,
            relax_box: ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("multigrid.relax_box"),
                size: RELAX_BOX_BYTES,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::INDIRECT,
                mapped_at_creation: false,
            }),
            fused_program: None,
            fused_from: if host.is_some() { None } else { fused },
        };
        Ok((bufs, bytes + RELAX_BOX_BYTES))
    }

    /// A host of [`GUEST_LEVEL0`] as a range: a level-0 buffer, or all of the level-2 stencils.
    pub(crate) fn host_range(&self, host: Host) -> Option<Slice> {
        match host {
            Host::Stencil2 => self.stencil.first().map(|b| Slice::whole(b.clone())),
            Host::Level0(b) => self.level0(b).cloned(),
        }
    }

    /// What a pass reading level `k`'s stencils binds for them (binding 1 of the coarse kernels):
    /// the records of level `k >= 2`, or for level 1 the level-0 `diag` it computes them from.
    pub fn stencils(&self, k: usize) -> Res<'_> {
        if k == 1 {
            bind(&self.diag)
        } else {
            bind(&self.stencil[k - 2])
        }
    }

    /// `v[from - 1 ..]` (levels `from ..` of `u` or `fc`) as one range: the fused pass binds the
    /// levels it runs so. `None` unless they lie one after the other in one buffer.
    pub fn fused_run(v: &[Slice], from: usize) -> Option<Slice> {
        let first = v.get(from.checked_sub(1)?)?;
        let mut end = first.offset;
        for s in &v[from - 1..] {
            if s.buffer != first.buffer || s.offset != end {
                return None;
            }
            end += s.size;
        }
        Some(Slice {
            buffer: first.buffer.clone(),
            offset: first.offset,
            size: end - first.offset,
        })
    }

    /// Where FMG's lift keeps its values `V` / `g`: `p`, or `r` when `f` is `p`.
    pub fn lift_values(&self) -> &Slice {
        if self.f_in_p { &self.r } else { &self.p }
    }

    /// A level-0 buffer (`h` only when it is a buffer).
    pub(crate) fn level0(&self, buf: Level0Buf) -> Option<&Slice> {
        Some(match buf {
            Level0Buf::Weight => &self.weight,
            Level0Buf::Value => &self.value,
            Level0Buf::Diag => &self.diag,
            Level0Buf::F => &self.f,
            Level0Buf::H => return self.h.buffer(),
            Level0Buf::R => &self.r,
            Level0Buf::Z => &self.z,
            Level0Buf::P => &self.p,
        })
    }
}

/// A whole buffer or a [`Slice`] as a pass resource.
fn bind<'a>(x: impl Into<Res<'a>>) -> Res<'a> {
    x.into()
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
        Op::Assemble { cold } => {
            params.slot_or_cold = cold as u32;
            let (east, north, band) = match &b.edges {
                Edges::None => (bind(&b.weight), bind(&b.weight), bind(&b.weight)),
                Edges::Uploaded(de, dn) => {
                    params.mode = 1;
                    (bind(de), bind(dn), bind(&b.weight))
                }
                Edges::Gradient { gx, gy, cell_m } => {
                    params.mode = 2;
                    [params.dx, params.dy] = *cell_m;
                    (bind(gx), bind(gy), bind(&b.r))
                }
            };
            vec![
                b.h.res(),
                bind(&b.weight),
                bind(&b.value),
                east,
                north,
                band,
                bind(&b.diag),
                bind(&b.f),
            ]
        }
        Op::GalerkinCoarse { level } => {
            params.n = side(level - 1);
            vec![b.stencils(level - 1), bind(&b.stencil[level - 2])]
        }
        Op::SmoothLevel0 { colour } => {
            params.colour = colour;
            vec![bind(&b.z), bind(&b.r), bind(&b.diag)]
        }
        Op::SmoothCoarse { level, colour } => {
            params.n = side(level);
            params.colour = colour;
            vec![
                b.stencils(level),
                bind(&b.u[level - 1]),
                bind(&b.fc[level - 1]),
            ]
        }
        Op::ResidualRestrictLevel0 { solution } => {
            let (x, rhs) = if solution {
                (b.h.res(), &b.f)
            } else {
                (bind(&b.z), &b.r)
            };
            vec![x, bind(rhs), bind(&b.diag), bind(&b.fc[0])]
        }
        Op::ResidualRestrictCoarse { level } => {
            params.n = side(level);
            vec![
                b.stencils(level),
                bind(&b.u[level - 1]),
                bind(&b.fc[level - 1]),
                bind(&b.fc[level]),
            ]
        }
        Op::ProlongLevel0 { solution } => {
            let x = if solution { b.h.res() } else { bind(&b.z) };
            vec![x, bind(&b.u[0]), bind(&b.diag)]
        }
        Op::ProlongCoarse { level, set } => {
            params.n = side(level);
            params.mode = set as u32;
            vec![b.stencils(level), bind(&b.u[level - 1]), bind(&b.u[level])]
        }
        Op::RestrictSum { level } => {
            params.n = side(level);
            vec![bind(&b.fc[level - 1]), bind(&b.fc[level])]
        }
        Op::CoarsestSolve => {
            params.n = side(kc);
            vec![b.stencils(kc), bind(&b.fc[kc - 1]), bind(&b.u[kc - 1])]
        }
        Op::CoarseFused { shape, fmg } => {
            let kf = shape
                .fused_from()
                .expect("a fused pass only on a shape with fused levels");
            params.n = side(kf);
            let cycle = plan::fused_program(Op::CoarseFused { shape, fmg: false }).len();
            params.src_offset = if fmg { cycle as u32 } else { 0 };
            params.dst_offset = plan::fused_program(op).len() as u32;
            let run = |v: &[Slice]| {
                Buffers::fused_run(v, kf).expect("the fused levels lie in one buffer, in order")
            };
            let program = b
                .fused_program
                .as_ref()
                .expect("the fused program is written before the passes are made");
            let mut res = vec![Res::Buffer(program)];
            for k in kf..kf + 4 {
                res.push(bind(&b.stencil[k.min(kc) - 2]));
            }
            res.push(Res::Owned(run(&b.u)));
            res.push(Res::Owned(run(&b.fc)));
            res
        }
        Op::ApplyLevel0 => vec![b.h.res(), bind(&b.f), bind(&b.diag), bind(&b.r)],
        // The windows go through `z` (rows) into `r` (the mask): both are scratch until FCG's
        // start, which rewrites them.
        Op::RelaxMask { mode } => {
            params.mode = mode;
            params.radius = crate::cpu::RADIUS as u32;
            // Mode 2 reads only the scalars and the box.
            let cells = |s: &'a Slice| if mode < 2 { bind(s) } else { stub(s) };
            vec![
                cells(&b.r),
                cells(&b.z),
                bind(&b.scalars),
                Res::Buffer(&b.relax_box),
            ]
        }
        Op::RelaxLevel0 { colour } => {
            params.colour = colour;
            vec![
                b.h.res(),
                bind(&b.f),
                bind(&b.diag),
                bind(&b.r),
                bind(&b.scalars),
            ]
        }
        // `q = A p` is recomputed from `p` and `diag` (no buffer holds it).
        // Each stage binds in full only what it reads (`p.q`: p, diag; `max |r|`: r), the rest
        // as stubs (the bindings are what the byte estimate counts).
        Op::DotPartial { stage } => {
            params.mode = stage;
            params.partials = plan::partial_groups(n * n);
            let reads = |s: &'a Slice, read: bool| if read { bind(s) } else { stub(s) };
            let (rz, pd) = (stage != STAGE_PQ, stage != STAGE_R);
            vec![
                reads(&b.r, rz),
                reads(&b.z, stage == STAGE_Z),
                reads(&b.p, pd),
                reads(&b.diag, pd),
                bind(&b.partials),
            ]
        }
        Op::DotFinal { stage } => {
            params.mode = stage;
            params.partials = plan::partial_groups(n * n);
            vec![bind(&b.partials), bind(&b.scalars)]
        }
        // The gates bind the solver's own gate buffers (`field::Gate`), not these.
        Op::Gate { .. } => unreachable!("gate passes are specified by their solver"),
        Op::FcgUpdate { mode } => {
            params.mode = mode;
            vec![
                b.h.res(),
                bind(&b.scalars),
                bind(&b.r),
                bind(&b.z),
                bind(&b.p),
                bind(&b.diag),
            ]
        }
        // The lift's packed storage aliases level-0 `z` (weights W) and FCG's `p` (values V, then g):
        // both are dead during FMG, and FCG writes them before reading them (see `Buffers`).
        // The lift binds of its packed storage only the levels it touches, and of the level-0
        // buffers only a stub where it does not read them (the bindings are what the byte
        // estimate counts).
        Op::LiftPush { level } => {
            params.n = side(level - 1);
            params.mode = (level > 1) as u32;
            let (base, w, v) = lift_ranges(b, n, (level - 1).max(1), level);
            params.src_offset = if level > 1 {
                (plan::lift_offset(n, level - 1) - base) as u32
            } else {
                0
            };
            params.dst_offset = (plan::lift_offset(n, level) - base) as u32;
            let level0 = |s: &'a Slice| if level == 1 { bind(s) } else { stub(s) };
            vec![level0(&b.diag), level0(&b.value), w, v]
        }
        Op::LiftPull { level } => {
            params.n = side(level);
            params.mode = (level == 0) as u32;
            let (base, w, v) = lift_ranges(b, n, level.max(1), level + 1);
            params.src_offset = (plan::lift_offset(n, level + 1) - base) as u32;
            params.dst_offset = if level > 0 {
                (plan::lift_offset(n, level) - base) as u32
            } else {
                0
            };
            let level0 = |s: &'a Slice| if level == 0 { bind(s) } else { stub(s) };
            let h = match b.h.buffer() {
                Some(h) if level > 0 => stub(h),
                _ => b.h.res(),
            };
            vec![h, level0(&b.diag), level0(&b.value), w, v]
        }
    };
    PassSpec {
        key: op,
        kernel: op.kernel(kc, b.h.in_texture()),
        params,
        resources,
        workgroups: op.workgroups(n),
        label: op.label(kc),
    }
}

/// The first 256 bytes of `s` (a binding a pass declares but does not read).
fn stub(s: &Slice) -> Res<'static> {
    Res::Owned(Slice {
        buffer: s.buffer.clone(),
        offset: s.offset,
        size: s.size.min(256),
    })
}

/// Lift levels `first ..= last` of the packed storage in `z` (weights) and the lift values, as
/// ranges from the level-`first` offset rounded down to 256 bytes (a valid binding offset on every
/// adapter): that rounded offset in elements and the two ranges.
fn lift_ranges(
    b: &Buffers,
    n: usize,
    first: usize,
    last: usize,
) -> (usize, Res<'static>, Res<'static>) {
    let base = plan::lift_offset(n, first) / 64 * 64;
    let end = plan::lift_offset(n, last) + (n >> last) * (n >> last);
    let range = |s: &Slice| {
        Res::Owned(Slice {
            buffer: s.buffer.clone(),
            offset: s.offset + 4 * base as u64,
            size: 4 * (end - base) as u64,
        })
    };
    (base, range(&b.z), range(b.lift_values()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cycle::CycleShape;
    use crate::gpu::params::{STAGE_R, STAGE_Z};

    #[test]
    fn sizes_and_levels() {
        assert_eq!(solve_levels(16), 2);
        assert_eq!(solve_levels(256), 6);
        let s = buffer_sizes(256, true);
        // Levels 1 ..= 5: stencils from level 2 on (level 1's are computed), `u`, `f` of levels
        // 1 ..= 3, and of the fused levels 4, 5 one buffer each.
        assert_eq!(s.len(), 10 + 4 + 6 + 2 + 2);
        assert_eq!(buffer_sizes(256, false).len(), 8 + 4 + 6 + 2 + 2);
        let fused_u = s.iter().find(|(l, _)| l == "multigrid.u.l4_down").unwrap();
        assert_eq!(fused_u.1, 4 * (16 * 16 + 8 * 8));
        assert!(s.iter().any(|(l, _)| l == "multigrid.u.l3"));
        assert!(!s.iter().any(|(l, _)| l == "multigrid.u.l5"));
        // 4096^2: levels 1 ..= 5 (2048^2 .. 128^2) unfused, 6 ..= 9 (64^2 .. 8^2) fused.
        let big = buffer_sizes(4096, false);
        assert!(big.iter().any(|(l, _)| l == "multigrid.f.l5"));
        assert!(big.iter().any(|(l, _)| l == "multigrid.f.l6_down"));
        assert!(!s.iter().any(|(l, _)| l == "multigrid.stencil.l1"));
        // FCG recomputes `q = A p` where it reads it: no buffer.
        assert!(!s.iter().any(|(l, _)| l == "multigrid.q.l0"));
        assert!(
            !buffer_sizes(256, false)
                .iter()
                .any(|(l, _)| l.contains("d_east") || l.contains("d_north"))
        );
        assert_eq!(
            s.iter()
                .find(|(l, _)| l == "multigrid.stencil.l2")
                .unwrap()
                .1,
            64 * 64 * 24
        );
        assert_eq!(buffer_sizes(16, false).len(), 8 + 2 + 2);
        // The FMG lift's packed levels fit in the level-0 vectors it borrows (`z`, `p` or `r`),
        // and the heights' level-2 stencils hold the fields' `z` (6 units).
        for n in [64, 256, 4096, MAX_SIDE] {
            let s = buffer_sizes(n, false);
            for name in ["multigrid.z.l0", "multigrid.p.l0", "multigrid.r.l0"] {
                let bytes = s.iter().find(|(l, _)| l == name).unwrap().1;
                assert!(4 * plan::lift_len(n) as u64 <= bytes, "{name} at n = {n}");
            }
            let l2 = s
                .iter()
                .find(|(l, _)| l == "multigrid.stencil.l2")
                .unwrap()
                .1;
            assert_eq!(l2, Host::Stencil2.units() * (n * n / 16 * 4) as u64);
        }
    }

    /// The ranges lent to `GpuSolver`'s gradient field and roughness and to the rasteriser's `vy`
    /// fit in their hosts, lie only in heights' buffers dead while the fields run (level-0 `diag`,
    /// `z`, `p` and the level-2 stencils; never `weight`, `value`, `r`, `h`), do not overlap, cover
    /// every guest buffer but roughness's `h`, and no solver pass binds one host both read-only and
    /// read-write.
    #[test]
    fn lent_ranges_fit_and_do_not_overlap() {
        use Level0Buf::*;
        // Units of n^2 / 16 floats: height buffers 16, gradient-field buffers 4, roughness 1.
        let mut ranges: Vec<(Host, u64, u64, String)> = GUEST_LEVEL0
            .iter()
            .map(|g| (g.host, g.at, g.units(), format!("{}.{:?}", g.shift, g.buf)))
            .collect();
        ranges.push((VY_HOME.0, VY_HOME.1, 4, "vy".into()));
        for (i, a) in ranges.iter().enumerate() {
            assert!(
                [
                    Host::Level0(Diag),
                    Host::Level0(Z),
                    Host::Level0(P),
                    Host::Stencil2
                ]
                .contains(&a.0),
                "{} in {:?}",
                a.3,
                a.0
            );
            assert!(
                a.1 + a.2 <= a.0.units(),
                "{} past the end of {:?}",
                a.3,
                a.0
            );
            for b in &ranges[i + 1..] {
                let apart = a.0 != b.0 || a.1 + a.2 <= b.1 || b.1 + b.2 <= a.1;
                assert!(apart, "{} and {} overlap in {:?}", a.3, b.3, a.0);
            }
        }
        assert_eq!(Level0Buf::ALL.map(Level0Buf::name), LEVEL0);
        let mut all = LEVEL0.to_vec();
        all.sort();
        let mut grad = borrowed_level0(1);
        grad.sort();
        assert_eq!(grad, all);
        let mut rough = borrowed_level0(2);
        rough.push("h");
        rough.sort();
        assert_eq!(rough, all);
        // The rasteriser writes the roughness problem (`weight`, `value`, adjacent: one binding)
        // while writing the level-0 maps into `weight`, `value`, `r`, `diag`, `z` of the heights;
        // the gradient downsampling's x pass writes grad `weight` / `value` while reading the maps
        // in `r`, `diag`, `z`, its y pass `vy` while reading `r`, `z`; the copy of `vy` into the
        // gradient field's `value` needs two buffers.
        let home = |shift: usize, buf: Level0Buf| {
            GUEST_LEVEL0
                .iter()
                .find(|g| g.shift == shift && g.buf == buf)
                .map(|g| (g.host, g.at))
        };
        assert_eq!(home(2, Weight).map(|h| (h.0, h.1 + 1)), home(2, Value));
        for buf in [Weight, Value] {
            for shift in [1, 2] {
                let (host, _) = home(shift, buf).unwrap();
                assert!(
                    ![Weight, Value, R, Diag, Z]
                        .map(Host::Level0)
                        .contains(&host)
                );
            }
        }
        assert!(![R, Z].map(Host::Level0).contains(&VY_HOME.0));
        assert_ne!(home(1, Value).map(|h| h.0), Some(VY_HOME.0));
        let home = |shift: usize, name: &str| {
            let buf = Level0Buf::ALL.into_iter().find(|b| b.name() == name)?;
            home(shift, buf).map(|h| h.0)
        };
        // The heights keep `f` in their own `p`, `h` in the height texture, level 1's `u` in
        // `value` (from 0) and its `f` in `weight` from 3/4, past the mips' constraint pyramid
        // (first `(n^2 - 1) / 3` pairs).
        assert_eq!(borrowed_level0(0), vec!["f", "h", "u.l1", "f.l1"]);
        for n in [16, 64, 4096, MAX_SIDE] {
            let c = super::super::mips::constraint_offsets(n);
            assert!(c[c.len() - 1] * 8 <= 3 * n * n, "pyramid at n = {n}");
        }
        // The level-0 buffers each solver pass reads and writes (as `pass_spec` binds them; the
        // guests have no edge differences: the assembly's unread slots are `weight`). A guest's
        // buffers that one pass reads and those it writes must lie in different height buffers
        // (roughness's own `h` is no height buffer).
        let passes: [(&str, &[&str], &[&str]); 13] = [
            ("assemble", &["weight", "value"], &["diag", "f", "h"]),
            // The level-1 passes compute level 1's stencils from `diag` and write coarse buffers.
            ("level-1 passes", &["diag"], &[]),
            ("smooth_level0", &["r", "diag"], &["z"]),
            ("residual_restrict_level0", &["z", "r", "diag"], &[]),
            ("residual_restrict_level0.h", &["h", "f", "diag"], &[]),
            ("prolong_level0", &["diag"], &["z"]),
            ("prolong_level0.h", &["diag"], &["h"]),
            ("apply_level0", &["h", "f", "diag"], &["r"]),
            ("dot_partial", &["r", "z", "p", "diag"], &[]),
            ("fcg_update", &["z", "diag"], &["h", "r", "p"]),
            ("lift_push", &["diag", "value"], &["z", "p"]),
            ("lift_pull", &["diag", "value", "z"], &["p", "h"]),
            ("clear_z", &[], &["z"]),
        ];
        for shift in [1, 2] {
            for (pass, reads, writes) in passes {
                for r in reads {
                    for w in writes {
                        let (hr, hw) = (home(shift, r), home(shift, w));
                        assert!(
                            hr.is_none() || hr != hw,
                            "{pass} of the field at shift {shift} reads {r} and writes {w}, both in {hr:?}"
                        );
                    }
                }
            }
        }
    }

    /// Who owns the data in a range: a solver of `GpuSolver` (the heights, the gradient field,
    /// roughness) or the rasteriser's maps and the mips' pyramid.
    #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
    enum Who {
        Heights,
        Grad,
        Rough,
        Raster,
        Mips,
    }

    /// A solver's buffer (`L0`, coarse level `k`), or the rasteriser's maps (band weight,
    /// prescribed gradient x and y, the gradient problem's y values) and the mips' pyramid.
    #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
    enum Buf {
        L0(Level0Buf),
        Stencil(usize),
        U(usize),
        Fc(usize),
        Band,
        Gx,
        Gy,
        Vy,
        Pyramid,
    }

    type Tenant = (Who, Buf);

    /// A physical buffer of `GpuSolver`: the heights' level-0 buffers (units of `n^2 / 16`
    /// floats), the height texture, a field's own level-0 buffer (roughness's `h`), the heights' coarse buffers (the level-2
    /// stencils in 6 units, the others one unit: their tenants share them whole).
    #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
    enum Phys {
        L0(Level0Buf),
        Texture,
        Own(Who, Level0Buf),
        Stencil(usize),
        U(usize),
        Fc(usize),
    }

    /// Where a tenant lives, as `Buffers::new` places it for `GpuSolver` (`GUEST_LEVEL0`,
    /// `VY_HOME`, a field's level k being the heights' level `k + shift`, the heights' `f` in
    /// their `p`, `h` in the texture, level 1's `u` in `value` 0..4 and `f` in `weight` 12..16,
    /// the mips' pyramid in `weight`'s first 2/3).
    fn place(t: Tenant) -> (Phys, u64, u64) {
        use Level0Buf::*;
        let host = |h: Host| match h {
            Host::Level0(b) => Phys::L0(b),
            Host::Stencil2 => Phys::Stencil(2),
        };
        match t {
            (Who::Heights, Buf::L0(F)) => (Phys::L0(P), 0, 16),
            (Who::Heights, Buf::L0(H)) => (Phys::Texture, 0, 16),
            (Who::Heights, Buf::L0(b)) => (Phys::L0(b), 0, 16),
            (Who::Heights, Buf::U(1)) => (Phys::L0(Value), 0, 4),
            (Who::Heights, Buf::Fc(1)) => (Phys::L0(Weight), 12, 16),
            (Who::Heights, Buf::Stencil(2)) => (Phys::Stencil(2), 0, Host::Stencil2.units()),
            (Who::Heights, Buf::Stencil(k)) => (Phys::Stencil(k), 0, 1),
            (Who::Heights, Buf::U(k)) => (Phys::U(k), 0, 1),
            (Who::Heights, Buf::Fc(k)) => (Phys::Fc(k), 0, 1),
            (who @ (Who::Grad | Who::Rough), b) => {
                let shift = if who == Who::Grad { 1 } else { 2 };
                match b {
                    // A buffer not lent is the field's own (roughness's `h`).
                    Buf::L0(b) => {
                        match GUEST_LEVEL0.iter().find(|g| g.shift == shift && g.buf == b) {
                            Some(g) => (host(g.host), g.at, g.at + g.units()),
                            None => (Phys::Own(who, b), 0, 1),
                        }
                    }
                    Buf::Stencil(k) => place((Who::Heights, Buf::Stencil(k + shift))),
                    Buf::U(k) => place((Who::Heights, Buf::U(k + shift))),
                    Buf::Fc(k) => place((Who::Heights, Buf::Fc(k + shift))),
                    _ => unreachable!("{t:?}"),
                }
            }
            (Who::Raster, Buf::Band) => (Phys::L0(R), 0, 16),
            (Who::Raster, Buf::Gx) => (Phys::L0(Diag), 0, 16),
            (Who::Raster, Buf::Gy) => (Phys::L0(Z), 0, 16),
            (Who::Raster, Buf::Vy) => (host(VY_HOME.0), VY_HOME.1, VY_HOME.1 + 4),
            (Who::Mips, Buf::Pyramid) => (Phys::L0(Weight), 0, 12),
            _ => unreachable!("{t:?}"),
        }
    }

    #[derive(Debug, Clone, Copy, PartialEq, Eq)]
    enum Access {
        Read,
        /// Overwrites the range before anything reads it.
        Write,
        /// Reads and writes (a smoother's unknowns, an update `x += ..`).
        Modify,
    }

    /// The buffers a plan step reads and writes (the passes' Reads / Writes headers in
    /// `shaders/`, as `pass_spec` binds them; the reductions' and gates' own buffers left out).
    /// `f_in_p`: the heights (their lift keeps its values in `r`). The fused pass is its steps.
    fn accesses(step: plan::Step, levels: usize, who: Who) -> Vec<(Buf, Access)> {
        use Access::*;
        use Level0Buf::*;
        let kc = levels - 1;
        let heights = who == Who::Heights;
        let lift_values = Buf::L0(if heights { R } else { P });
        let st = |k: usize| {
            if k == 1 {
                Buf::L0(Diag)
            } else {
                Buf::Stencil(k)
            }
        };
        let l0 = Buf::L0;
        let op = match step {
            plan::Step::Dispatch(op) | plan::Step::Gated(op) => op,
            plan::Step::ClearU { level } => return vec![(Buf::U(level), Write)],
            plan::Step::ClearZ => return vec![(l0(Z), Write)],
            _ => return Vec::new(),
        };
        match op {
            Op::Assemble { cold } => {
                let band = if heights { Buf::Band } else { l0(Weight) };
                let h = if cold { Write } else { Modify };
                vec![
                    (l0(Weight), Read),
                    (l0(Value), Read),
                    (band, Read),
                    (l0(Diag), Write),
                    (l0(F), Write),
                    (l0(H), h),
                ]
            }
            Op::GalerkinCoarse { level } => {
                vec![(st(level - 1), Read), (Buf::Stencil(level), Write)]
            }
            Op::SmoothLevel0 { .. } => vec![(l0(R), Read), (l0(Diag), Read), (l0(Z), Modify)],
            Op::SmoothCoarse { level, .. } => vec![
                (st(level), Read),
                (Buf::Fc(level), Read),
                (Buf::U(level), Modify),
            ],
            Op::ResidualRestrictLevel0 { solution } => {
                let (x, rhs) = if solution { (H, F) } else { (Z, R) };
                vec![
                    (l0(x), Read),
                    (l0(rhs), Read),
                    (l0(Diag), Read),
                    (Buf::Fc(1), Write),
                ]
            }
            Op::ResidualRestrictCoarse { level } => vec![
                (st(level), Read),
                (Buf::U(level), Read),
                (Buf::Fc(level), Read),
                (Buf::Fc(level + 1), Write),
            ],
            Op::ProlongLevel0 { solution } => {
                let x = if solution { H } else { Z };
                vec![(Buf::U(1), Read), (l0(Diag), Read), (l0(x), Modify)]
            }
            Op::ProlongCoarse { level, set } => vec![
                (st(level), Read),
                (Buf::U(level + 1), Read),
                (Buf::U(level), if set { Write } else { Modify }),
            ],
            Op::RestrictSum { level } => vec![(Buf::Fc(level), Read), (Buf::Fc(level + 1), Write)],
            Op::CoarsestSolve => vec![(st(kc), Read), (Buf::Fc(kc), Read), (Buf::U(kc), Write)],
            Op::CoarseFused { .. } => op
                .fused_steps()
                .into_iter()
                .flat_map(|s| accesses(s, levels, who))
                .collect(),
            Op::ApplyLevel0 => vec![
                (l0(H), Read),
                (l0(F), Read),
                (l0(Diag), Read),
                (l0(R), Write),
            ],
            Op::RelaxMask { mode: 0 } => vec![(l0(R), Read), (l0(Z), Write)],
            Op::RelaxMask { mode: 1 } => vec![(l0(Z), Read), (l0(R), Write)],
            // Mode 2 turns the windows' bounds into the colour passes' workgroups: it touches
            // only the relaxation box and the scalars, which no other tenant shares.
            Op::RelaxMask { .. } => Vec::new(),
            Op::RelaxLevel0 { .. } => vec![
                (l0(F), Read),
                (l0(Diag), Read),
                (l0(R), Read),
                (l0(H), Modify),
            ],
            // `z.q` also reads `p`, but the first direction ignores it (`p = z` follows), so
            // only `p.q` checks `p`.
            Op::DotPartial { stage: STAGE_Z } => {
                vec![(l0(R), Read), (l0(Z), Read), (l0(Diag), Read)]
            }
            Op::DotPartial { stage: STAGE_R } => vec![(l0(R), Read)],
            Op::DotPartial { .. } => vec![(l0(P), Read), (l0(Diag), Read)],
            Op::FcgUpdate { mode: 0 } => vec![
                (l0(P), Read),
                (l0(Diag), Read),
                (l0(H), Modify),
                (l0(R), Modify),
            ],
            Op::FcgUpdate { mode: 1 } => vec![(l0(Z), Read), (l0(P), Modify)],
            Op::FcgUpdate { .. } => vec![(l0(Z), Read), (l0(P), Write)],
            // Level 1 from level 0's problem; the next levels from the previous ones, in the
            // same ranges.
            Op::LiftPush { level: 1 } => vec![
                (l0(Diag), Read),
                (l0(Value), Read),
                (l0(Z), Write),
                (lift_values, Write),
            ],
            Op::LiftPush { .. } => vec![(l0(Z), Modify), (lift_values, Modify)],
            Op::LiftPull { level: 0 } => vec![
                (l0(Z), Read),
                (lift_values, Read),
                (l0(Diag), Read),
                (l0(Value), Read),
                (l0(H), Write),
            ],
            Op::LiftPull { .. } => vec![(l0(Z), Read), (lift_values, Modify)],
            Op::DotFinal { .. } | Op::Gate { .. } => Vec::new(),
        }
    }

    /// The last tenant to write each unit of each physical buffer.
    #[derive(Default)]
    struct Memory {
        owner: std::collections::HashMap<Phys, Vec<Option<Tenant>>>,
    }

    impl Memory {
        fn units(&mut self, t: Tenant) -> (&mut [Option<Tenant>], std::ops::Range<usize>) {
            let (phys, a, b) = place(t);
            let v = self.owner.entry(phys).or_insert_with(|| vec![None; 16]);
            (v.as_mut_slice(), a as usize..b as usize)
        }

        /// `t` reads its range: every unit must still hold what `t` wrote.
        fn read(&mut self, t: Tenant, what: &str) {
            let (v, r) = self.units(t);
            for u in r {
                assert_eq!(
                    v[u],
                    Some(t),
                    "{what}: {t:?} reads unit {u} of {:?}, last written by {:?}",
                    place(t).0,
                    v[u]
                );
            }
        }

        fn write(&mut self, t: Tenant) {
            let (v, r) = self.units(t);
            v[r].fill(Some(t));
        }

        fn access(&mut self, who: Who, b: Buf, a: Access, what: &str) {
            // The heights' assembly reads the rasteriser's band weight.
            let who = if b == Buf::Band { Who::Raster } else { who };
            if a != Access::Write {
                self.read((who, b), what);
            }
            if a != Access::Read {
                self.write((who, b));
            }
        }

        fn run(&mut self, who: Who, levels: usize, steps: &[plan::Step], what: &str) {
            for (i, &s) in steps.iter().enumerate() {
                for (b, a) in accesses(s, levels, who) {
                    self.access(who, b, a, &format!("{what}, step {i} {s:?}"));
                }
            }
        }
    }

    /// One solve of a field as `GpuSolver::begin` runs it (`solve` there): the assembly, FMG
    /// on a cold start, the queued relaxation and FCG (gated passes counted as run).
    fn field_solve(mem: &mut Memory, who: Who, shape: &CycleShape, cold: bool, what: &str) {
        let l = shape.levels;
        mem.run(who, l, &plan::assemble(shape, cold), what);
        if cold {
            mem.run(who, l, &plan::fmg(shape), what);
        }
        let sweeps = if who == Who::Heights {
            crate::cycle::SWEEPS
        } else {
            crate::cycle::FIELD_WARM_SWEEPS
        };
        mem.run(who, l, &plan::fcg_queued(shape, sweeps, 3, true), what);
    }

    /// The buffers `GpuSolver` shares between its solvers (`GUEST_LEVEL0`, `VY_HOME`, the
    /// fields' coarse levels, the heights' level 1 inside their level 0, `f` in `p`, the mips'
    /// pyramid in `weight`) walked through two frames of `GpuSolver` (a cold one, a warm one, each
    /// with further FCG iterations and publishes after `begin`), with what every plan step reads
    /// and writes: no tenant reads a range after another tenant wrote it.
    #[test]
    fn aliased_ranges_are_not_read_after_another_tenant_wrote_them() {
        use Level0Buf::*;
        let params = crate::SolverParams::default();
        for n in [64, 256, 1024, 4096] {
            let levels = solve_levels(n);
            let heights = CycleShape::new(levels, &params);
            let field = |shift: usize| CycleShape {
                levels: levels - shift,
                shift,
                ..heights
            };
            let (grad, rough) = (field(1), field(2));
            let mut mem = Memory::default();
            // Persistent between frames: the heights' `h` (the texture) and roughness's own `h`.
            mem.write((Who::Heights, Buf::L0(H)));
            mem.write((Who::Rough, Buf::L0(H)));
            for cold in [true, false] {
                let what = format!("{n}^2, {} frame", if cold { "cold" } else { "warm" });
                // The rasteriser: the height problem, the band weight, the gradient maps and
                // the roughness problem.
                for t in [
                    (Who::Heights, Buf::L0(Weight)),
                    (Who::Heights, Buf::L0(Value)),
                    (Who::Raster, Buf::Band),
                    (Who::Raster, Buf::Gx),
                    (Who::Raster, Buf::Gy),
                    (Who::Rough, Buf::L0(Weight)),
                    (Who::Rough, Buf::L0(Value)),
                ] {
                    mem.write(t);
                }
                // The gradient downsampling: x, then y (`vy`); the roughness range pass.
                let down = format!("{what}, downsampling");
                for t in [
                    (Who::Raster, Buf::Band),
                    (Who::Raster, Buf::Gx),
                    (Who::Raster, Buf::Gy),
                ] {
                    mem.read(t, &down);
                }
                mem.write((Who::Grad, Buf::L0(Weight)));
                mem.write((Who::Grad, Buf::L0(Value)));
                mem.read((Who::Raster, Buf::Band), &down);
                mem.read((Who::Raster, Buf::Gy), &down);
                mem.write((Who::Raster, Buf::Vy));
                mem.read((Who::Rough, Buf::L0(Weight)), &down);
                mem.read((Who::Rough, Buf::L0(Value)), &down);
                // The gradient field: x (warm from `gx`), `vy` into its values, y (warm from
                // `gy`), the solution kept in `gx` / `gy` after each.
                let gh = (Who::Grad, Buf::L0(H));
                if !cold {
                    mem.write(gh);
                }
                field_solve(
                    &mut mem,
                    Who::Grad,
                    &grad,
                    cold,
                    &format!("{what}, gradient x"),
                );
                mem.read(gh, &what);
                mem.read((Who::Raster, Buf::Vy), &what);
                mem.write((Who::Grad, Buf::L0(Value)));
                if !cold {
                    mem.write(gh);
                }
                field_solve(
                    &mut mem,
                    Who::Grad,
                    &grad,
                    cold,
                    &format!("{what}, gradient y"),
                );
                mem.read(gh, &what);
                field_solve(
                    &mut mem,
                    Who::Rough,
                    &rough,
                    cold,
                    &format!("{what}, roughness"),
                );
                field_solve(
                    &mut mem,
                    Who::Heights,
                    &heights,
                    cold,
                    &format!("{what}, heights"),
                );
                // Publishing (the pyramid from `diag` and `h`), then more FCG, published again.
                for _ in 0..2 {
                    mem.read((Who::Heights, Buf::L0(Diag)), &what);
                    mem.read((Who::Heights, Buf::L0(H)), &what);
                    mem.write((Who::Mips, Buf::Pyramid));
                    mem.read((Who::Mips, Buf::Pyramid), &what);
                    let more = plan::fcg_queued_iterations(&heights, false, 2);
                    mem.run(Who::Heights, levels, &more, &format!("{what}, more FCG"));
                }
            }
        }
    }

    #[test]
    fn limits_refuse_before_allocating() {
        let small = wgpu::Limits {
            max_storage_buffer_binding_size: 128 << 20,
            ..wgpu::Limits::default()
        };
        // 4096^2: level-0 buffers of 64 MiB (the largest), level-2 stencil records of 24 MiB.
        assert!(check_limits(4096, &small).is_ok());
        let e = check_limits(8192, &small).unwrap_err();
        assert!(matches!(e, GpuError::TooLarge { .. }), "{e}");
        assert!(e.to_string().contains("multigrid.weight.l0"), "{e}");
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
