//! The height texture with a full mip chain and the min/max pyramid (`ALGORITHM.md`, "Mip chain and
//! min/max pyramid") on the GPU. The CPU twin, and the oracle of the tests, is [`crate::pyramid`].
//!
//! Per mip level k >= 1 a constraint pyramid holds, per cell, the number of hard level-0 cells in its
//! footprint and the sum of their `E` (summed level by level, children in the order
//! (0,0), (1,0), (0,1), (1,1) on both sides): `W_k = count > 0`, `Ebar_k = sum / count`.

use super::field::GpuFieldSolver;
use super::kernels::{PassSpec, PassTable, Pipelines, Res};
use super::params::Params;
use super::plan::{groups_2d, minmax_base_groups, minmax_finest_side};
use super::readback;
use super::resources::{Buffers, HStore};
use super::shaders::Kernel;
use super::slice::Slice;
use super::{GpuContext, GpuError};
use crate::pyramid::MinMaxLevel;

/// Element offsets of the constraint pyramid: entry `k - 1` is where level k (side `n >> k`) starts, for
/// k = 1 ..= log2 n; the last entry is the total element count.
pub fn constraint_offsets(n: usize) -> Vec<usize> {
    let mut out = vec![0];
    let mut side = n / 2;
    while side >= 1 {
        out.push(out[out.len() - 1] + side * side);
        side /= 2;
    }
    out
}

/// Elements `from .. end` of the constraint pyramid (`vec2` elements) as a binding from `from`
/// rounded down to 256 bytes (a valid binding offset on every adapter): that rounded element
/// offset and the range.
fn pyramid_range(pyramid: &Slice, from: usize, end: usize) -> (usize, Res<'static>) {
    let base = from / 32 * 32;
    let range = Slice {
        buffer: pyramid.buffer.clone(),
        offset: pyramid.offset + 8 * base as u64,
        size: 8 * (end - base) as u64,
    };
    (base, Res::Owned(range))
}

/// The height texture of an `n x n` grid: R32Float, a full mip chain, `STORAGE_BINDING |
/// TEXTURE_BINDING | COPY_SRC` (texel (i, j) = cell (i, j), row 0 = south). Made by [`GpuMips`], or
/// first, for a solver that keeps its `h` in mip 0 ([`GpuFieldSolver::with_texture_h`]).
pub fn height_texture(ctx: &GpuContext, n: usize) -> wgpu::Texture {
    ctx.device.create_texture(&wgpu::TextureDescriptor {
        label: Some("multigrid.heights"),
        size: wgpu::Extent3d {
            width: n as u32,
            height: n as u32,
            depth_or_array_layers: 1,
        },
        mip_level_count: n.trailing_zeros() + 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: wgpu::TextureFormat::R32Float,
        usage: wgpu::TextureUsages::STORAGE_BINDING
            | wgpu::TextureUsages::TEXTURE_BINDING
            | wgpu::TextureUsages::COPY_SRC,
        view_formats: &[],
    })
}

/// Element offsets of the min/max pyramid, finest stored level (side `min(n, 64)`) first down to 1x1;
/// the last entry is the total element count.
pub fn min_max_offsets(n: usize) -> Vec<usize> {
    let mut out = vec![0];
    let mut side = minmax_finest_side(n);
    while side >= 1 {
        out.push(out[out.len() - 1] + side * side);
        side /= 2;
    }
    out
}
/// Side of the largest mip level [`Kernel::MipTail`] starts from: its level in workgroup memory.
const TAIL_SIDE: usize = 32;
/// Mip levels one [`Kernel::MipTail`] dispatch writes at most (its storage views: WebGPU's default
/// limit is 4 per stage).
const TAIL_LEVELS: usize = 4;

/// The passes copying `h` into mip 0 (when it is a buffer), then building each mip level with its
/// constraint pyramid level: one pass per level of side > [`TAIL_SIDE`], then up to [`TAIL_LEVELS`]
/// levels per one-workgroup pass; with their steps in order. `spare` is a 1 x 1 storage view bound to
/// a tail's unused slots.
fn texture_specs<'a>(
    n: usize,
    b: &'a Buffers,
    views: &'a [wgpu::TextureView],
    spare: &'a wgpu::TextureView,
    constraints: &Slice,
) -> (Vec<PassSpec<'a, MipOp>>, Vec<MipOp>) {
    let mip_count = n.trailing_zeros() as usize + 1;
    let c_off = constraint_offsets(n);
    let mut specs = Vec::new();
    let mut steps = Vec::new();
    let side = |k: usize| n >> k;
    if let HStore::Buffer(h) = &b.h {
        let params = Params {
            n: n as u32,
            ..Params::default()
        };
        let res = vec![Res::Slice(h), Res::View(&views[0])];
        specs.push(spec(
            MipOp::Level0,
            Kernel::MipLevel0,
            params,
            res,
            groups_2d(n, n),
        ));
        steps.push(MipOp::Level0);
    }
    let mut level = 1;
    while level < mip_count {
        let count = if side(level) > TAIL_SIDE {
            1
        } else {
            TAIL_LEVELS.min(mip_count - level)
        };
        let key = MipOp::Levels {
            first: level,
            count,
        };
        // Of the pyramid, the levels read and written; the level-0 diagonal (a stub above level
        // 1) only where read: the bindings are what the byte estimate counts.
        let from = if level > 1 { level - 2 } else { level - 1 };
        let (base, pyramid) = pyramid_range(constraints, c_off[from], c_off[level + count - 1]);
        let params = Params {
            n: side(level - 1) as u32,
            mode: (level > 1) as u32,
            src_offset: if level > 1 {
                (c_off[level - 2] - base) as u32
            } else {
                0
            },
            dst_offset: (c_off[level - 1] - base) as u32,
            partials: count as u32,
            ..Params::default()
        };
        let diag = if level > 1 {
            Res::Owned(Slice {
                size: b.diag.size.min(256),
                ..b.diag.clone()
            })
        } else {
            Res::Slice(&b.diag)
        };
        let (kernel, mut res, groups) = if side(level) > TAIL_SIDE {
            let res = vec![Res::View(&views[level - 1]), Res::View(&views[level])];
            (Kernel::MipLevel, res, groups_2d(side(level), side(level)))
        } else {
            let mut res = vec![Res::View(&views[level - 1])];
            res.extend((0..TAIL_LEVELS).map(|t| {
                if t < count {
                    Res::View(&views[level + t])
                } else {
                    Res::UnreadView(spare)
                }
            }));
            (Kernel::MipTail, res, [1, 1, 1])
        };
        res.extend([diag, pyramid]);
        specs.push(spec(key, kernel, params, res, groups));
        steps.push(key);
        level += count;
    }
    (specs, steps)
}

/// The passes building the min/max pyramid (its finest stored level, then the coarser ones in one
/// workgroup), appended to `specs` and `steps`.
fn minmax_specs<'a>(
    n: usize,
    b: &'a Buffers,
    minmax: &'a wgpu::Buffer,
    texture_h: bool,
    specs: &mut Vec<PassSpec<'a, MipOp>>,
    steps: &mut Vec<MipOp>,
) {
    let s0 = minmax_finest_side(n);
    let params = Params {
        n: n as u32,
        mode: s0 as u32,
        dst_offset: 0,
        ..Params::default()
    };
    let res = vec![b.h.res(), Res::Buffer(minmax)];
    specs.push(spec(
        MipOp::MinmaxBase,
        pick(Kernel::MinmaxBase, texture_h),
        params,
        res,
        minmax_base_groups(n),
    ));
    steps.push(MipOp::MinmaxBase);
    if s0 > 1 {
        let params = Params {
            n: s0 as u32,
            ..Params::default()
        };
        specs.push(spec(
            MipOp::MinmaxReduce,
            Kernel::MinmaxReduce,
            params,
            vec![Res::Buffer(minmax)],
            [1, 1, 1],
        ));
        steps.push(MipOp::MinmaxReduce);
    }
}

/// `k`, or its variant reading `h` from the height texture when `h` lives there.
fn pick(k: Kernel, texture_h: bool) -> Kernel {
    if texture_h {
        k.with_texture_h().unwrap_or(k)
    } else {
        k
    }
}

fn spec<'a>(
    key: MipOp,
    kernel: Kernel,
    params: Params,
    resources: Vec<Res<'a>>,
    workgroups: [u32; 3],
) -> PassSpec<'a, MipOp> {
    let label = format!("multigrid.{}.{:?}", kernel.name(), key)
        .to_lowercase()
        .replace([' ', '{', '}', ':'], "");
    PassSpec {
        key,
        kernel,
        params,
        resources,
        workgroups,
        label,
    }
}

/// One pass of the mip chain.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
enum MipOp {
    Level0,
    /// Mip levels `first .. first + count` and their constraint pyramid levels.
    Levels {
        first: usize,
        count: usize,
    },
    MinmaxBase,
    MinmaxReduce,
}

/// The height texture (R32Float, full mip chain, `STORAGE_BINDING | TEXTURE_BINDING | COPY_SRC`) and the
/// min/max pyramid of one solver's level-0 solution. When the solver keeps `h` in mip 0 of the
/// height texture ([`GpuFieldSolver::with_texture_h`], `GpuSolver`'s heights), that is the texture:
/// mip 0 is `h` at every moment (each FCG iteration changes it), [`GpuMips::update`] rebuilds mips
/// 1 .. and the min/max pyramid from it.
pub struct GpuMips {
    ctx: GpuContext,
    n: usize,
    texture: wgpu::Texture,
    _views: Vec<wgpu::TextureView>,
    _spare: wgpu::TextureView,
    _constraints: Slice,
    minmax: wgpu::Buffer,
    pipelines: Pipelines,
    table: PassTable<MipOp>,
    steps: Vec<MipOp>,
    gpu_bytes: u64,
    /// Staging copy of the min/max pyramid for reads that do not wait ([`Self::try_min_max`]),
    /// and its requested mapping.
    minmax_staging: wgpu::Buffer,
    minmax_pending: std::sync::Mutex<Option<readback::MapPending>>,
}

impl GpuMips {
    /// Allocates the texture (unless `solver`'s `h` is mip 0 of one: then that one) and pyramids
    /// for `solver`'s grid and binds its `h` and `diag`.
    pub fn new(solver: &GpuFieldSolver) -> Result<GpuMips, GpuError> {
        Self::build(solver, false)
    }

    /// As [`Self::new`], but the constraint pyramid (`(n^2 - 1) / 3` pairs, 2/3 of a level-0
    /// buffer) is the first part of `solver`'s level-0 `weight`, which nothing reads after the
    /// assembly (the pyramid is built from `diag` and `h`, FMG's lift reads `value`):
    /// [`Self::update`] may run only between an assembly and the next rasterisation or upload into
    /// `solver` (`GpuSolver::publish`; see `Buffers` in `gpu::resources`), and rewrites the pyramid
    /// before reading it.
    pub(crate) fn in_weight_of(solver: &GpuFieldSolver) -> Result<GpuMips, GpuError> {
        Self::build(solver, true)
    }

    fn build(solver: &GpuFieldSolver, shared: bool) -> Result<GpuMips, GpuError> {
        let ctx = solver.context().clone();
        let n = solver.n();
        ctx.clone().checked("multigrid.mips.new", || {
            let mip_count = n.trailing_zeros() as usize + 1;
            let b = &solver.bufs;
            // `h` in mip 0 already: no copy (`MipLevel0`), and the passes reading `h` read it there.
            let texture_h = b.h.in_texture();
            let texture = match &b.h {
                HStore::Texture { texture, .. } => texture.clone(),
                HStore::Buffer(_) => height_texture(&ctx, n),
            };
            let views: Vec<wgpu::TextureView> = (0..mip_count as u32)
                .map(|k| {
                    texture.create_view(&wgpu::TextureViewDescriptor {
                        label: Some(&format!("multigrid.heights.mip{k}")),
                        base_mip_level: k,
                        mip_level_count: Some(1),
                        ..Default::default()
                    })
                })
                .collect();
            let texture_bytes: u64 = (0..mip_count)
                .map(|k| ((n >> k) * (n >> k) * 4) as u64)
                .sum();
            let c_off = constraint_offsets(n);
            let m_off = min_max_offsets(n);
            let storage = |label: &str, bytes: u64| {
                ctx.device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some(label),
                    size: bytes,
                    usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
                    mapped_at_creation: false,
                })
            };
            let constraint_bytes = (c_off[c_off.len() - 1] * 8) as u64;
            let constraints = if shared {
                solver
                    .bufs
                    .weight
                    .part(0, constraint_bytes)
                    .ok_or_else(|| {
                        GpuError::ProblemMismatch(
                            "no room for the constraint pyramid in weight".into(),
                        )
                    })?
            } else {
                Slice::whole(storage("multigrid.mips.constraints", constraint_bytes))
            };
            let minmax = storage("multigrid.mips.minmax", (m_off[m_off.len() - 1] * 8) as u64);
            let pipelines = Pipelines::new(
                &ctx,
                &[
                    Kernel::MipLevel,
                    Kernel::MipTail,
                    Kernel::MipLevel0,
                    pick(Kernel::MinmaxBase, texture_h),
                    Kernel::MinmaxReduce,
                ],
            );
            let spare_texture = ctx.device.create_texture(&wgpu::TextureDescriptor {
                label: Some("multigrid.mips.spare"),
                size: wgpu::Extent3d {
                    width: 1,
                    height: 1,
                    depth_or_array_layers: 1,
                },
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format: wgpu::TextureFormat::R32Float,
                usage: wgpu::TextureUsages::STORAGE_BINDING,
                view_formats: &[],
            });
            let spare = spare_texture.create_view(&Default::default());
            let (mut specs, mut steps) = texture_specs(n, b, &views, &spare, &constraints);
            minmax_specs(n, b, &minmax, texture_h, &mut specs, &mut steps);
            let table = PassTable::new(&ctx, &pipelines, "multigrid.mips.params", specs);
            let own_constraints = if shared { 0 } else { constraint_bytes };
            let minmax_staging = ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("multigrid.mips.minmax_staging"),
                size: minmax.size(),
                usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            // The spare view's texel: 4 bytes.
            let gpu_bytes = texture_bytes
                + 4
                + own_constraints
                + minmax.size()
                + table.bytes
                + minmax_staging.size();
            Ok(GpuMips {
                ctx: ctx.clone(),
                n,
                texture,
                _views: views,
                _spare: spare,
                _constraints: constraints,
                minmax,
                minmax_staging,
                minmax_pending: std::sync::Mutex::new(None),
                pipelines,
                table,
                steps,
                gpu_bytes,
            })
        })
    }

    /// Rebuilds the constraint pyramid, every mip from the solver's current `h` (mip 0 a copy of it,
    /// unless it is `h`), and the min/max pyramid.
    pub fn update(&self) -> Result<(), GpuError> {
        self.update_and_copy_top(None)
    }

    /// [`Self::update`], then the top min/max cell (the whole map's `[min, max]`, 8 bytes) copied to
    /// `top` (buffer, byte offset) in the same submission, to be read with other results.
    pub fn update_and_copy_top(&self, top: Option<(&wgpu::Buffer, u64)>) -> Result<(), GpuError> {
        self.ctx.checked("multigrid.mips.update", || {
            let mut enc = self
                .ctx
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                    label: Some("multigrid.mips"),
                });
            {
                let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some("multigrid.mips"),
                    timestamp_writes: None,
                });
                for op in &self.steps {
                    self.table.dispatch(&self.pipelines, &mut pass, op);
                }
            }
            if let Some((dst, offset)) = top {
                let off = min_max_offsets(self.n);
                let top_cell = (off[off.len() - 2] * 8) as u64;
                enc.copy_buffer_to_buffer(&self.minmax, top_cell, dst, offset, 8);
            }
            self.ctx.submit([enc.finish()]);
            Ok(())
        })
    }

    /// The height texture (texel (i, j) = cell (i, j), row 0 = south).
    pub fn texture(&self) -> &wgpu::Texture {
        &self.texture
    }

    /// Number of mips (log2 n + 1, down to 1x1).
    pub fn mip_count(&self) -> usize {
        self.n.trailing_zeros() as usize + 1
    }

    /// Mip `k` read back (side `n >> k`, row 0 = south).
    pub fn read_mip(&self, k: usize) -> Result<Vec<f32>, GpuError> {
        if k >= self.mip_count() {
            return Err(GpuError::BadLevel {
                level: k,
                levels: self.mip_count(),
            });
        }
        self.ctx.checked("multigrid.mips.read", || {
            readback::read_texture_r32(
                &self.ctx,
                &self.texture,
                k as u32,
                (self.n >> k) as u32,
                "height mip",
            )
        })
    }

    /// Bytes of the min/max pyramid read back by [`Self::read_min_max`] (43,688 for sides >= 64).
    pub fn min_max_bytes(&self) -> u64 {
        self.minmax.size()
    }

    /// The min/max pyramid, finest stored level (side `min(n, 64)`) first, as [`crate::pyramid::minmax_pyramid`].
    pub fn read_min_max(&self) -> Result<Vec<MinMaxLevel>, GpuError> {
        let off = min_max_offsets(self.n);
        let flat = self.ctx.checked("multigrid.mips.read_min_max", || {
            readback::read_f32(
                &self.ctx,
                &self.minmax,
                0,
                (off[off.len() - 1] * 2) as u64,
                "min/max pyramid",
            )
        })?;
        Ok(self.levels_of(&flat))
    }

    /// [`Self::update`], then the min/max pyramid copied to a staging buffer whose mapping is
    /// requested without waiting, unless an earlier one is still pending (then that one will be
    /// read, and a later update copies again). [`Self::try_min_max`] reads it.
    pub fn update_and_request_min_max(&self) -> Result<(), GpuError> {
        self.update()?;
        let mut pending = self
            .minmax_pending
            .lock()
            .map_err(|_| GpuError::ProblemMismatch("min/max staging lock poisoned".into()))?;
        if pending.is_none() {
            self.ctx.checked("multigrid.mips.request_min_max", || {
                let mut enc =
                    self.ctx
                        .device
                        .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                            label: Some("multigrid.mips.request_min_max"),
                        });
                enc.copy_buffer_to_buffer(
                    &self.minmax,
                    0,
                    &self.minmax_staging,
                    0,
                    self.minmax.size(),
                );
                self.ctx.submit([enc.finish()]);
                Ok(())
            })?;
            *pending = Some(readback::request_map(
                &self.minmax_staging,
                self.minmax.size(),
            ));
        }
        Ok(())
    }

    /// The min/max pyramid [`Self::update_and_request_min_max`] asked for, if the device has
    /// delivered it (a non-blocking poll); `None` otherwise. Never waits.
    pub fn try_min_max(&self) -> Result<Option<Vec<MinMaxLevel>>, GpuError> {
        let mut pending = self
            .minmax_pending
            .lock()
            .map_err(|_| GpuError::ProblemMismatch("min/max staging lock poisoned".into()))?;
        let Some(rx) = pending.as_ref() else {
            return Ok(None);
        };
        self.ctx
            .poll_nonblocking()
            .map_err(|e| GpuError::Readback {
                what: "min/max pyramid".into(),
                message: e.to_string(),
            })?;
        let size = self.minmax.size();
        let Some(bytes) = readback::finish_map(
            &self.ctx,
            &self.minmax_staging,
            size,
            rx,
            false,
            "min/max pyramid",
        )?
        else {
            return Ok(None);
        };
        *pending = None;
        Ok(Some(self.levels_of(&readback::f32s(&bytes))))
    }

    /// The levels of a flat min/max pyramid.
    fn levels_of(&self, flat: &[f32]) -> Vec<MinMaxLevel> {
        let off = min_max_offsets(self.n);
        let mut out = Vec::new();
        let mut side = minmax_finest_side(self.n);
        for w in off.windows(2) {
            let cells = flat[2 * w[0]..2 * w[1]]
                .chunks_exact(2)
                .map(|c| [c[0], c[1]])
                .collect();
            out.push(MinMaxLevel { side, cells });
            side /= 2;
        }
        out
    }

    /// Bytes of every texture and buffer this object allocated.
    pub fn gpu_bytes(&self) -> u64 {
        self.gpu_bytes
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pyramid::MINMAX_MAX_SIDE;

    #[test]
    fn offsets() {
        assert_eq!(constraint_offsets(4), vec![0, 4, 5]);
        let m = min_max_offsets(256);
        assert_eq!(m.len(), 8);
        assert_eq!(m[7] * 8, 43_688);
        assert_eq!(min_max_offsets(16), vec![0, 256, 320, 336, 340, 341]);
        assert_eq!(minmax_finest_side(4096), MINMAX_MAX_SIDE);
    }
}
