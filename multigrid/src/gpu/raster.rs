//! [`GpuRaster`]: the constraint maps of a sketch rasterised on the GPU (`rasterize.wgsl`, the twin of
//! [`crate::constraints`]) in one pass straight into the height problem's `weight` / `value`
//! buffers, the gradient-field problem straight onto level 1 and the roughness problem onto level 2
//! (the rasteriser sums its texels' band-weighted gradient in 2 x 2 blocks and their roughness in
//! 4 x 4 blocks as [`crate::fields::downsample_weighted`] does: no level-0 gradient or roughness map
//! exists), with the problems' value ranges. Only the stroke
//! geometry goes up (a few KB). The value ranges (the problems' reliefs) stay on the GPU: each
//! solver's scalar block is scaled by its problem's relief there (`relief_scale.wgsl`, see
//! [`GpuRaster::encode_relief`]). They come back (32 bytes, one wait) only when the CPU cannot tell
//! from the geometry whether any elevation constraint exists (every stroke outside the map).

use terrasketch_sketch::{Sketch, StrokeKind};

use super::kernels::{PassSpec, PassTable, Pipelines, Res};
use super::params::Params;
use super::resources::{Slice, VY_HOME};
use super::shaders::Kernel;
use super::{GpuContext, GpuError, GpuFieldSolver};
use crate::constraints::{ConstraintMaps, PreparedSketch};
use crate::grid::Grid;
use crate::problem::FieldProblem;

/// Words of one stroke record in the geometry buffer.
const STROKE_WORDS: usize = 16;
/// Words of one segment record.
const SEG_WORDS: usize = 8;
/// Words of one chunk record (a run of a stroke's segments and its box).
const CHUNK_WORDS: usize = 8;
/// Stats slots: elevation, gradient x, gradient y, roughness (min key, max key each).
const STATS_BYTES: u64 = 32;

/// Value ranges of the rasterised problems.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RasterStats {
    /// `[min, max]` of the elevation values over weighted texels (None: no elevation constraint).
    pub elevation: Option<[f32; 2]>,
    /// The same for the gradient-field problems (x and y) and the roughness problem.
    pub grad_x: Option<[f32; 2]>,
    /// See `grad_x`.
    pub grad_y: Option<[f32; 2]>,
    /// See `grad_x`.
    pub roughness: Option<[f32; 2]>,
}

fn from_key(k: u32) -> f32 {
    let bits = if k & 0x8000_0000 != 0 {
        k & 0x7fff_ffff
    } else {
        !k
    };
    f32::from_bits(bits)
}

/// The stroke geometry as `rasterize.wgsl` reads it (see its header): the strokes as
/// `constraints::PreparedSketch` prepares them (each curve's fine polyline, strokes without finite
/// points skipped, segments that are a point seen from above dropped, a stroke of only such
/// segments one dot, widths below 0 are 0, slopes clamped to 0..89 degrees, roughness to 0..1),
/// their segments in runs of `CHUNK_SEGS` with the runs' boxes.
pub fn pack_geometry(sketch: &Sketch, grid: &Grid) -> Vec<f32> {
    pack(sketch, grid).0
}

/// [`pack_geometry`], and what the geometry says of the elevation constraints without
/// rasterising: `Some(false)` no stroke, `Some(true)` a stroke point inside the map (the texel
/// whose cell holds it is within `c / sqrt(2)` of the curve, so its elevation weight is at least
/// `1.5 - 0.71 > 0`), `None` every point outside (only the rasteriser can tell).
fn pack(sketch: &Sketch, grid: &Grid) -> (Vec<f32>, Option<bool>) {
    let [dx, dy] = grid.cell_size_m();
    let cell = dx.max(dy);
    let prepared = PreparedSketch::new(sketch, grid).strokes;
    let [ex, ey] = grid.extent_m;
    let inside = |p: [f64; 3]| (0.0..=ex).contains(&p[0]) && (0.0..=ey).contains(&p[1]);
    let elevation = if prepared.is_empty() {
        Some(false)
    } else if prepared
        .iter()
        .any(|p| p.segs.iter().any(|s| inside(s.a) || inside(s.b)))
    {
        Some(true)
    } else {
        None
    };
    let chunk_count: usize = prepared.iter().map(|p| p.chunks.len()).sum();
    let seg_count: usize = prepared.iter().map(|p| p.segs.len()).sum();
    let chunk_base = 4 + STROKE_WORDS * prepared.len();
    let seg_base = chunk_base + CHUNK_WORDS * chunk_count;
    let mut out = Vec::with_capacity(seg_base + SEG_WORDS * seg_count);
    let word = |v: usize| f32::from_bits(v as u32);
    out.extend_from_slice(&[word(prepared.len()), 0.0, 0.0, 0.0]);
    let (mut chunk, mut seg) = (0, 0);
    for p in &prepared {
        let reach = p.width_m as f64 + 1.5 * cell;
        let bbox = p.chunks.iter().fold(
            [
                f64::INFINITY,
                f64::NEG_INFINITY,
                f64::INFINITY,
                f64::NEG_INFINITY,
            ],
            |b, c| {
                [
                    b[0].min(c.bbox[0]),
                    b[1].max(c.bbox[1]),
                    b[2].min(c.bbox[2]),
                    b[3].max(c.bbox[3]),
                ]
            },
        );
        let kind = match p.kind {
            StrokeKind::Ridge => 0,
            StrokeKind::Valley => 1,
            StrokeKind::Plateau => 2,
        };
        out.extend_from_slice(&[
            word(chunk_base + CHUNK_WORDS * chunk),
            word(p.chunks.len()),
            word(kind),
            p.inv_width,
            p.tan_left,
            p.tan_right,
            p.width_m,
            p.roughness,
            reach as f32,
            bbox[0] as f32,
            bbox[1] as f32,
            bbox[2] as f32,
            bbox[3] as f32,
            p.falloff[0],
            p.falloff[1],
            p.falloff[2],
        ]);
        chunk += p.chunks.len();
    }
    for p in &prepared {
        for c in &p.chunks {
            out.extend_from_slice(&[
                c.bbox[0] as f32,
                c.bbox[1] as f32,
                c.bbox[2] as f32,
                c.bbox[3] as f32,
                word(seg_base + SEG_WORDS * (seg + c.segs.start)),
                word(c.segs.len()),
                0.0,
                0.0,
            ]);
        }
        seg += p.segs.len();
    }
    for p in &prepared {
        for s in &p.segs {
            let (a, b) = (s.a, s.b);
            let (ex, ey) = (b[0] - a[0], b[1] - a[1]);
            let len2 = ex * ex + ey * ey;
            let inv = if len2 > 0.0 { 1.0 / len2 } else { 0.0 };
            out.extend_from_slice(&[
                a[0] as f32,
                a[1] as f32,
                a[2] as f32,
                b[0] as f32,
                b[1] as f32,
                b[2] as f32,
                inv as f32,
                0.0,
            ]);
        }
    }
    (out, elevation)
}

/// The outputs of `rasterize.wgsl`, all aliases of the height solver's buffers: the elevation
/// weight and value are its problem; the band weight lives in `r` (dead until the height operator
/// is assembled, which computes the edge differences from it without writing `r`); the gradient
/// problem (level 1) is the gradient field's `weight` and `value`, adjacent ranges of the heights'
/// `p` bound as one (`grad`: weight plane, then x value plane), its y values `vy` a range of their
/// `diag`; the roughness problem (level 2) is roughness's `weight` and `value`, adjacent ranges of
/// the heights' `p` bound as one (`rough`). See `Buffers` for when each range is live.
#[derive(Clone)]
struct Targets {
    ew: Slice,
    ev: Slice,
    band: Slice,
    grad: Planes,
    rough: Planes,
}

/// A field problem the rasteriser writes: its solver's weight and value planes, adjacent, bound as
/// one range (`both`: weight plane, then value plane), and its side.
#[derive(Clone)]
struct Planes {
    both: Slice,
    n: usize,
    weight: Slice,
    value: Slice,
}

impl Planes {
    /// The planes of `solver`'s problem (`what` names it in the error when they are not adjacent).
    fn of(solver: &GpuFieldSolver, what: &str) -> Result<Planes, GpuError> {
        let (w, v) = (&solver.bufs.weight, &solver.bufs.value);
        if v.buffer != w.buffer || v.offset != w.offset + w.size {
            return Err(GpuError::ProblemMismatch(format!(
                "the {what} problem's weight and value are not adjacent"
            )));
        }
        Ok(Planes {
            both: Slice {
                buffer: w.buffer.clone(),
                offset: w.offset,
                size: w.size + v.size,
            },
            n: solver.n(),
            weight: w.clone(),
            value: v.clone(),
        })
    }

    /// The problem read back, with the axis weights `[ax, ay]`.
    fn read(
        &self,
        ctx: &GpuContext,
        [ax, ay]: [f32; 2],
        what: &str,
    ) -> Result<FieldProblem, GpuError> {
        let cells = (self.n * self.n) as u64;
        let read = |b: &Slice, part: &str| {
            super::readback::read_f32(
                ctx,
                &b.buffer,
                b.first_f32(),
                cells,
                &format!("{what} {part}"),
            )
        };
        Ok(FieldProblem {
            n: self.n,
            ax,
            ay,
            weight: read(&self.weight, "weight")?,
            value: read(&self.value, "values")?,
            ..FieldProblem::default()
        })
    }
}

/// The GPU rasteriser of one [`crate::gpu_solver::GpuSolver`].
pub struct GpuRaster {
    ctx: GpuContext,
    n: usize,
    cell_m: [f32; 3],
    pipelines: Pipelines,
    geom: wgpu::Buffer,
    raster: PassTable<()>,
    relief: PassTable<ReliefOf>,
    targets: Targets,
    /// The y component of the gradient problem's values (copied into the solver for the second
    /// solve): a range of the height solver's `diag` (`VY_HOME`, see `Buffers`).
    pub(crate) vy: Slice,
    stats: wgpu::Buffer,
    stats_read: wgpu::Buffer,
    /// Bytes allocated (without the geometry buffer, which grows with the sketch).
    pub bytes: u64,
}

impl GpuRaster {
    /// Passes for an `n x n` grid writing into `heights` (its problem, and its scratch buffers for the
    /// other level-0 maps, see `Targets`) and the problems of `grad` (level 1) and `rough` (level 2).
    pub(crate) fn new(
        ctx: &GpuContext,
        grid: &Grid,
        heights: &GpuFieldSolver,
        grad: &GpuFieldSolver,
        rough: &GpuFieldSolver,
    ) -> Result<GpuRaster, GpuError> {
        let n = grid.n;
        let [dx, dy] = grid.cell_size_m();
        ctx.checked("multigrid.raster.new", || {
            let storage = |label: &str, bytes: u64| {
                ctx.device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some(label),
                    size: bytes.max(4),
                    usage: wgpu::BufferUsages::STORAGE
                        | wgpu::BufferUsages::COPY_DST
                        | wgpu::BufferUsages::COPY_SRC,
                    mapped_at_creation: false,
                })
            };
            let stats = storage("multigrid.raster.stats", STATS_BYTES);
            let stats_read = ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("multigrid.raster.stats_read"),
                size: STATS_BYTES,
                usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            let geom = storage("multigrid.raster.geom", 4096);
            let pipelines = Pipelines::new(ctx, &[Kernel::Rasterize, Kernel::ReliefScale]);
            let h = &heights.bufs;
            let (home, units) = VY_HOME;
            let vy = h
                .host_range(home)
                .and_then(|s| s.part(units * (n * n / 4) as u64, (n * n) as u64))
                .ok_or_else(|| GpuError::ProblemMismatch(format!("no room for vy in {home}")))?;
            // The gradient and roughness problems' weight and value planes, adjacent in the
            // heights' `p`, are one binding each of the rasteriser (which binds as many storage
            // buffers as it may).
            let t = Targets {
                ew: h.weight.clone(),
                ev: h.value.clone(),
                band: h.r.clone(),
                grad: Planes::of(grad, "gradient")?,
                rough: Planes::of(rough, "roughness")?,
            };
            let relief = relief_table(ctx, &pipelines, [heights, grad, rough], &stats);
            let mut r = GpuRaster {
                ctx: ctx.clone(),
                n,
                cell_m: [dx as f32, dy as f32, dx.max(dy) as f32],
                raster: PassTable::new(ctx, &pipelines, "multigrid.raster.params", vec![]),
                pipelines,
                geom,
                relief,
                targets: t,
                bytes: stats.size() + STATS_BYTES,
                vy,
                stats,
                stats_read,
            };
            r.raster = r.raster_table();
            r.bytes += r.raster.bytes + r.relief.bytes;
            Ok(r)
        })
    }

    fn raster_table(&self) -> PassTable<()> {
        let n = self.n as u32;
        let t = &self.targets;
        let spec = PassSpec {
            key: (),
            kernel: Kernel::Rasterize,
            params: Params {
                n,
                ax: self.cell_m[0],
                ay: self.cell_m[1],
                threshold: self.cell_m[2],
                ..Params::default()
            },
            resources: vec![
                Res::Buffer(&self.geom),
                Res::Slice(&t.ew),
                Res::Slice(&t.ev),
                Res::Slice(&t.band),
                Res::Slice(&t.grad.both),
                Res::Slice(&self.vy),
                Res::Slice(&t.rough.both),
                Res::Buffer(&self.stats),
            ],
            workgroups: [n.div_ceil(8), n.div_ceil(8), 1],
            label: "multigrid.rasterize".into(),
        };
        PassTable::new(
            &self.ctx,
            &self.pipelines,
            "multigrid.raster.params",
            vec![spec],
        )
    }

    /// Rasterises `sketch` (the level-0 maps, the gradient and roughness problems and their value
    /// ranges, in one pass). Returns whether any elevation constraint exists: from the geometry
    /// when it tells (no wait), else from the ranges read back (one wait). Overwrites the height
    /// solver's problem and scratch vectors: it must be assembled next.
    pub(crate) fn run(&mut self, sketch: &Sketch, grid: &Grid) -> Result<bool, GpuError> {
        let (geom, elevation) = pack(sketch, grid);
        let bytes = (geom.len() * 4) as u64;
        let limit = self.ctx.device.limits().max_storage_buffer_binding_size;
        if bytes > limit {
            return Err(GpuError::ProblemMismatch(format!(
                "the sketch's geometry ({bytes} bytes) exceeds the device's storage binding limit ({limit})"
            )));
        }
        let ctx = self.ctx.clone();
        if bytes > self.geom.size() {
            let size = bytes.next_power_of_two().min(limit);
            self.geom = ctx.checked("multigrid.raster.geom", || {
                Ok(ctx.device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("multigrid.raster.geom"),
                    size,
                    usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
                    mapped_at_creation: false,
                }))
            })?;
            self.raster = ctx.checked("multigrid.raster.table", || Ok(self.raster_table()))?;
        }
        ctx.checked("multigrid.raster.run", || {
            let q = &ctx.queue;
            q.write_buffer(&self.geom, 0, bytemuck::cast_slice(&geom));
            let init: [u32; 8] = [u32::MAX, 0, u32::MAX, 0, u32::MAX, 0, u32::MAX, 0];
            q.write_buffer(&self.stats, 0, bytemuck::cast_slice(&init));
            ctx.count_up(bytes + STATS_BYTES);
            let mut enc = ctx
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                    label: Some("multigrid.raster"),
                });
            {
                let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some("multigrid.raster"),
                    timestamp_writes: None,
                });
                self.raster.dispatch(&self.pipelines, &mut pass, &());
            }
            ctx.submit([enc.finish()]);
            Ok(())
        })?;
        match elevation {
            Some(known) => Ok(known),
            None => Ok(self.read_stats()?.elevation.is_some()),
        }
    }

    /// The value ranges of the last [`Self::run`] (one wait).
    pub fn read_stats(&self) -> Result<RasterStats, GpuError> {
        let ctx = &self.ctx;
        let raw = ctx.checked("multigrid.raster.stats", || {
            let mut enc = ctx
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                    label: Some("multigrid.raster.stats"),
                });
            enc.copy_buffer_to_buffer(&self.stats, 0, &self.stats_read, 0, STATS_BYTES);
            ctx.submit([enc.finish()]);
            super::readback::map_read(ctx, &self.stats_read, STATS_BYTES, "raster stats")
        })?;
        let k: Vec<u32> = raw
            .chunks_exact(4)
            .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect();
        let range = |s: usize| (k[s] != u32::MAX).then(|| [from_key(k[s]), from_key(k[s + 1])]);
        Ok(RasterStats {
            elevation: range(0),
            grad_x: range(2),
            grad_y: range(4),
            roughness: range(6),
        })
    }

    /// Records `relief_scale` for one problem of the last [`Self::run`]: its relief from its value
    /// range, into its solver's scalar block, whose `relax_limit` and `stop_rmax` (written by the
    /// CPU as normalised residuals) it scales. Must follow the CPU's write of that block.
    pub(crate) fn encode_relief(&self, enc: &mut wgpu::CommandEncoder, problem: ReliefOf) {
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("multigrid.relief_scale"),
            timestamp_writes: None,
        });
        self.relief.dispatch(&self.pipelines, &mut pass, &problem);
    }

    /// Reads what the last [`Self::run`] wrote (right after it: the buffers are reused): the
    /// level-0 maps, without gradient or roughness maps (empty: the GPU has none), and the
    /// gradient and roughness problems (`ax`, `ay` of `grid`), and their value ranges.
    pub fn read_maps(&self, grid: &Grid) -> Result<RasterMaps, GpuError> {
        let n = self.n;
        let cells = (n * n) as u64;
        let ctx = &self.ctx;
        let t = &self.targets;
        let axes = grid.axis_weights();
        let stats = self.read_stats()?;
        ctx.checked("multigrid.raster.read", || {
            let read = |b: &Slice, count: u64, what: &str| {
                super::readback::read_f32(ctx, &b.buffer, b.first_f32(), count, what)
            };
            // No level-0 gradient or roughness maps: they stay empty.
            let mut maps = ConstraintMaps::new(n);
            maps.elev_weight = read(&t.ew, cells, "elevation weight")?;
            maps.elev_value = read(&t.ev, cells, "elevation value")?;
            maps.band_weight = read(&t.band, cells, "band weight")?;
            for v in [
                &mut maps.grad_x,
                &mut maps.grad_y,
                &mut maps.rough_weight,
                &mut maps.rough_value,
            ] {
                *v = Vec::new();
            }
            let gradient = t.grad.read(ctx, axes, "gradient")?;
            let gradient_y = read(&self.vy, (t.grad.n * t.grad.n) as u64, "gradient y values")?;
            Ok(RasterMaps {
                maps,
                gradient,
                gradient_y,
                roughness: t.rough.read(ctx, axes, "roughness")?,
                stats,
            })
        })
    }
}

/// What [`GpuRaster::read_maps`] reads back.
pub struct RasterMaps {
    /// The level-0 elevation and band maps (the gradient and roughness maps empty).
    pub maps: ConstraintMaps,
    /// The gradient-field problem on level 1 (values: the x component), as
    /// [`crate::fields::gradient_problem`] makes it.
    pub gradient: FieldProblem,
    /// Its y values.
    pub gradient_y: Vec<f32>,
    /// The roughness problem on level 2, as [`crate::fields::roughness_problem`] makes it.
    pub roughness: FieldProblem,
    /// The value ranges of the four problems.
    pub stats: RasterStats,
}

/// The problems whose relief [`GpuRaster::encode_relief`] computes, with their stats slots.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub(crate) enum ReliefOf {
    /// The heights (elevation constraints, slot 0).
    Heights,
    /// The gradient field's x component (slot 2).
    GradX,
    /// Its y component (slot 4).
    GradY,
    /// Roughness (slot 6).
    Roughness,
}

/// One `relief_scale` pass per problem, each into its solver's scalar block.
fn relief_table(
    ctx: &GpuContext,
    pipelines: &Pipelines,
    [heights, grad, rough]: [&GpuFieldSolver; 3],
    stats: &wgpu::Buffer,
) -> PassTable<ReliefOf> {
    fn spec<'a>(
        key: ReliefOf,
        solver: &'a GpuFieldSolver,
        slot: u32,
        stats: &'a wgpu::Buffer,
    ) -> PassSpec<'a, ReliefOf> {
        let [ax, ay] = solver.axis_weights();
        PassSpec {
            key,
            kernel: Kernel::ReliefScale,
            params: Params {
                ax,
                ay,
                slot_or_cold: slot,
                ..Params::default()
            },
            resources: vec![Res::Buffer(stats), Res::Buffer(&solver.bufs.scalars)],
            workgroups: [1, 1, 1],
            label: format!("multigrid.relief_scale.{key:?}"),
        }
    }
    PassTable::new(
        ctx,
        pipelines,
        "multigrid.relief_scale.params",
        vec![
            spec(ReliefOf::Heights, heights, 0, stats),
            spec(ReliefOf::GradX, grad, 2, stats),
            spec(ReliefOf::GradY, grad, 4, stats),
            spec(ReliefOf::Roughness, rough, 6, stats),
        ],
    )
}
