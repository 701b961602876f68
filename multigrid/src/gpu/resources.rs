//! The solver's GPU resources: the buffer list (sizes checked against the device limits before anything
//! is allocated), the buffers themselves, and each pass's parameters and bindings.

use super::kernels::Res;
use super::params::{MAX_PARTIALS, PARTIAL_SLOTS, STENCIL_BYTES, Scalars};
use super::plan;
pub(crate) use super::slice::Slice;
use super::{GpuContext, GpuError};
use crate::grid::{COARSEST_SIDE, MAX_SIDE};
use passes::bind;
pub(crate) use passes::pass_spec;
use sharing::GUEST_LEVEL0;
pub use sharing::borrowed_level0;
pub(crate) use sharing::{Host, Level0Buf, VY_HOME};

mod passes;
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
            // The input of the level's tile sweeps after a prolongation (`plan::tile_sweeps`).
            out.push((format!("multigrid.alt.l{level}"), c * 4));
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
    [
        "multigrid.stencil.",
        "multigrid.u.",
        "multigrid.f.",
        "multigrid.alt.",
    ]
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

    /// `h` as a pass resource the pass does not access in its mode: a stub of the buffer, or the
    /// view marked unread (the bindings are what the byte estimate counts).
    pub fn unread_res(&self) -> Res<'_> {
        match self {
            HStore::Buffer(s) => passes::stub(s),
            HStore::Texture { view, .. } => Res::UnreadView(view),
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
    let needs: [(&str, u64, u64, &'static str); 5] = [
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
        (
            // `mip_tail` writes four mips: the WebGPU default.
            "storage textures per stage",
            4,
            limits.max_storage_textures_per_shader_stage as u64,
            "max_storage_textures_per_shader_stage",
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

/// A new [`Buffers::relax_box`], empty (as `relax_mask` leaves it after each relaxation: the mask
/// pass only widens it).
fn empty_relax_box(ctx: &GpuContext) -> wgpu::Buffer {
    let buffer = ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("multigrid.relax_box"),
        size: RELAX_BOX_BYTES,
        usage: wgpu::BufferUsages::STORAGE
            | wgpu::BufferUsages::INDIRECT
            | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let empty: [u32; 8] = [u32::MAX, 0, u32::MAX, 0, 0, 1, 1, 0];
    ctx.queue
        .write_buffer(&buffer, 0, bytemuck::cast_slice(&empty));
    ctx.count_up(RELAX_BOX_BYTES);
    buffer
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
/// the order of `GpuSolver::begin` (rasterise, gradient x and y, roughness, heights,
/// then FCG and publishing) with what each step reads and writes, and fails if a range is read
/// after another tenant wrote it; `lent_ranges_fit_and_do_not_overlap` checks the layout and that
/// no pass binds one host both read-only and read-write (wgpu forbids it within a dispatch: so a
/// field's `z` needs a host of its own, the level-2 stencils). The rasteriser writes no level-0
/// gradient or roughness map: the problems on levels 1 and 2 directly.
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
    /// `alt[k - 1]`: level k's tile-sweep input (levels above the fused ones).
    pub alt: Vec<Slice>,
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
        let scalars = all.pop().ok_or_else(missing)?;
        let partials = all.pop().ok_or_else(missing)?;
        let own_level0 = LEVEL0.len() - borrowed.iter().filter(|b| !b.contains('.')).count()
            + if edge_buffers { 2 } else { 0 };
        if all.len() < own_level0 {
            return Err(missing());
        }
        let coarse = all.split_off(own_level0);
        let mut l0 = all.into_iter();
        let level0 = level0_slices(ctx, n, host, f_in_p, h_store.is_some(), &mut l0)?;
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
        let fused = plan::fused_from(solve_levels(n), plan::FUSED_SIDE);
        let (stencil, u, fc, alt) = coarse_levels(
            n,
            host,
            f_in_p,
            (&value, &weight),
            &listed[own_level0..],
            coarse,
        )?;
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
            alt,
            partials,
            scalars,
            relax_box: empty_relax_box(ctx),
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

/// Level 0's buffers in [`Level0Buf::ALL`] order, without `f` (kept in `p`) when `f_in_p` and `h`
/// when `h_in_texture`: the host's range where [`GUEST_LEVEL0`] puts one, else the next of `l0`.
fn level0_slices(
    ctx: &GpuContext,
    n: usize,
    host: Option<(&Buffers, usize, bool)>,
    f_in_p: bool,
    h_in_texture: bool,
    l0: &mut impl Iterator<Item = wgpu::Buffer>,
) -> Result<Vec<Slice>, GpuError> {
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
            None if h_in_texture && buf == Level0Buf::H => continue,
            None => Slice::whole(l0.next().ok_or_else(missing)?),
        };
        level0.push(slice);
    }
    Ok(level0)
}

/// The coarse levels' stencils, `u`, `f` and `alt`: levels `shift + 1 ..` of `host`'s, level 1 in
/// `value` / `weight` when `f_in_p`, then `coarse` (the own buffers, labelled by `listed`; one
/// range per fused level of a fused buffer).
#[allow(clippy::type_complexity)]
fn coarse_levels(
    n: usize,
    host: Option<(&Buffers, usize, bool)>,
    f_in_p: bool,
    (value, weight): (&Slice, &Slice),
    listed: &[(String, u64)],
    coarse: Vec<wgpu::Buffer>,
) -> CoarseLevels {
    let fused = plan::fused_from(solve_levels(n), plan::FUSED_SIDE);
    let (mut stencil, mut u, mut fc, mut alt) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
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
        alt = hb.alt.iter().skip(shift).take(levels).cloned().collect();
    }
    if f_in_p {
        // Level 1's `u` and `f`: in `value` (from 0) and `weight` (from 3/4 of it; the mips'
        // constraint pyramid takes its first 2/3), both dead from FMG's lift on.
        let c1 = (n * n) as u64;
        let no_room = || GpuError::ProblemMismatch("no room for level 1 in level 0".into());
        u.push(value.part(0, c1).ok_or_else(no_room)?);
        fc.push(weight.part(3 * c1, c1).ok_or_else(no_room)?);
        // Level 1's tile-sweep input: at the start of `weight` (the mips' constraint pyramid, dead
        // while the heights are solved), not in `value` with `u` (a pass binds both, one
        // read-write, and wgpu refuses two such views of one buffer).
        alt.push(weight.part(0, c1).ok_or_else(no_room)?);
    }
    for ((label, _), b) in listed.iter().zip(coarse) {
        let into = if label.starts_with("multigrid.stencil.") {
            stencil.push(b);
            continue;
        } else if label.starts_with("multigrid.u.") {
            &mut u
        } else if label.starts_with("multigrid.alt.") {
            &mut alt
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
    Ok((stencil, u, fc, alt))
}

/// The coarse levels' stencil buffers and `u`, `f`, `alt` ranges ([`coarse_levels`]).
type CoarseLevels = Result<(Vec<wgpu::Buffer>, Vec<Slice>, Vec<Slice>, Vec<Slice>), GpuError>;

/// The buffer list is shorter than the layout needs.
fn missing() -> GpuError {
    GpuError::ProblemMismatch("buffer list shorter than expected".into())
}

#[cfg(test)]
mod tests;
