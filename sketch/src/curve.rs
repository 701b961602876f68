//! A stroke's curve: its control points turned into the fine polyline that the rasterisers (CPU and
//! GPU) and the editor all use ([`stroke_curve`]), and the simplification of freehand input into a
//! few control points ([`simplify`]).
//!
//! Smooth strokes are centripetal Catmull-Rom curves (knot spacing the square root of the distance
//! seen from above): unlike the uniform variant they have no cusps or self-intersections within a
//! span, and unlike the chordal one they stay close to the control polygon on uneven spacing.
//! Heights use the same knots, with their tangents limited as Fritsch and Carlson's monotone cubic
//! does, so the heights between two points never leave the range of those two points.

use crate::model::{CurveKind, Sketch, Stroke};

/// Largest turn of the curve's direction over one tessellated segment (1 degree), unless that
/// would make segments shorter than [`MIN_SEGMENT_CELLS`]: the direction from the curve to the land
/// then changes by about a degree every cell or two instead of jumping at each control point.
pub const MAX_TURN_RAD: f64 = 1.0 * std::f64::consts::PI / 180.0;
/// Longest tessellated segment, in cells (heights along a straight span still follow the cubic).
const MAX_SEGMENT_CELLS: f64 = 16.0;
/// Shortest tessellated segment, in cells, unless the span itself is shorter (finer segments cost
/// the rasteriser without changing the solved terrain: measured in `multigrid/ALGORITHM.md`).
const MIN_SEGMENT_CELLS: f64 = 2.0;
/// Samples per span used to measure its turn and length.
const PROBES: usize = 32;
/// Most segments of a span.
const MAX_SPAN_SEGMENTS: usize = 4096;
/// Most tessellated segments of a whole sketch (shared between strokes in proportion to their
/// spans, never fewer than [`MIN_STROKE_SEGMENTS`] per stroke): hostile input stays bounded.
pub const MAX_CURVE_SEGMENTS: usize = 1 << 20;
const MIN_STROKE_SEGMENTS: usize = 16;

/// A stroke's curve as a polyline (seen from above and with heights), in metres.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Curve {
    /// The polyline's points. A closed curve repeats its first point at the end. One point for a
    /// stroke whose points all coincide seen from above; empty if a coordinate is not finite.
    pub points: Vec<[f64; 3]>,
    /// A loop (at least three distinct control points): the last segment joins the first.
    pub closed: bool,
}

/// The curves of every stroke of `sketch` for a grid of cells of side `cell_m` (the larger side).
pub fn stroke_curves(sketch: &Sketch, cell_m: f64) -> Vec<Curve> {
    let total = total_spans(sketch);
    sketch
        .strokes
        .iter()
        .map(|s| curve_with_budget(s, cell_m, budget(s, total)))
        .collect()
}

/// The curve of stroke `index` of `sketch` (as in [`stroke_curves`]); empty if there is no such
/// stroke.
pub fn stroke_curve(sketch: &Sketch, index: usize, cell_m: f64) -> Curve {
    match sketch.strokes.get(index) {
        Some(s) => curve_with_budget(s, cell_m, budget(s, total_spans(sketch))),
        None => Curve::default(),
    }
}

fn total_spans(sketch: &Sketch) -> usize {
    sketch.strokes.iter().map(|s| s.points.len()).sum()
}

fn budget(stroke: &Stroke, total_spans: usize) -> usize {
    let share = MAX_CURVE_SEGMENTS as f64 * stroke.points.len() as f64 / total_spans.max(1) as f64;
    (share as usize).max(MIN_STROKE_SEGMENTS)
}

/// The control points without repeats seen from above (the first of equal neighbours kept; for a
/// loop, also without trailing points on the first one), and whether the curve is a loop.
pub(crate) fn distinct_points(stroke: &Stroke) -> (Vec<[f64; 3]>, bool) {
    let same = |a: &[f64; 3], b: &[f64; 3]| a[0] == b[0] && a[1] == b[1];
    let mut pts: Vec<[f64; 3]> = Vec::with_capacity(stroke.points.len());
    for p in &stroke.points {
        if !pts.last().is_some_and(|q| same(q, p)) {
            pts.push(*p);
        }
    }
    if stroke.closed {
        while pts.len() > 1 && same(&pts[0], &pts[pts.len() - 1]) {
            pts.pop();
        }
    }
    let closed = stroke.closed && pts.len() >= 3;
    (pts, closed)
}

fn curve_with_budget(stroke: &Stroke, cell_m: f64, max_segments: usize) -> Curve {
    if !stroke.points.iter().flatten().all(|v| v.is_finite()) {
        return Curve::default();
    }
    let (pts, closed) = distinct_points(stroke);
    if pts.len() < 2 {
        return Curve {
            points: pts,
            closed: false,
        };
    }
    let mut points = match stroke.curve {
        CurveKind::Polyline => pts.clone(),
        CurveKind::Smooth => tessellate(&pts, closed, cell_m, max_segments),
    };
    if closed && stroke.curve == CurveKind::Polyline {
        points.push(pts[0]);
    }
    Curve { points, closed }
}

/// Distance seen from above.
fn dist_xy(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    (dx * dx + dy * dy).sqrt()
}

/// The centripetal Catmull-Rom curve through `pts` (distinct neighbours, at least two), as one
/// Hermite cubic per span.
struct Spline<'a> {
    pts: &'a [[f64; 3]],
    closed: bool,
    /// Per point, the tangent with respect to the knot parameter.
    tangents: Vec<[f64; 3]>,
}

impl<'a> Spline<'a> {
    fn new(pts: &'a [[f64; 3]], closed: bool) -> Spline<'a> {
        let n = pts.len();
        let tangents = (0..n)
            .map(|i| {
                let b = pts[i];
                // Open ends: a neighbour mirrored through the end point.
                let a = match (i, closed) {
                    (0, false) => mirror(&pts[0], &pts[1]),
                    (0, true) => pts[n - 1],
                    _ => pts[i - 1],
                };
                let c = match (i + 1 == n, closed) {
                    (true, false) => mirror(&pts[n - 1], &pts[n - 2]),
                    (true, true) => pts[0],
                    _ => pts[i + 1],
                };
                tangent(&a, &b, &c)
            })
            .collect();
        Spline {
            pts,
            closed,
            tangents,
        }
    }

    fn spans(&self) -> usize {
        self.pts.len() - usize::from(!self.closed)
    }

    /// Span `k` (from point `k` to the next) at `u` in `[0, 1]`.
    fn eval(&self, k: usize, u: f64) -> [f64; 3] {
        let n = self.pts.len();
        let (p1, p2) = (&self.pts[k], &self.pts[(k + 1) % n]);
        let d = dist_xy(p1, p2).sqrt();
        let (m1, m2) = (&self.tangents[k], &self.tangents[(k + 1) % n]);
        let (u2, u3) = (u * u, u * u * u);
        let h00 = 2.0 * u3 - 3.0 * u2 + 1.0;
        let h10 = u3 - 2.0 * u2 + u;
        let h01 = -2.0 * u3 + 3.0 * u2;
        let h11 = u3 - u2;
        std::array::from_fn(|c| h00 * p1[c] + h10 * d * m1[c] + h01 * p2[c] + h11 * d * m2[c])
    }
}

impl Spline<'_> {
    /// The direction of span `k` at `u` seen from above (its derivative; not normalised).
    fn direction(&self, k: usize, u: f64) -> [f64; 2] {
        let n = self.pts.len();
        let (p1, p2) = (&self.pts[k], &self.pts[(k + 1) % n]);
        let d = dist_xy(p1, p2).sqrt();
        let (m1, m2) = (&self.tangents[k], &self.tangents[(k + 1) % n]);
        let u2 = u * u;
        let h00 = 6.0 * u2 - 6.0 * u;
        let h10 = 3.0 * u2 - 4.0 * u + 1.0;
        let h11 = 3.0 * u2 - 2.0 * u;
        std::array::from_fn(|c| h00 * (p1[c] - p2[c]) + h10 * d * m1[c] + h11 * d * m2[c])
    }
}

fn mirror(end: &[f64; 3], next: &[f64; 3]) -> [f64; 3] {
    std::array::from_fn(|c| 2.0 * end[c] - next[c])
}

/// The centripetal Catmull-Rom tangent at `b` between neighbours `a` and `c` (with respect to the
/// knot parameter, knots `sqrt` of the distances seen from above), its height component limited so
/// that the heights stay monotone between points (0 at a height extremum, at most 3 times the
/// smaller neighbouring secant).
fn tangent(a: &[f64; 3], b: &[f64; 3], c: &[f64; 3]) -> [f64; 3] {
    let d0 = dist_xy(a, b).sqrt();
    let d1 = dist_xy(b, c).sqrt();
    let mut m: [f64; 3] = std::array::from_fn(|k| {
        (b[k] - a[k]) / d0 - (c[k] - a[k]) / (d0 + d1) + (c[k] - b[k]) / d1
    });
    let (s0, s1) = ((b[2] - a[2]) / d0, (c[2] - b[2]) / d1);
    m[2] = if s0 * s1 <= 0.0 || m[2] * s0 <= 0.0 {
        0.0
    } else {
        let limit = 3.0 * s0.abs().min(s1.abs());
        m[2].clamp(-limit, limit)
    };
    m
}

/// The smooth curve through `pts` as a polyline: each span cut into segments that turn by at most
/// [`MAX_TURN_RAD`] and are at most [`MAX_SEGMENT_CELLS`] long (not shorter than
/// [`MIN_SEGMENT_CELLS`]), placed at equal steps of that measure along the span; every control point
/// is a vertex.
fn tessellate(pts: &[[f64; 3]], closed: bool, cell_m: f64, max_segments: usize) -> Vec<[f64; 3]> {
    let spline = Spline::new(pts, closed);
    let cell = if cell_m.is_finite() && cell_m > 0.0 {
        cell_m
    } else {
        1.0
    };
    // Per span: cumulative measure at the probes, and the segment count.
    let mut plans: Vec<(Vec<f64>, usize)> = (0..spline.spans())
        .map(|k| {
            let probe: Vec<[f64; 3]> = (0..=PROBES)
                .map(|j| spline.eval(k, j as f64 / PROBES as f64))
                .collect();
            let mut cum = vec![0.0; PROBES + 1];
            let mut length = 0.0;
            let mut dir = spline.direction(k, 0.0);
            for j in 1..=PROBES {
                let len = dist_xy(&probe[j - 1], &probe[j]);
                let next = spline.direction(k, j as f64 / PROBES as f64);
                let turn = (dir[0] * next[1] - dir[1] * next[0])
                    .atan2(dir[0] * next[0] + dir[1] * next[1])
                    .abs();
                dir = next;
                length += len;
                cum[j] = cum[j - 1] + (turn / MAX_TURN_RAD).max(len / (MAX_SEGMENT_CELLS * cell));
            }
            let wanted = cum[PROBES].ceil().max(1.0);
            let most = (length / (MIN_SEGMENT_CELLS * cell)).floor().max(1.0);
            let m = wanted.min(most).min(MAX_SPAN_SEGMENTS as f64) as usize;
            (cum, m.max(1))
        })
        .collect();
    // Over budget: fewer segments everywhere, in proportion.
    let total: usize = plans.iter().map(|p| p.1).sum();
    if total > max_segments {
        let scale = max_segments as f64 / total as f64;
        for p in &mut plans {
            p.1 = ((p.1 as f64 * scale) as usize).max(1);
        }
    }
    let mut out = Vec::with_capacity(plans.iter().map(|p| p.1).sum::<usize>() + 1);
    out.push(pts[0]);
    for (k, (cum, m)) in plans.iter().enumerate() {
        let total = cum[PROBES];
        let mut j = 0;
        for s in 1..*m {
            let target = total * s as f64 / *m as f64;
            while j + 1 < PROBES && cum[j + 1] <= target {
                j += 1;
            }
            let step = cum[j + 1] - cum[j];
            let frac = if step > 0.0 {
                ((target - cum[j]) / step).clamp(0.0, 1.0)
            } else {
                0.0
            };
            out.push(spline.eval(k, (j as f64 + frac) / PROBES as f64));
        }
        out.push(pts[(k + 1) % pts.len()]);
    }
    out
}

/// Freehand samples reduced to control points (Douglas-Peucker): the first and last samples are
/// kept, and a sample is kept where the kept points' polyline would pass farther than `tol_xy_m`
/// from it seen from above, or `tol_z_m` from its height. Non-finite tolerances keep every sample.
pub fn simplify(samples: &[[f64; 3]], tol_xy_m: f64, tol_z_m: f64) -> Vec<[f64; 3]> {
    let n = samples.len();
    if n <= 2 || !(tol_xy_m > 0.0 && tol_z_m > 0.0) {
        return samples.to_vec();
    }
    let mut keep = vec![false; n];
    keep[0] = true;
    keep[n - 1] = true;
    let mut stack = vec![(0, n - 1)];
    while let Some((a, b)) = stack.pop() {
        if b <= a + 1 {
            continue;
        }
        let (pa, pb) = (&samples[a], &samples[b]);
        let (ex, ey) = (pb[0] - pa[0], pb[1] - pa[1]);
        let len2 = ex * ex + ey * ey;
        let mut worst = (1.0, 0);
        for (i, p) in samples.iter().enumerate().take(b).skip(a + 1) {
            let t = if len2 > 0.0 {
                (((p[0] - pa[0]) * ex + (p[1] - pa[1]) * ey) / len2).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let dxy = (p[0] - pa[0] - t * ex).hypot(p[1] - pa[1] - t * ey);
            let dz = (p[2] - (pa[2] + t * (pb[2] - pa[2]))).abs();
            let dev = (dxy / tol_xy_m).max(dz / tol_z_m);
            if dev > worst.0 {
                worst = (dev, i);
            }
        }
        if worst.1 > 0 {
            keep[worst.1] = true;
            stack.push((a, worst.1));
            stack.push((worst.1, b));
        }
    }
    samples
        .iter()
        .zip(keep)
        .filter_map(|(p, k)| k.then_some(*p))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::StrokeKind;

    fn circle(count: usize, radius: f64) -> Vec<[f64; 3]> {
        (0..count)
            .map(|k| {
                let a = std::f64::consts::TAU * k as f64 / count as f64;
                [5000.0 + radius * a.cos(), 5000.0 + radius * a.sin(), 100.0]
            })
            .collect()
    }

    fn sketch_of(stroke: Stroke) -> Sketch {
        Sketch {
            extent_m: [10000.0, 10000.0],
            base_elevation_m: 0.0,
            seed: 0,
            strokes: vec![stroke],
        }
    }

    /// Largest turn between consecutive segments of a polyline, radians.
    fn max_turn(points: &[[f64; 3]]) -> f64 {
        points
            .windows(3)
            .map(|w| {
                let (ux, uy) = (w[1][0] - w[0][0], w[1][1] - w[0][1]);
                let (vx, vy) = (w[2][0] - w[1][0], w[2][1] - w[1][1]);
                (ux * vy - uy * vx).atan2(ux * vx + uy * vy).abs()
            })
            .fold(0.0, f64::max)
    }

    #[test]
    fn a_closed_smooth_curve_through_a_circle_is_round_and_fine() {
        let mut s = Stroke::new(StrokeKind::Ridge, circle(12, 2000.0));
        s.closed = true;
        let c = stroke_curve(&sketch_of(s.clone()), 0, 10.0);
        assert!(c.closed);
        assert_eq!(c.points.first(), c.points.last());
        // Every control point is on the curve.
        for p in &s.points {
            assert!(c.points.contains(p));
        }
        // Close to the circle (a polygon of 12 is 68 m inside it at mid-chord), smooth through
        // the join too.
        let off = c
            .points
            .iter()
            .map(|p| ((p[0] - 5000.0).hypot(p[1] - 5000.0) - 2000.0).abs())
            .fold(0.0, f64::max);
        assert!(off < 5.0, "{off} m off the circle");
        let mut wrapped = c.points.clone();
        wrapped.push(c.points[1]);
        assert!(
            max_turn(&wrapped) < 1.5 * MAX_TURN_RAD,
            "{}",
            max_turn(&wrapped)
        );
        // The polyline version is the polygon.
        s.curve = CurveKind::Polyline;
        let p = stroke_curve(&sketch_of(s), 0, 10.0);
        assert_eq!(p.points.len(), 13);
        assert!(max_turn(&p.points) > 0.5);
    }

    #[test]
    fn heights_do_not_overshoot_and_a_straight_stroke_stays_straight() {
        let s = Stroke::new(
            StrokeKind::Valley,
            vec![
                [0.0, 0.0, 0.0],
                [1000.0, 0.0, 0.0],
                [1100.0, 0.0, 500.0],
                [3000.0, 0.0, 500.0],
            ],
        );
        let c = stroke_curve(&sketch_of(s), 0, 10.0);
        for p in &c.points {
            assert!(p[1] == 0.0, "left the line: {p:?}");
            assert!((0.0..=500.0).contains(&p[2]), "overshoot: {p:?}");
        }
        // Monotone in x and segments about `MAX_SEGMENT_CELLS` long at most (equal steps in the
        // span's parameter are nearly equal steps in length).
        for w in c.points.windows(2) {
            assert!(
                w[1][0] > w[0][0] && w[1][0] - w[0][0] <= 1.1 * MAX_SEGMENT_CELLS * 10.0,
                "{:?} -> {:?}",
                w[0],
                w[1]
            );
        }
    }

    #[test]
    fn degenerate_strokes_give_small_curves_without_panicking() {
        let dot = Stroke::new(StrokeKind::Plateau, vec![[1.0, 2.0, 3.0], [1.0, 2.0, 9.0]]);
        assert_eq!(
            stroke_curve(&sketch_of(dot), 0, 10.0).points,
            vec![[1.0, 2.0, 3.0]]
        );
        let mut two = Stroke::new(StrokeKind::Ridge, vec![[0.0, 0.0, 0.0], [100.0, 0.0, 0.0]]);
        two.closed = true;
        let c = stroke_curve(&sketch_of(two), 0, 10.0);
        assert!(!c.closed, "two points cannot make a loop");
        let bad = Stroke::new(
            StrokeKind::Ridge,
            vec![[0.0, 0.0, 0.0], [f64::NAN, 0.0, 0.0]],
        );
        assert!(stroke_curve(&sketch_of(bad), 0, 10.0).points.is_empty());
        // Far-flung points: the segment count stays bounded.
        let far = Stroke::new(
            StrokeKind::Ridge,
            vec![[0.0, 0.0, 0.0], [1e300, 1e300, 0.0], [-1e300, 1e300, 0.0]],
        );
        let c = stroke_curve(&sketch_of(far), 0, 1e-3);
        assert!(c.points.len() <= MAX_CURVE_SEGMENTS + 1);
    }

    #[test]
    fn simplify_keeps_the_shape_with_few_points() {
        // 400 samples of a half circle of radius 1000 m: a few tens of points within 2 m.
        let samples: Vec<[f64; 3]> = (0..400)
            .map(|k| {
                let a = std::f64::consts::PI * k as f64 / 399.0;
                [1000.0 * a.cos(), 1000.0 * a.sin(), 50.0]
            })
            .collect();
        let kept = simplify(&samples, 2.0, 2.0);
        assert!(kept.len() > 5 && kept.len() < 40, "{}", kept.len());
        assert_eq!(kept.first(), samples.first());
        assert_eq!(kept.last(), samples.last());
        // The smooth curve through the kept points stays within the tolerance of every sample.
        let c = stroke_curve(&sketch_of(Stroke::new(StrokeKind::Ridge, kept)), 0, 1.0);
        for s in &samples {
            let d = c
                .points
                .windows(2)
                .map(|w| {
                    let (ex, ey) = (w[1][0] - w[0][0], w[1][1] - w[0][1]);
                    let t = (((s[0] - w[0][0]) * ex + (s[1] - w[0][1]) * ey) / (ex * ex + ey * ey))
                        .clamp(0.0, 1.0);
                    (s[0] - w[0][0] - t * ex).hypot(s[1] - w[0][1] - t * ey)
                })
                .fold(f64::INFINITY, f64::min);
            assert!(d < 2.0, "sample {s:?} is {d} m from the curve");
        }
    }
}
