//! [`GpuRaster`]: the constraint maps of a sketch rasterised on the GPU (`rasterize.wgsl`, the twin of
//! [`crate::constraints`]) straight into the height problem's `weight` / `value` buffers, the
//! roughness problem straight onto level 2 (the rasteriser sums its texels' roughness in 4 x 4
//! blocks as [`crate::fields::downsample_weighted`] does: no level-0 roughness map exists), plus the
//! downsampled gradient-field problem (`downsample_fields.wgsl`, the twin of
//! [`crate::fields::downsample_weighted`]) straight into its solver's buffers. Only the stroke
//! geometry goes up (a few KB). The value ranges (the problems' reliefs) stay on the GPU: each
//! solver's scalar block is scaled by its problem's relief there (`relief_scale.wgsl`, see
//! [`GpuRaster::encode_relief`]). They come back (32 bytes, one wait) only when the CPU cannot tell
//! from the geometry whether any elevation constraint exists (every stroke outside the map).

use terrasketch_sketch::{Sketch, StrokeKind};

use super::kernels::{PassSpec, PassTable, Pipelines, Res};
use super::params::Params;
use super::resources::{Buffers, Slice, VY_HOME};
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

/// The `downsample_fields` passes, in the order they run (see `Buffers`: the y pass writes `vy`
/// into the heights' `diag`, which holds the gradient x map the x pass reads).
const DS_GRAD_X: u8 = 0;
const DS_GRAD_Y: u8 = 1;
const DS_ROUGH_RANGE: u8 = 2;
const DS_ELEV_RANGE: u8 = 3;

/// One `downsample_fields` pass: `key`, source side `n`, block side `f`, `(weight, value)`
/// sources, `(weight, value)` destinations (the weight not written with `values_only`; neither with
/// `f == 1`), `stats` and the plane's slot.
#[allow(clippy::too_many_arguments)]
fn ds_spec<'a>(
    key: u8,
    n: usize,
    f: usize,
    values_only: bool,
    src: [&'a Slice; 2],
    dst: [&'a Slice; 2],
    stats: &'a wgpu::Buffer,
    slot: u32,
) -> PassSpec<'a, u8> {
    let nc = (n / f) as u32;
    PassSpec {
        key,
        kernel: Kernel::DownsampleFields,
        params: Params {
            n: n as u32,
            mode: f as u32,
            slot_or_cold: slot,
            values_only: values_only as u32,
            ..Params::default()
        },
        resources: vec![
            Res::Slice(src[0]),
            Res::Slice(src[1]),
            Res::Slice(dst[0]),
            Res::Slice(dst[1]),
            Res::Buffer(stats),
        ],
        workgroups: [nc.div_ceil(8), nc.div_ceil(8), 1],
        label: format!("multigrid.downsample_fields.{key}"),
    }
}

/// The outputs of `rasterize.wgsl`, all aliases of the height solver's buffers: the elevation
/// weight and value are its problem; the band weight lives in `r`, the gradient planes in `diag` and
/// `z`; the roughness problem (level 2) is roughness's `weight` and `value`, adjacent ranges of the
/// heights' `p` bound as one (`rough`: weight plane, then value plane). All but the problem are
/// dead until the height operator is assembled. The downsample passes read the gradient planes
/// (the y pass after the x pass) and write the gradient problem into ranges of the heights' `p` and
/// `vy` into their `diag` (the fields' level-0 buffers live there: see `Buffers`); the band stays
/// in `r` for the height assembly, which computes the edge differences from it (without writing
/// `r`) and rebuilds `diag` and the stencils.
#[derive(Clone)]
struct Targets {
    ew: Slice,
    ev: Slice,
    band: Slice,
    gx: Slice,
    gy: Slice,
    rough: Slice,
    /// The roughness problem's side and its two planes (views of `rough`).
    rough_n: usize,
    rough_w: Slice,
    rough_v: Slice,
}

/// The GPU rasteriser of one [`crate::gpu_solver::GpuSolver`].
pub struct GpuRaster {
    ctx: GpuContext,
    n: usize,
    cell_m: [f32; 3],
    pipelines: Pipelines,
    geom: wgpu::Buffer,
    raster: PassTable<()>,
    downsample: PassTable<u8>,
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
            let pipelines = Pipelines::new(
                ctx,
                &[
                    Kernel::Rasterize,
                    Kernel::DownsampleFields,
                    Kernel::ReliefScale,
                ],
            );
            let h = &heights.bufs;
            let (home, units) = VY_HOME;
            let vy = h
                .host_range(home)
                .and_then(|s| s.part(units * (n * n / 4) as u64, (n * n) as u64))
                .ok_or_else(|| GpuError::ProblemMismatch(format!("no room for vy in {home}")))?;
            // The roughness problem's weight and value planes, adjacent in the heights' `p`, are
            // one binding of the rasteriser (which binds as many storage buffers as it may).
            let (rw, rv) = (&rough.bufs.weight, &rough.bufs.value);
            if rv.buffer != rw.buffer || rv.offset != rw.offset + rw.size {
                return Err(GpuError::ProblemMismatch(
                    "the roughness problem's weight and value are not adjacent".into(),
                ));
            }
            let rough_planes = Slice {
                buffer: rw.buffer.clone(),
                offset: rw.offset,
                size: rw.size + rv.size,
            };
            let t = Targets {
                ew: h.weight.clone(),
                ev: h.value.clone(),
                band: h.r.clone(),
                gx: h.diag.clone(),
                gy: h.z.clone(),
                rough: rough_planes,
                rough_n: rough.n(),
                rough_w: rw.clone(),
                rough_v: rv.clone(),
            };
            let downsample = downsample_table(ctx, &pipelines, n, &t, grad, &vy, h, &stats);
            let relief = relief_table(ctx, &pipelines, [heights, grad, rough], &stats);
            let mut r = GpuRaster {
                ctx: ctx.clone(),
                n,
                cell_m: [dx as f32, dy as f32, dx.max(dy) as f32],
                raster: PassTable::new(ctx, &pipelines, "multigrid.raster.params", vec![]),
                pipelines,
                geom,
                downsample,
                relief,
                targets: t,
                bytes: stats.size() + STATS_BYTES,
                vy,
                stats,
                stats_read,
            };
            r.raster = r.raster_table();
            r.bytes += r.raster.bytes + r.downsample.bytes + r.relief.bytes;
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
                Res::Slice(&t.gx),
                Res::Slice(&t.gy),
                Res::Slice(&t.rough),
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

    /// Rasterises `sketch` (the level-0 maps and the roughness problem) and, with `downsample`,
    /// downsamples the gradient problem and computes the value ranges on the GPU (without it, only
    /// the rasteriser runs, for [`Self::read_maps`]: the gradient y pass overwrites part of the
    /// gradient x map; the ranges are then meaningless). Returns whether any elevation constraint
    /// exists: from the geometry when it tells (no wait), else from the ranges read back (one
    /// wait; `downsample` only, else `true`). Overwrites the height solver's problem and scratch
    /// vectors: it must be assembled next.
    pub(crate) fn run(
        &mut self,
        sketch: &Sketch,
        grid: &Grid,
        downsample: bool,
    ) -> Result<bool, GpuError> {
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
                // Gradient x before y: the y pass writes `vy` into the heights' `diag`, which
                // holds the gradient x map the x pass reads (see `Buffers`).
                if downsample {
                    for k in [DS_GRAD_X, DS_GRAD_Y, DS_ROUGH_RANGE, DS_ELEV_RANGE] {
                        self.downsample.dispatch(&self.pipelines, &mut pass, &k);
                    }
                }
            }
            ctx.submit([enc.finish()]);
            Ok(())
        })?;
        match elevation {
            Some(known) => Ok(known),
            None if downsample => Ok(self.read_stats()?.elevation.is_some()),
            None => Ok(true),
        }
    }

    /// The value ranges of the last [`Self::run`] with `downsample` (one wait).
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

    /// Reads what the last [`Self::run`] wrote without downsampling (right after it: the buffers
    /// are reused): the level-0 maps, without roughness maps (`rough_weight`, `rough_value` empty:
    /// the GPU has none), and the roughness problem on level 2 (`weight`, `value`; `ax`, `ay` of
    /// `grid`).
    pub fn read_maps(&self, grid: &Grid) -> Result<(ConstraintMaps, FieldProblem), GpuError> {
        let n = self.n;
        let cells = (n * n) as u64;
        let ctx = &self.ctx;
        let t = &self.targets;
        let read = |b: &Slice, count: u64, what: &str| {
            super::readback::read_f32(ctx, &b.buffer, b.first_f32(), count, what)
        };
        let mut m = ConstraintMaps::new(n);
        let rn = t.rough_n;
        let [ax, ay] = grid.axis_weights();
        let mut rough = FieldProblem {
            n: rn,
            ax,
            ay,
            ..FieldProblem::default()
        };
        ctx.checked("multigrid.raster.read", || {
            m.elev_weight = read(&t.ew, cells, "elevation weight")?;
            m.elev_value = read(&t.ev, cells, "elevation value")?;
            m.band_weight = read(&t.band, cells, "band weight")?;
            m.grad_x = read(&t.gx, cells, "gradient x")?;
            m.grad_y = read(&t.gy, cells, "gradient y")?;
            m.rough_weight = Vec::new();
            m.rough_value = Vec::new();
            rough.weight = read(&t.rough_w, (rn * rn) as u64, "roughness weight")?;
            rough.value = read(&t.rough_v, (rn * rn) as u64, "roughness value")?;
            Ok(())
        })?;
        Ok((m, rough))
    }
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

/// The downsampling passes: the gradient field's problem (x with its weight, then y into `vy`) onto
/// level 1, and the value ranges of the roughness and elevation constraints.
#[allow(clippy::too_many_arguments)]
fn downsample_table(
    ctx: &GpuContext,
    pipelines: &Pipelines,
    n: usize,
    t: &Targets,
    grad: &GpuFieldSolver,
    vy: &Slice,
    h: &Buffers,
    stats: &wgpu::Buffer,
) -> PassTable<u8> {
    PassTable::new(
        ctx,
        pipelines,
        "multigrid.raster.downsample.params",
        vec![
            ds_spec(
                DS_GRAD_X,
                n,
                2,
                false,
                [&t.band, &t.gx],
                [&grad.bufs.weight, &grad.bufs.value],
                stats,
                2,
            ),
            // Values only (the weight is the x pass's), into `vy` (in `diag`, which
            // this pass does not read).
            ds_spec(DS_GRAD_Y, n, 2, true, [&t.band, &t.gy], [vy, vy], stats, 4),
            // Value ranges only: with f = 1 the pass writes no map, its outputs are
            // bound (to buffers it does not read) but untouched.
            ds_spec(
                DS_ROUGH_RANGE,
                t.rough_n,
                1,
                false,
                [&t.rough_w, &t.rough_v],
                [&h.diag, &h.diag],
                stats,
                6,
            ),
            ds_spec(
                DS_ELEV_RANGE,
                n,
                1,
                false,
                [&t.ew, &t.ev],
                [&h.f, &h.f],
                stats,
                0,
            ),
        ],
    )
}
