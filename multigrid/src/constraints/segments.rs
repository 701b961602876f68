//! A stroke prepared for rasterisation: its curve's polyline as segments with their boxes,
//! chunked so that a row tests a few boxes, and the conservative texel ranges of the segments
//! that can hold a texel's closest point.

use terrasketch_sketch::{Curve, Sketch, Stroke, StrokeKind};

use crate::grid::Grid;

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
    pub(super) closed: bool,
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
    pub(super) exhaustive: bool,
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
    pub(super) len: f64,
    pub(super) u: [f64; 2],
    /// Expanded bounding box in metres: x0, x1, y0, y1.
    pub(crate) bbox: [f64; 4],
    /// The rows (y, metres) the segment's region (`reach_interval`) can meet: its slab's when the
    /// turn to the next segment is gentle, else the box's (set by `prepare`).
    pub(super) ys: [f64; 2],
    /// The per-texel arithmetic's view (f32, as the GPU twin `rasterize.wgsl` packs it): `a` (x, y,
    /// z), `b.z - a.z`, `b - a` in x and y (differences of the f32 end points), `1 / |b - a|^2` (0 for a
    /// single point).
    pub(super) ax: f32,
    pub(super) ay: f32,
    pub(super) az: f32,
    pub(super) dz: f32,
    pub(super) ex32: f32,
    pub(super) ey32: f32,
    pub(super) inv32: f32,
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

/// The candidate segments of stroke `p` on row `j` with their texel ranges (clipped to
/// `0..cols.end`): a conservative range of the texels within `reach + c/2` of the stroke whose
/// closest point can be on the segment (`Seg::reach_interval`). Empty ranges are left out; so are
/// the segments whose box lies clear of the columns `cols` (their ranges, inside the box widened
/// by a cell, would be clipped away by the caller).
pub(super) fn candidate_ranges(
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
pub(super) fn reach_m(p: &Prepared, cell: f64) -> f64 {
    p.width_m as f64 + 1.5 * cell
}

/// Stroke `index` of `sketch` prepared (`None` if there is none or it has no finite curve).
pub(super) fn prepare_one(
    sketch: &Sketch,
    index: usize,
    grid: &Grid,
    cell: f64,
) -> Option<Prepared> {
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
pub(super) fn prepare(stroke: &Stroke, curve: Curve, grid: &Grid, cell: f64) -> Option<Prepared> {
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
