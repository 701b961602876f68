//! Rasterisation of strokes into level-0 constraint maps.
//!
//! Every stroke is first turned into its curve's fine polyline (`terrasketch_sketch::stroke_curve`,
//! shared with the GPU twin and the editor). Per texel and per stroke, the closest point on that
//! polyline (in metres, seen from above) decides everything: its distance `d`, its height `z`, the side (left/right of the direction of
//! travel) and the direction `n` from the curve to the texel. With `c` the larger cell side:
//! - elevation weight `clamp(1.5 - d / c, 0, 1)`: hard (1) within half a cell of the curve, so a curve is
//!   never thinner than one texel (at least 8-connected), anti-aliased over the next cell; plateaus extend
//!   the hard core to `width_m`;
//! - band weight `clamp((width_m - d) / c + 0.5, 0, 1)` for ridges and valleys, with the gradient
//!   `-tan(slope) f(d / width_m) n` (ridge: falls away) or `+tan(slope) f(d / width_m) n` (valley:
//!   rises away), `f` the stroke's falloff profile (`Falloff`: 1 at the curve, fading to 0 at the
//!   band edge so the slope eases into the land instead of stopping dead);
//! - roughness over the whole footprint.
//!
//! Where strokes overlap, the closest stroke gives the values and the weights are the maxima, so the
//! result does not depend on drawing order except for exact ties (later wins).

use rayon::prelude::*;
use terrasketch_sketch::{Curve, Sketch, Stroke, StrokeKind};

use crate::cpu::rows::{mask, sel};
use crate::cpu::simd::multiversion;
use crate::grid::Grid;

/// Level-0 constraint maps. All arrays are `n * n`, row 0 = south, index `j * n + i`.
#[derive(Debug, Clone, PartialEq)]
pub struct ConstraintMaps {
    /// Cells per side.
    pub n: usize,
    /// Elevation constraint weight in [0, 1] (1 = hard).
    pub elev_weight: Vec<f32>,
    /// Constrained elevation, metres.
    pub elev_value: Vec<f32>,
    /// Gradient band coverage in [0, 1] (ridges and valleys).
    pub band_weight: Vec<f32>,
    /// Prescribed gradient, x component (dz/dx, unitless).
    pub grad_x: Vec<f32>,
    /// Prescribed gradient, y component (dz/dy, unitless).
    pub grad_y: Vec<f32>,
    /// Roughness constraint weight (stroke footprint coverage).
    pub rough_weight: Vec<f32>,
    /// Constrained roughness in [0, 1].
    pub rough_value: Vec<f32>,
}

/// Consecutive segments per chunk: a chunk's box (the union of its segments' boxes) prunes them
/// together, so a texel or row tests a stroke's chunks and then the segments of the few nearby
/// ones, not every segment of a finely tessellated curve.
pub(crate) const CHUNK_SEGS: usize = 32;

/// A stroke prepared for rasterisation: segments and per-kind parameters.
pub(crate) struct Prepared {
    pub(crate) kind: StrokeKind,
    pub(crate) segs: Vec<Seg>,
    /// Runs of `CHUNK_SEGS` segments (the last one shorter) with their boxes.
    pub(crate) chunks: Vec<Chunk>,
    /// The polyline is a loop: the last segment's next one is the first, and there are no end caps.
    closed: bool,
    pub(crate) tan_left: f32,
    pub(crate) tan_right: f32,
    pub(crate) width_m: f32,
    pub(crate) roughness: f32,
    /// `1 / width_m` (0 for a zero width) and the falloff's coefficients, as the texels use them.
    pub(crate) inv_width: f32,
    pub(crate) falloff: [f32; 3],
    /// Texel-row range this stroke can touch.
    pub(crate) rows: std::ops::Range<usize>,
    /// Every segment is a candidate for every texel of its rows (the reference the tests compare
    /// the candidate ranges with).
    exhaustive: bool,
}

/// A run of consecutive segments and the union of their boxes.
pub(crate) struct Chunk {
    pub(crate) bbox: [f64; 4],
    pub(crate) segs: std::ops::Range<usize>,
}

#[derive(Clone, Copy)]
pub(crate) struct Seg {
    pub(crate) a: [f64; 3],
    pub(crate) b: [f64; 3],
    /// Length of `b - a` in x and y, and its unit direction (0 for a single point).
    len: f64,
    u: [f64; 2],
    /// Expanded bounding box in metres: x0, x1, y0, y1.
    pub(crate) bbox: [f64; 4],
    /// The rows (y, metres) the segment's region (`reach_interval`) can meet: its slab's when the
    /// turn to the next segment is gentle, else the box's (set by `prepare`).
    ys: [f64; 2],
    /// The per-texel arithmetic's view (f32, as the GPU twin `rasterize.wgsl` packs it): `a` (x, y,
    /// z), `b.z - a.z`, `b - a` in x and y (differences of the f32 end points), `1 / |b - a|^2` (0 for a
    /// single point).
    ax: f32,
    ay: f32,
    az: f32,
    dz: f32,
    ex32: f32,
    ey32: f32,
    inv32: f32,
}

impl Seg {
    fn new(a: [f64; 3], b: [f64; 3], bbox: [f64; 4]) -> Seg {
        let e = [b[0] - a[0], b[1] - a[1]];
        let len2 = e[0] * e[0] + e[1] * e[1];
        let inv_len2 = if len2 > 0.0 { 1.0 / len2 } else { 0.0 };
        let (a32, b32) = (a.map(|v| v as f32), b.map(|v| v as f32));
        let len = len2.sqrt();
        let u = if len > 0.0 {
            [e[0] / len, e[1] / len]
        } else {
            [0.0, 0.0]
        };
        Seg {
            a,
            b,
            len,
            u,
            bbox,
            ys: [bbox[2], bbox[3]],
            ax: a32[0],
            ay: a32[1],
            az: a32[2],
            dz: b32[2] - a32[2],
            ex32: b32[0] - a32[0],
            ey32: b32[1] - a32[1],
            inv32: inv_len2 as f32,
        }
    }

    /// A superset of the x-interval (metres) of the points of the line `y` within `r` of the
    /// segment whose closest point on the polyline can lie on this segment (`next`: the following
    /// segment of the polyline, `first`: this is the first one): the slab over the segment (the
    /// points whose projection falls on it), the wedge beyond its end that the next segment's slab
    /// leaves out (every point there is closest to the shared vertex), and the end caps of the
    /// polyline; each widened by `m` along the segment. A point within `r` of the polyline is in the
    /// region of the segment holding its closest point, so these regions cover everything within
    /// reach, while a texel is in only one or two of them away from tight bends (instead of every
    /// segment within `r`). `None` if empty.
    /// How far the slab must extend beyond the end to cover the wedge before `next` (for a turn
    /// of at most 60 degrees; `None`: no next segment or a sharper turn).
    fn gentle_end(&self, next: Option<&Seg>, r: f64, m: f64) -> Option<f64> {
        let u = self.u;
        next.filter(|s| s.len > 0.0 && self.len > 0.0)
            .and_then(|s| {
                let cos = u[0] * s.u[0] + u[1] * s.u[1];
                let sin = (u[0] * s.u[1] - u[1] * s.u[0]).abs();
                (cos >= 0.5).then(|| (m + r * sin) / cos)
            })
    }

    fn reach_interval(
        &self,
        y: f64,
        r: f64,
        m: f64,
        next: Option<&Seg>,
        first: bool,
    ) -> Option<(f64, f64)> {
        let a = [self.a[0], self.a[1]];
        let b = [self.b[0], self.b[1]];
        let (u, len) = (self.u, self.len);
        if len == 0.0 {
            return disk(y, a, r);
        }
        let nrm = [-u[1], u[0]];
        // A gentle turn to the next segment (at most 60 degrees, as along a finely tessellated
        // curve): the wedge beyond the end, `(x - b) . u >= -m`, `(x - b) . u_next <= m` within `r`
        // of `b`, lies in the slab extended by `(m + r sin(turn)) / cos(turn)` along `u`, which
        // costs one clip instead of a disk and two clips.
        let gentle = self.gentle_end(next, r, m);
        let slab = Some((f64::NEG_INFINITY, f64::INFINITY))
            .and_then(|i| clip(i, y, a, [-u[0], -u[1]], m))
            .and_then(|i| clip(i, y, a, u, len + gentle.unwrap_or(m)))
            .and_then(|i| clip(i, y, a, nrm, r))
            .and_then(|i| clip(i, y, a, [-nrm[0], -nrm[1]], r));
        let end = match gentle {
            Some(_) => None,
            None => disk(y, b, r)
                .and_then(|i| clip(i, y, b, [-u[0], -u[1]], m))
                .and_then(|i| match next {
                    Some(s) if s.len > 0.0 => clip(i, y, b, s.u, m),
                    _ => Some(i),
                }),
        };
        let start = if first {
            disk(y, a, r).and_then(|i| clip(i, y, a, u, m))
        } else {
            None
        };
        [slab, end, start]
            .into_iter()
            .flatten()
            .reduce(|p, q| (p.0.min(q.0), p.1.max(q.1)))
    }
}

/// The x-interval of the line `y` inside the disk of radius `r` around `c`.
fn disk(y: f64, c: [f64; 2], r: f64) -> Option<(f64, f64)> {
    let h2 = r * r - (y - c[1]) * (y - c[1]);
    (h2 >= 0.0).then(|| {
        let h = h2.sqrt();
        (c[0] - h, c[0] + h)
    })
}

/// Interval `i` of the line `y` cut to the half-plane of the points `x` with `(x - o) . d <= c`.
fn clip(i: (f64, f64), y: f64, o: [f64; 2], d: [f64; 2], c: f64) -> Option<(f64, f64)> {
    let q = c - (y - o[1]) * d[1];
    let (lo, hi) = if d[0] > 0.0 {
        (i.0, i.1.min(o[0] + q / d[0]))
    } else if d[0] < 0.0 {
        (i.0.max(o[0] + q / d[0]), i.1)
    } else if q >= 0.0 {
        i
    } else {
        return None;
    };
    (lo <= hi).then_some((lo, hi))
}

/// One row of every map, and the per-row compositing scratch.
struct RowOut<'a> {
    ew: &'a mut [f32],
    ev: &'a mut [f32],
    bw: &'a mut [f32],
    gx: &'a mut [f32],
    gy: &'a mut [f32],
    rw: &'a mut [f32],
    rv: &'a mut [f32],
    /// Distance (m) to the stroke that set the elevation value.
    ed: &'a mut [f32],
    /// Distance (m) to the stroke that set the band values.
    bd: &'a mut [f32],
}

/// Per-row scratch of the rasteriser (kept per worker thread).
#[derive(Default)]
pub(crate) struct RowScratch {
    ed: Vec<f32>,
    bd: Vec<f32>,
    near: NearestRow,
}

/// Per texel of the current row and stroke, what the closest segment so far says: squared distance,
/// the vector from the closest point to the texel, the height there and the signed slope of the side
/// the texel is on (f32 throughout, as the GPU twin).
#[derive(Default)]
struct NearestRow {
    d2: Vec<f32>,
    vx: Vec<f32>,
    vy: Vec<f32>,
    z: Vec<f32>,
    slope: Vec<f32>,
    /// Candidate segments of the current row and stroke: index and texel range.
    cand: Vec<(u32, std::ops::Range<usize>)>,
}

impl NearestRow {
    fn resize(&mut self, n: usize) {
        for v in [
            &mut self.d2,
            &mut self.vx,
            &mut self.vy,
            &mut self.z,
            &mut self.slope,
        ] {
            v.resize(n, 0.0);
        }
    }
}

/// The per-stroke constants of the per-texel arithmetic.
#[derive(Clone, Copy)]
struct StrokeConsts {
    /// Squared reach: texels at this squared distance or more are out of reach.
    reach2: f32,
    /// Larger cell side (m).
    cell: f32,
    /// Hard-core radius (plateau width, else 0).
    core: f32,
    width: f32,
    /// Ridges and valleys have a gradient band.
    banded: bool,
    roughness: f32,
    /// `1 / width` and the falloff's coefficients (`Prepared`).
    inv_width: f32,
    falloff: [f32; 3],
}

impl ConstraintMaps {
    /// Empty maps (no constraint anywhere) for an `n x n` grid.
    pub fn new(n: usize) -> ConstraintMaps {
        let z = || vec![0.0f32; n * n];
        ConstraintMaps {
            n,
            elev_weight: z(),
            elev_value: z(),
            band_weight: z(),
            grad_x: z(),
            grad_y: z(),
            rough_weight: z(),
            rough_value: z(),
        }
    }

    /// The seven maps in the rasteriser's order: elevation weight and value, band weight, gradient x
    /// and y, roughness weight and value.
    fn arrays_mut(&mut self) -> [&mut Vec<f32>; 7] {
        [
            &mut self.elev_weight,
            &mut self.elev_value,
            &mut self.band_weight,
            &mut self.grad_x,
            &mut self.grad_y,
            &mut self.rough_weight,
            &mut self.rough_value,
        ]
    }

    /// Rasterises the whole sketch.
    pub fn rasterize(sketch: &Sketch, grid: &Grid) -> ConstraintMaps {
        let mut maps = ConstraintMaps::new(grid.n);
        maps.rasterize_rows(sketch, grid, 0..grid.n);
        maps
    }

    /// Clears rows `rows` and rasterises every stroke into them (incremental update after an edit).
    ///
    /// Rows are independent: each row is cleared and composited stroke by stroke (in sketch order),
    /// in parallel over rows, with per-row scratch only.
    pub fn rasterize_rows(&mut self, sketch: &Sketch, grid: &Grid, rows: std::ops::Range<usize>) {
        let n = self.n;
        let rows = rows.start.min(n)..rows.end.min(n);
        if rows.is_empty() {
            return;
        }
        let span = rows.start * n..rows.end * n;
        let out = self.arrays_mut().map(|v| &mut v[span.clone()]);
        rasterize_block(sketch, grid, rows, 0..n, out, false);
    }

    /// Rasterises rows `rows` of an `n x n` grid into `band`, a band of maps holding just those
    /// rows (every array `rows.len() * n` cells, row `rows.start` first; `band.n` is ignored). The
    /// values are those `rasterize_rows` writes into the same rows of full maps.
    pub fn rasterize_band(
        band: &mut ConstraintMaps,
        sketch: &Sketch,
        grid: &Grid,
        rows: std::ops::Range<usize>,
    ) {
        ConstraintMaps::rasterize_band_cols(band, sketch, grid, rows, 0..grid.n);
    }

    /// Like `rasterize_band`, but only the columns `cols`: every array holds `rows.len() *
    /// cols.len()` cells, row-major, with the values a full rasterisation gives those texels
    /// (bit for bit: a texel's closest segment is chosen among the same candidates).
    pub fn rasterize_band_cols(
        band: &mut ConstraintMaps,
        sketch: &Sketch,
        grid: &Grid,
        rows: std::ops::Range<usize>,
        cols: std::ops::Range<usize>,
    ) {
        let n = grid.n;
        let rows = rows.start.min(n)..rows.end.min(n);
        let cols = cols.start.min(n)..cols.end.min(n);
        let len = rows.len() * cols.len();
        let out = band.arrays_mut().map(|v| {
            v.resize(len, 0.0);
            &mut v[..]
        });
        if len > 0 {
            rasterize_block(sketch, grid, rows, cols, out, false);
        }
    }

    /// Per texel row that stroke `stroke` of `sketch` can touch, the columns of the texels within
    /// its reach (the texels whose values can change when the stroke is added, removed or moved),
    /// rows ascending, rows without such texels left out. Pass the spans of an edited stroke before
    /// and after the edit to `CpuSolver::update_sketch_spans`.
    pub fn stroke_spans(
        sketch: &Sketch,
        stroke: usize,
        grid: &Grid,
    ) -> Vec<(usize, std::ops::Range<usize>)> {
        let [dx, dy] = grid.cell_size_m();
        let cell = dx.max(dy);
        let Some(p) = prepare_one(sketch, stroke, grid, cell) else {
            return Vec::new();
        };
        p.rows
            .clone()
            .into_par_iter()
            .filter_map(|j| {
                let (a, b) = candidate_ranges(&p, dx, dy, cell, j, 0..grid.n)
                    .fold((usize::MAX, 0), |(a, b), (_, r)| {
                        (a.min(r.start), b.max(r.end))
                    });
                (a < b).then_some((j, a..b))
            })
            .collect()
    }

    /// Rows of the grid that stroke `stroke` of `sketch` can touch (for dirty tracking).
    pub fn stroke_rows(sketch: &Sketch, stroke: usize, grid: &Grid) -> std::ops::Range<usize> {
        let [dx, dy] = grid.cell_size_m();
        prepare_one(sketch, stroke, grid, dx.max(dy))
            .map(|p| p.rows)
            .unwrap_or(0..0)
    }
}

/// Composites stroke `p` into row `j`.
///
/// Candidate segments are those whose expanded box holds the row, each with a conservative texel
/// range of the points within reach. Every candidate, in segment order, lowers a per-texel minimum
/// of the squared distance (a branch-free loop); a segment replaces the current one only if
/// strictly closer. Segments out of reach never win, so the winner of each texel (the smallest
/// squared distance, the first segment on exact ties) is the one a test of all segments gives. The
/// winner's vector, height and side are kept along with its distance, so compositing needs no
/// second look at the segments (and is branch-free too).
fn splat_row(
    p: &Prepared,
    [dx, dy]: [f64; 2],
    cell: f64,
    j: usize,
    cols: std::ops::Range<usize>,
    out: &mut RowOut<'_>,
    near: &mut NearestRow,
) {
    // `out` and `near` hold the texels `cols` of the row: local index = column - c0.
    let (c0, c1) = (cols.start, cols.end);
    let reach = reach_m(p, cell) as f32;
    let NearestRow {
        d2,
        vx,
        vy,
        z,
        slope,
        cand,
    } = near;
    cand.clear();
    let (mut i0, mut i1) = (c1 - c0, 0);
    for (k, range) in candidate_ranges(p, dx, dy, cell, j, c0..c1) {
        let (ia, ib) = (range.start.max(c0), range.end);
        if ia < ib {
            cand.push((k, ia - c0..ib - c0));
            i0 = i0.min(ia - c0);
            i1 = i1.max(ib - c0);
        }
    }
    if i0 >= i1 {
        return;
    }
    let (tl, tr) = if p.kind == StrokeKind::Ridge {
        (-p.tan_left, -p.tan_right)
    } else {
        (p.tan_left, p.tan_right)
    };
    let k = StrokeConsts {
        reach2: reach * reach,
        cell: cell as f32,
        core: if p.kind == StrokeKind::Plateau {
            p.width_m
        } else {
            0.0
        },
        width: p.width_m,
        banded: p.kind != StrokeKind::Plateau,
        roughness: p.roughness,
        inv_width: p.inv_width,
        falloff: p.falloff,
    };
    let y = (j as f32 + 0.5) * dy as f32;
    let dx = dx as f32;
    d2[i0..i1].fill(k.reach2);
    for (s, range) in cand.iter() {
        let s = &p.segs[*s as usize];
        let r = range.clone();
        nearer(
            s,
            (tl, tr),
            y,
            dx,
            c0 + r.start,
            [
                &mut d2[r.clone()],
                &mut vx[r.clone()],
                &mut vy[r.clone()],
                &mut z[r.clone()],
                &mut slope[r],
            ],
        );
    }
    let r = i0..i1;
    composite(
        &k,
        &d2[r.clone()],
        &vx[r.clone()],
        &vy[r.clone()],
        &z[r.clone()],
        &slope[r.clone()],
        &mut out.ew[r.clone()],
        &mut out.ev[r.clone()],
        &mut out.bw[r.clone()],
        &mut out.gx[r.clone()],
        &mut out.gy[r.clone()],
        &mut out.rw[r.clone()],
        &mut out.rv[r.clone()],
        &mut out.ed[r.clone()],
        &mut out.bd[r],
    );
}

/// The candidate segments of stroke `p` on row `j` with their texel ranges (clipped to
/// `0..cols.end`): a conservative range of the texels within `reach + c/2` of the stroke whose
/// closest point can be on the segment (`Seg::reach_interval`). Empty ranges are left out; so are
/// the segments whose box lies clear of the columns `cols` (their ranges, inside the box widened
/// by a cell, would be clipped away by the caller).
fn candidate_ranges(
    p: &Prepared,
    dx: f64,
    dy: f64,
    cell: f64,
    j: usize,
    cols: std::ops::Range<usize>,
) -> impl Iterator<Item = (u32, std::ops::Range<usize>)> + '_ {
    let n = cols.end;
    let y = (j as f64 + 0.5) * dy;
    // Margin so that the ranges are strict supersets despite rounding.
    let r = reach_m(p, cell) + 0.5 * cell;
    // The columns in metres, widened by two cells and two texels (more than the box misses).
    let (x0, x1) = (
        cols.start as f64 * dx - 2.0 * (cell + dx),
        cols.end as f64 * dx + 2.0 * (cell + dx),
    );
    let boxed = move |b: &[f64; 4]| y >= b[2] && y <= b[3] && b[1] >= x0 && b[0] <= x1;
    let last = p.segs.len() - 1;
    p.chunks
        .iter()
        .filter(move |c| boxed(&c.bbox))
        .flat_map(move |c| c.segs.clone())
        .filter_map(move |k| {
            let s = &p.segs[k];
            if !boxed(&s.bbox) || y < s.ys[0] || y > s.ys[1] {
                return None;
            }
            let (a, b) = if p.exhaustive {
                (f64::NEG_INFINITY, f64::INFINITY)
            } else {
                let next = match (k == last, p.closed) {
                    (true, true) => p.segs.first(),
                    _ => p.segs.get(k + 1),
                };
                s.reach_interval(y, r, 0.5 * cell, next, k == 0 && !p.closed)?
            };
            // The texels whose centre `(i + 0.5) dx` lies in `[a, b]` (the margins are in `r`,
            // `m` and the gentle ends' extension): a finely tessellated curve has many short
            // segments, and the two texels more per side used before would multiply the
            // candidates.
            let ia = ((a / dx - 0.5).ceil()).clamp(0.0, n as f64) as usize;
            let ib = ((b / dx - 0.5).floor() + 1.0).clamp(0.0, n as f64) as usize;
            (ia < ib).then_some((k as u32, ia..ib))
        })
}

/// How far (metres) a stroke's influence reaches from its curve.
fn reach_m(p: &Prepared, cell: f64) -> f64 {
    p.width_m as f64 + 1.5 * cell
}

/// Rasterises rows `rows` x columns `cols` of an `n x n` grid into `out` (elevation weight and value,
/// band weight, gradient x and y, roughness weight and value), each holding `rows.len() * cols.len()`
/// cells, row-major.
fn rasterize_block(
    sketch: &Sketch,
    grid: &Grid,
    rows: std::ops::Range<usize>,
    cols: std::ops::Range<usize>,
    out: [&mut [f32]; 7],
    exhaustive: bool,
) {
    let n = cols.len();
    let prepared = PreparedSketch::new_for_rows(sketch, grid, rows.clone(), exhaustive);
    let [ew, ev, bw, gx, gy, rw, rv] = out;
    ew.par_chunks_mut(n)
        .zip(ev.par_chunks_mut(n))
        .zip(bw.par_chunks_mut(n))
        .zip(gx.par_chunks_mut(n))
        .zip(gy.par_chunks_mut(n))
        .zip(rw.par_chunks_mut(n))
        .zip(rv.par_chunks_mut(n))
        .enumerate()
        .with_min_len(4)
        .for_each_init(
            RowScratch::default,
            |scratch, (r, ((((((ew, ev), bw), gx), gy), rw), rv))| {
                prepared.row(
                    rows.start + r,
                    cols.clone(),
                    [ew, ev, bw, gx, gy, rw, rv],
                    scratch,
                );
            },
        );
}

/// The strokes of a sketch prepared for rasterisation (segments with their boxes, per-kind
/// constants), for callers that rasterise many small blocks: prepared once, not per block.
pub(crate) struct PreparedSketch {
    pub(crate) strokes: Vec<Prepared>,
    dx: f64,
    dy: f64,
    cell: f64,
}

impl PreparedSketch {
    /// Every stroke of `sketch` (those without finite points left out).
    pub(crate) fn new(sketch: &Sketch, grid: &Grid) -> PreparedSketch {
        PreparedSketch::new_for_rows(sketch, grid, 0..grid.n, false)
    }

    /// The strokes that can touch rows `rows`.
    fn new_for_rows(
        sketch: &Sketch,
        grid: &Grid,
        rows: std::ops::Range<usize>,
        exhaustive: bool,
    ) -> PreparedSketch {
        let [dx, dy] = grid.cell_size_m();
        let cell = dx.max(dy);
        let curves = terrasketch_sketch::stroke_curves(sketch, cell);
        let strokes = sketch
            .strokes
            .iter()
            .zip(curves)
            .filter_map(|(s, c)| prepare(s, c, grid, cell))
            .filter(|p| p.rows.start < rows.end && p.rows.end > rows.start)
            .map(|p| Prepared { exhaustive, ..p })
            .collect();
        PreparedSketch {
            strokes,
            dx,
            dy,
            cell,
        }
    }

    /// Rasterises row `j`, columns `cols`, into `out` (the seven maps' cells of those columns, in
    /// the order of `rasterize_block`), on the calling thread: the values `rasterize_block` gives
    /// them, bit for bit.
    pub(crate) fn row(
        &self,
        j: usize,
        cols: std::ops::Range<usize>,
        out: [&mut [f32]; 7],
        scratch: &mut RowScratch,
    ) {
        let n = cols.len();
        let [ew, ev, bw, gx, gy, rw, rv] = out;
        for v in [
            &mut *ew, &mut *ev, &mut *bw, &mut *gx, &mut *gy, &mut *rw, &mut *rv,
        ] {
            v[..n].fill(0.0);
        }
        scratch.ed.clear();
        scratch.ed.resize(n, f32::INFINITY);
        scratch.bd.clear();
        scratch.bd.resize(n, f32::INFINITY);
        scratch.near.resize(n);
        let RowScratch { ed, bd, near } = scratch;
        let mut out = RowOut {
            ew,
            ev,
            bw,
            gx,
            gy,
            rw,
            rv,
            ed,
            bd,
        };
        for p in &self.strokes {
            if p.rows.contains(&j) {
                splat_row(
                    p,
                    [self.dx, self.dy],
                    self.cell,
                    j,
                    cols.clone(),
                    &mut out,
                    near,
                );
            }
        }
    }
}

/// Stroke `index` of `sketch` prepared (`None` if there is none or it has no finite curve).
fn prepare_one(sketch: &Sketch, index: usize, grid: &Grid, cell: f64) -> Option<Prepared> {
    let stroke = sketch.strokes.get(index)?;
    prepare(
        stroke,
        terrasketch_sketch::stroke_curve(sketch, index, cell),
        grid,
        cell,
    )
}

/// `1 / width_m` (0 for a zero width) and the falloff's coefficients, in f32 as both rasterisers
/// use them.
pub(crate) fn falloff_consts(stroke: &Stroke) -> (f32, [f32; 3]) {
    let width_m = stroke.width_m.max(0.0);
    let inv = if width_m > 0.0 { 1.0 / width_m } else { 0.0 };
    (inv as f32, stroke.falloff.coefficients().map(|c| c as f32))
}

/// `stroke` prepared from its curve's polyline `curve` (`None` if the curve is empty: a coordinate
/// was not finite).
fn prepare(stroke: &Stroke, curve: Curve, grid: &Grid, cell: f64) -> Option<Prepared> {
    let mut segs = Vec::new();
    let width_m = stroke.width_m.max(0.0);
    let reach = width_m + 1.5 * cell;
    let points = curve.points;
    for w in points.windows(2) {
        let (a, b) = (w[0], w[1]);
        if a[0] == b[0] && a[1] == b[1] {
            continue;
        }
        let bbox = [
            a[0].min(b[0]) - reach,
            a[0].max(b[0]) + reach,
            a[1].min(b[1]) - reach,
            a[1].max(b[1]) + reach,
        ];
        segs.push(Seg::new(a, b, bbox));
    }
    if segs.is_empty() {
        // A stroke whose points all coincide (seen from above) is a single point: keep it as a dot.
        let a = *points.first()?;
        let bbox = [a[0] - reach, a[0] + reach, a[1] - reach, a[1] + reach];
        segs.push(Seg::new(a, a, bbox));
    }
    // Tight row ranges: a segment with a gentle end (and no start cap) only meets the rows of
    // its slab, extended as `reach_interval` extends it (`r`, `m` as `candidate_ranges` uses them).
    let closed = curve.closed && segs.len() > 1;
    let (r, m) = ((width_m as f32) as f64 + 2.0 * cell, 0.5 * cell);
    for k in 0..segs.len() {
        let next = match (k + 1 == segs.len(), closed) {
            (true, true) => Some(segs[0]),
            _ => segs.get(k + 1).copied(),
        };
        let s = &segs[k];
        if let Some(e) = s
            .gentle_end(next.as_ref(), r, m)
            .filter(|_| k > 0 || closed)
        {
            let [ux, uy] = s.u;
            let ys = [-m, s.len + e]
                .into_iter()
                .flat_map(|t| [-r, r].map(|q| s.a[1] + t * uy + q * ux));
            let (lo, hi) = ys.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), y| {
                (lo.min(y), hi.max(y))
            });
            segs[k].ys = [lo, hi];
        }
    }
    let chunks: Vec<Chunk> = (0..segs.len())
        .step_by(CHUNK_SEGS)
        .map(|k0| {
            let run = k0..(k0 + CHUNK_SEGS).min(segs.len());
            let bbox = segs[run.clone()].iter().fold(
                [
                    f64::INFINITY,
                    f64::NEG_INFINITY,
                    f64::INFINITY,
                    f64::NEG_INFINITY,
                ],
                |b, s| {
                    [
                        b[0].min(s.bbox[0]),
                        b[1].max(s.bbox[1]),
                        b[2].min(s.bbox[2]),
                        b[3].max(s.bbox[3]),
                    ]
                },
            );
            Chunk { bbox, segs: run }
        })
        .collect();
    let dy = grid.cell_size_m()[1];
    let y0 = chunks
        .iter()
        .map(|c| c.bbox[2])
        .fold(f64::INFINITY, f64::min);
    let y1 = chunks
        .iter()
        .map(|c| c.bbox[3])
        .fold(f64::NEG_INFINITY, f64::max);
    let j0 = (y0 / dy - 0.5).floor().clamp(0.0, grid.n as f64) as usize;
    let j1 = (y1 / dy + 0.5).ceil().clamp(0.0, grid.n as f64) as usize;
    let tan = |deg: f64| deg.clamp(0.0, 89.0).to_radians().tan() as f32;
    let (inv_width, falloff) = falloff_consts(stroke);
    Some(Prepared {
        kind: stroke.kind,
        closed,
        segs,
        chunks,
        tan_left: tan(stroke.slope_left_deg),
        tan_right: tan(stroke.slope_right_deg),
        width_m: width_m as f32,
        roughness: stroke.roughness.clamp(0.0, 1.0) as f32,
        inv_width,
        falloff,
        rows: j0..j1,
        exhaustive: false,
    })
}

multiversion! {
    /// Lowers the squared distances `near[0]` (texels from column `i0`) with segment `s`: a texel takes
    /// the segment (distance, vector, height, signed slope of its side) if strictly closer.
    fn nearer(
        s: &Seg,
        slopes: (f32, f32),
        y: f32,
        dx: f32,
        i0: usize,
        near: [&mut [f32]; 5],
    ) {
        let (slope_left, slope_right) = slopes;
        let [bd, bvx, bvy, bz, bs] = near;
        let n = bd.len();
        let (bvx, bvy, bz, bs) = (&mut bvx[..n], &mut bvy[..n], &mut bz[..n], &mut bs[..n]);
        let (ex, ey, inv) = (s.ex32, s.ey32, s.inv32);
        let py = y - s.ay;
        for o in 0..n {
            // Through i32: converts 8 lanes at once (exact below 2^24, as the column is).
            let x = ((i0 + o) as i32 as f32 + 0.5) * dx;
            let px = x - s.ax;
            let t = ((px * ex + py * ey) * inv).clamp(0.0, 1.0);
            let (vx, vy) = (px - t * ex, py - t * ey);
            let d2 = vx * vx + vy * vy;
            let take = d2 < bd[o];
            let left = ex * vy - ey * vx > 0.0;
            bd[o] = if take { d2 } else { bd[o] };
            bvx[o] = if take { vx } else { bvx[o] };
            bvy[o] = if take { vy } else { bvy[o] };
            bz[o] = if take { s.az + t * s.dz } else { bz[o] };
            let sl = if left { slope_left } else { slope_right };
            bs[o] = if take { sl } else { bs[o] };
        }
    }
}

multiversion! {
    /// Composites one stroke's closest points (`near`: squared distance, vector, height, signed slope)
    /// into a row (`out`: elevation weight and value, band weight, gradient x and y, roughness weight
    /// and value, and the distances of the strokes that set the elevation and band values). Texels at
    /// the squared reach or beyond (no segment within reach) are left alone.
    /// (Every slice is its own argument, so that the compiler knows that they do not overlap.)
    #[allow(clippy::too_many_arguments)]
    fn composite(
        k: &StrokeConsts,
        d2s: &[f32],
        vxs: &[f32],
        vys: &[f32],
        zs: &[f32],
        ss: &[f32],
        ew: &mut [f32],
        ev: &mut [f32],
        bw: &mut [f32],
        gx: &mut [f32],
        gy: &mut [f32],
        rw: &mut [f32],
        rv: &mut [f32],
        ed: &mut [f32],
        bd: &mut [f32],
    ) {
        let n = d2s.len();
        let (vxs, vys, zs, ss) = (&vxs[..n], &vys[..n], &zs[..n], &ss[..n]);
        let (ew, ev, bw, gx, gy) = (&mut ew[..n], &mut ev[..n], &mut bw[..n], &mut gx[..n], &mut gy[..n]);
        let (rw, rv, ed, bd) = (&mut rw[..n], &mut rv[..n], &mut ed[..n], &mut bd[..n]);
        let k = *k;
        // Blocks of 8 texels, then the rest.
        const L: usize = 8;
        macro_rules! lanes {
            ($len:expr, $r:expr) => {{
                let r = $r;
                composite_lanes::<$len>(
                    &k,
                    [&d2s[r.clone()], &vxs[r.clone()], &vys[r.clone()], &zs[r.clone()], &ss[r.clone()]],
                    [
                        &mut ew[r.clone()],
                        &mut ev[r.clone()],
                        &mut bw[r.clone()],
                        &mut gx[r.clone()],
                        &mut gy[r.clone()],
                        &mut rw[r.clone()],
                        &mut rv[r.clone()],
                        &mut ed[r.clone()],
                        &mut bd[r],
                    ],
                )
            }};
        }
        let whole = n / L * L;
        for b in (0..whole).step_by(L) {
            lanes!(L, b..b + L);
        }
        for i in whole..n {
            lanes!(1, i..i + 1);
        }
    }
}

/// `composite` on `L` texels: copied into fixed-size arrays, computed lane by lane with bit-mask
/// selects (every value is finite: no NaN rules), copied back. With bool conditions the compiler kept
/// the lanes scalar; with `mask` / `sel` the AVX2 build computes the 8 lanes as vectors (single thread
/// at 1024^2: 20-25 -> 16-17 ms for the whole rasterisation).
#[inline(always)]
fn composite_lanes<const L: usize>(k: &StrokeConsts, near: [&[f32]; 5], out: [&mut [f32]; 9]) {
    let get = |v: &[f32]| -> [f32; L] { std::array::from_fn(|l| v[l]) };
    let [d2s, vxs, vys, zs, ss] = near.map(get);
    let [ew, ev, bw, gx, gy, rw, rv, ed, bd] = out;
    let (mut o_ew, mut o_ev, mut o_bw, mut o_gx, mut o_gy) =
        (get(ew), get(ev), get(bw), get(gx), get(gy));
    let (mut o_rw, mut o_rv, mut o_ed, mut o_bd) = (get(rw), get(rv), get(ed), get(bd));
    let c = k.cell;
    // Bit masks and selects (`cpu::rows::{mask, sel}`), as the solver's kernels use them.
    let max = |a: f32, b: f32| sel(mask(a > b), a, b);
    let unit = |v: f32| v.clamp(0.0, 1.0);
    let banded = mask(k.banded);
    for i in 0..L {
        let d2 = d2s[i];
        let found = mask(d2 < k.reach2);
        let d = d2.sqrt();
        // Elevation.
        let we = sel(found, unit((k.core - d) / c + 1.5), 0.0);
        let set_e = mask(we > 0.0) & mask(d <= o_ed[i]);
        o_ed[i] = sel(set_e, d, o_ed[i]);
        o_ev[i] = sel(set_e, zs[i], o_ev[i]);
        o_ew[i] = max(o_ew[i], we);
        // Gradient band (ridges and valleys), outside the hard core.
        let in_band = found & banded & mask(d > 0.5 * c);
        let wb = sel(in_band, unit((k.width - d) / c + 0.5), 0.0);
        let set_b = mask(wb > 0.0) & mask(d <= o_bd[i]);
        // In the band `d > c / 2`: the direction is well defined. The slope fades with the
        // falloff profile `1 + u^2 (c2 + u (c3 + u c4))` of `u = d / width` (1 for "none").
        let (ux, uy) = (vxs[i] / d, vys[i] / d);
        let u = (d * k.inv_width).min(1.0);
        let [c2, c3, c4] = k.falloff;
        let f = (1.0 + u * u * (c2 + u * (c3 + u * c4))).clamp(0.0, 1.0);
        let slope = ss[i] * f;
        o_bd[i] = sel(set_b, d, o_bd[i]);
        o_gx[i] = sel(set_b, slope * ux, o_gx[i]);
        o_gy[i] = sel(set_b, slope * uy, o_gy[i]);
        o_bw[i] = max(o_bw[i], wb);
        // Roughness over the footprint.
        let foot = sel(found & mask(d <= k.width), 1.0, 0.0);
        let wr = max(max(we, wb), foot);
        let set_r = mask(wr > 0.0) & mask(wr >= o_rw[i]);
        o_rv[i] = sel(set_r, k.roughness, o_rv[i]);
        o_rw[i] = max(o_rw[i], wr);
    }
    for (dst, src) in [ew, ev, bw, gx, gy, rw, rv, ed, bd].into_iter().zip([
        &o_ew, &o_ev, &o_bw, &o_gx, &o_gy, &o_rw, &o_rv, &o_ed, &o_bd,
    ]) {
        dst[..L].copy_from_slice(src);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use terrasketch_sketch::Stroke;

    fn grid(n: usize) -> Grid {
        Grid::new(n, [6400.0, 6400.0]).unwrap()
    }

    #[test]
    fn curve_is_never_thinner_than_one_texel() {
        // A diagonal stroke at an awkward angle: every column it crosses has a hard texel.
        let g = grid(64);
        let s = Sketch {
            extent_m: g.extent_m,
            base_elevation_m: 0.0,
            seed: 0,
            strokes: vec![Stroke::new(
                StrokeKind::Ridge,
                vec![[130.0, 710.0, 500.0], [6100.0, 4333.0, 700.0]],
            )],
        };
        let m = ConstraintMaps::rasterize(&s, &g);
        let n = g.n;
        for i in 2..60 {
            let hard = (0..n).filter(|&j| m.elev_weight[j * n + i] >= 1.0).count();
            assert!(hard >= 1, "column {i} has no hard texel");
        }
        // Heights along the curve interpolate between 500 and 700.
        let vals: Vec<f32> = (0..n * n)
            .filter(|&k| m.elev_weight[k] >= 1.0)
            .map(|k| m.elev_value[k])
            .collect();
        assert!(vals.iter().all(|v| (499.0..=701.0).contains(v)));
    }

    #[test]
    fn ridge_band_gradients_point_down_and_away() {
        let g = grid(64);
        let mut st = Stroke::new(
            StrokeKind::Ridge,
            vec![[0.0, 3200.0, 800.0], [6400.0, 3200.0, 800.0]],
        );
        st.slope_left_deg = 30.0;
        st.slope_right_deg = 10.0;
        st.width_m = 1000.0;
        st.falloff = terrasketch_sketch::Falloff::None;
        let mut s = Sketch {
            extent_m: g.extent_m,
            base_elevation_m: 0.0,
            seed: 0,
            strokes: vec![st],
        };
        let m = ConstraintMaps::rasterize(&s, &g);
        let n = g.n;
        // Travel is eastward: left = north. North of the ridge heights fall northward: gy = -tan 30.
        let north = 40 * n + 32; // y = 4050 m, 850 m north of the curve
        assert!((m.grad_y[north] + 30f32.to_radians().tan()).abs() < 1e-5);
        assert!(m.band_weight[north] == 1.0);
        let south = 26 * n + 32; // y = 2650 m, 550 m south
        assert!((m.grad_y[south] - 10f32.to_radians().tan()).abs() < 1e-5);
        // With a falloff the slope fades with the profile of the distance over the width.
        for falloff in [
            terrasketch_sketch::Falloff::Foot,
            terrasketch_sketch::Falloff::Sigmoid,
        ] {
            s.strokes[0].falloff = falloff;
            let f = ConstraintMaps::rasterize(&s, &g);
            for (k, d, tan) in [(north, 850.0, -30f64), (south, 550.0, 10.0)] {
                let want =
                    tan.signum() * tan.abs().to_radians().tan() * falloff.profile(d / 1000.0);
                assert!((f.grad_y[k] as f64 - want).abs() < 1e-5, "{falloff:?} {d}");
            }
            assert_eq!(f.band_weight, m.band_weight);
        }
        // Outside the band: nothing.
        let far = 60 * n + 32;
        assert_eq!(m.band_weight[far], 0.0);
        assert_eq!(m.elev_weight[far], 0.0);
    }

    #[test]
    fn incremental_rows_match_full_rasterisation() {
        let g = grid(128);
        let s = terrasketch_sketch::benchmark_sketch();
        let g = Grid::new(g.n, s.extent_m).unwrap();
        let full = ConstraintMaps::rasterize(&s, &g);
        let mut part = ConstraintMaps::rasterize(
            &Sketch {
                strokes: vec![],
                ..s.clone()
            },
            &g,
        );
        part.rasterize_rows(&s, &g, 0..50);
        part.rasterize_rows(&s, &g, 50..128);
        assert_eq!(full, part);
    }

    /// The maps with every segment a candidate for every texel of its rows.
    fn rasterize_exhaustive(sketch: &Sketch, g: &Grid) -> ConstraintMaps {
        let mut m = ConstraintMaps::new(g.n);
        let out = m.arrays_mut().map(|v| &mut v[..]);
        rasterize_block(sketch, g, 0..g.n, 0..g.n, out, true);
        m
    }

    #[test]
    fn candidate_ranges_find_the_closest_segment_of_every_texel() {
        // Wiggly strokes (the benchmark), a hairpin, a zig-zag with sharp turns and a dot.
        let mut sharp = terrasketch_sketch::example_sketch();
        let e = sharp.extent_m;
        let mut hairpin = Stroke::new(
            StrokeKind::Ridge,
            vec![
                [0.2 * e[0], 0.3 * e[1], 400.0],
                [0.8 * e[0], 0.32 * e[1], 600.0],
                [0.21 * e[0], 0.36 * e[1], 500.0],
            ],
        );
        hairpin.width_m = 0.1 * e[0];
        let zigzag = Stroke::new(
            StrokeKind::Valley,
            (0..12)
                .map(|k| {
                    let x = (0.1 + 0.07 * k as f64) * e[0];
                    let y = if k % 2 == 0 { 0.6 } else { 0.75 } * e[1];
                    [x, y, 100.0 + 10.0 * k as f64]
                })
                .collect(),
        );
        let dot = Stroke::new(
            StrokeKind::Plateau,
            vec![
                [0.5 * e[0], 0.9 * e[1], 50.0],
                [0.5 * e[0], 0.9 * e[1], 50.0],
            ],
        );
        let mut ring = Stroke::new(
            StrokeKind::Ridge,
            (0..7)
                .map(|k| {
                    let a = std::f64::consts::TAU * k as f64 / 7.0;
                    [
                        (0.7 + 0.1 * a.cos()) * e[0],
                        (0.5 + 0.1 * a.sin()) * e[1],
                        300.0,
                    ]
                })
                .collect(),
        );
        ring.closed = true;
        let mut polygon = ring.clone();
        polygon.curve = terrasketch_sketch::CurveKind::Polyline;
        for p in &mut polygon.points {
            p[1] -= 0.25 * e[1];
        }
        sharp.strokes.extend([hairpin, zigzag, dot, ring, polygon]);
        let bench = terrasketch_sketch::benchmark_sketch;
        for (s, n) in [
            (bench(), 128),
            (bench(), 256),
            (bench(), 512),
            (sharp.clone(), 256),
            (sharp, 512),
        ] {
            let g = Grid::new(n, s.extent_m).unwrap();
            let fast = ConstraintMaps::rasterize(&s, &g);
            let all = rasterize_exhaustive(&s, &g);
            // Distances decide the weights: the same closest distance gives the same weights.
            assert_eq!(fast.elev_weight, all.elev_weight);
            if let Some(k) = (0..n * n).find(|&k| fast.band_weight[k] != all.band_weight[k]) {
                panic!(
                    "band weight at ({}, {}): {} against {} (of {} differing)",
                    k % n,
                    k / n,
                    fast.band_weight[k],
                    all.band_weight[k],
                    (0..n * n)
                        .filter(|&k| fast.band_weight[k] != all.band_weight[k])
                        .count()
                );
            }
            assert_eq!(fast.rough_weight, all.rough_weight);
            // At a vertex two segments can be closest within rounding: values agree closely.
            let close =
                |a: &[f32], b: &[f32], tol: f32| a.iter().zip(b).all(|(x, y)| (x - y).abs() <= tol);
            assert!(close(&fast.elev_value, &all.elev_value, 1e-3));
            assert!(close(&fast.grad_x, &all.grad_x, 1e-4));
            assert!(close(&fast.grad_y, &all.grad_y, 1e-4));
            assert_eq!(fast.rough_value, all.rough_value);
        }
    }

    #[test]
    fn column_windows_match_full_rasterisation_bit_for_bit() {
        for (s, n) in [
            (terrasketch_sketch::benchmark_sketch(), 128),
            (terrasketch_sketch::example_sketch(), 256),
        ] {
            let g = Grid::new(n, s.extent_m).unwrap();
            let full = ConstraintMaps::rasterize(&s, &g);
            let mut band = ConstraintMaps::new(0);
            // Windows of every shape: edges, one column, odd offsets, the whole grid.
            let mut seed = 7usize;
            let mut windows = vec![(0..n, 0..n), (0..1, n - 1..n), (n - 3..n, 0..1)];
            for _ in 0..20 {
                seed = seed
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                let (a, b) = ((seed >> 20) % n, (seed >> 40) % n);
                let (c, d) = ((seed >> 8) % n, (seed >> 50) % n);
                windows.push((a.min(b)..a.max(b) + 1, c.min(d)..c.max(d) + 1));
            }
            for (rows, cols) in windows {
                ConstraintMaps::rasterize_band_cols(&mut band, &s, &g, rows.clone(), cols.clone());
                let w = cols.len();
                for (r, j) in rows.clone().enumerate() {
                    for (c, i) in cols.clone().enumerate() {
                        let (k, l) = (r * w + c, j * n + i);
                        let pairs = [
                            (band.elev_weight[k], full.elev_weight[l]),
                            (band.elev_value[k], full.elev_value[l]),
                            (band.band_weight[k], full.band_weight[l]),
                            (band.grad_x[k], full.grad_x[l]),
                            (band.grad_y[k], full.grad_y[l]),
                            (band.rough_weight[k], full.rough_weight[l]),
                            (band.rough_value[k], full.rough_value[l]),
                        ];
                        for (m, (a, b)) in pairs.iter().enumerate() {
                            assert_eq!(
                                a.to_bits(),
                                b.to_bits(),
                                "map {m} at ({i},{j}), window {rows:?} x {cols:?}"
                            );
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn stroke_spans_cover_every_texel_the_stroke_changes() {
        let s = terrasketch_sketch::benchmark_sketch();
        let n = 128;
        let g = Grid::new(n, s.extent_m).unwrap();
        let full = ConstraintMaps::rasterize(&s, &g);
        for stroke in 0..s.strokes.len() {
            let mut without = s.clone();
            without.strokes.remove(stroke);
            let other = ConstraintMaps::rasterize(&without, &g);
            let spans = ConstraintMaps::stroke_spans(&s, stroke, &g);
            let covered = |i: usize, j: usize| spans.iter().any(|(r, c)| *r == j && c.contains(&i));
            let mut changed = 0;
            for j in 0..n {
                for i in 0..n {
                    let l = j * n + i;
                    let differs = [
                        (&full.elev_weight, &other.elev_weight),
                        (&full.elev_value, &other.elev_value),
                        (&full.band_weight, &other.band_weight),
                        (&full.grad_x, &other.grad_x),
                        (&full.grad_y, &other.grad_y),
                        (&full.rough_weight, &other.rough_weight),
                        (&full.rough_value, &other.rough_value),
                    ]
                    .iter()
                    .any(|(a, b)| a[l].to_bits() != b[l].to_bits());
                    if differs {
                        changed += 1;
                        assert!(
                            covered(i, j),
                            "stroke {stroke} changes ({i},{j}) outside its spans"
                        );
                    }
                }
            }
            assert!(changed > 0, "stroke {stroke} changes nothing");
            // Spans are narrower than whole rows (they are worth having).
            let cells: usize = spans.iter().map(|(_, c)| c.len()).sum();
            assert!(cells < n * n, "stroke {stroke}: spans cover the whole grid");
        }
    }
}
