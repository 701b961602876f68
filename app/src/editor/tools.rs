//! Tools and pointer gestures: drawing strokes (projected as the paper says), dragging handles, moving
//! and deleting strokes. Pure logic on the document; the caller re-solves the rows returned.
//!
//! Drawing: the pointer's samples are kept in window pixels with the camera of the stroke's start.
//! Each is cast onto the terrain as it was when the stroke began (a frozen copy of the displayed mip,
//! the "depth map"). Ridges and valleys are projected onto the vertical plane through the first sample
//! that touches the terrain and the current end (its hit on the frozen terrain): above the surface
//! raises, below digs. Plateaus are projected onto the horizontal plane at the first touching point.

use std::ops::Range;

use glam::{Vec2, Vec3};
use terrasketch_sketch::{CurveKind, Falloff, Sketch, Stroke, StrokeKind};

use super::camera::{Projection, Ray};
use super::doc::Document;
use super::heightfield::HeightField;
use super::terrain::Terrain;

/// The editing tools.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Tool {
    /// Draw a ridge / mountain.
    Ridge,
    /// Draw a valley / crevice.
    Valley,
    /// Draw a plateau.
    Plateau,
    /// Select strokes, drag handles, move strokes.
    Select,
    /// Delete the stroke clicked.
    Delete,
}

impl Tool {
    /// All tools, in toolbar order.
    pub const ALL: [Tool; 5] = [
        Tool::Ridge,
        Tool::Valley,
        Tool::Plateau,
        Tool::Select,
        Tool::Delete,
    ];

    /// Name used in sessions and logs.
    pub fn name(self) -> &'static str {
        match self {
            Tool::Ridge => "ridge",
            Tool::Valley => "valley",
            Tool::Plateau => "plateau",
            Tool::Select => "select",
            Tool::Delete => "delete",
        }
    }

    /// Parses a tool name.
    pub fn parse(name: &str) -> Option<Tool> {
        Tool::ALL.into_iter().find(|t| t.name() == name)
    }

    fn stroke_kind(self) -> Option<StrokeKind> {
        match self {
            Tool::Ridge => Some(StrokeKind::Ridge),
            Tool::Valley => Some(StrokeKind::Valley),
            Tool::Plateau => Some(StrokeKind::Plateau),
            _ => None,
        }
    }
}

/// One pointer sample of a stroke being drawn.
struct Sample {
    px: Vec2,
    ray: Ray,
    /// Hit on the frozen terrain.
    hit: Option<Vec3>,
}

/// A stroke being drawn.
pub struct Drawing {
    kind: StrokeKind,
    proj: Projection,
    frozen: HeightField,
    samples: Vec<Sample>,
    /// Index of the stroke in the sketch once it has two points.
    index: Option<usize>,
    before: Sketch,
}

/// What the left button is doing.
pub enum Gesture {
    /// Nothing.
    Idle,
    /// Drawing a stroke.
    Draw(Box<Drawing>),
    /// Dragging an end handle on the horizontal plane through it.
    Handle {
        stroke: usize,
        first: bool,
        orig: Stroke,
        before: Sketch,
    },
    /// Moving a whole stroke in plan.
    Move {
        stroke: usize,
        grab_m: Vec3,
        orig: Stroke,
        before: Sketch,
    },
}

/// Pixels within which a handle or a stroke is picked.
const HANDLE_PICK_PX: f32 = 12.0;
const STROKE_PICK_PX: f32 = 8.0;

/// Window positions of a stroke's points (None behind the camera).
pub fn stroke_screen(proj: &Projection, s: &Stroke) -> Vec<Option<Vec2>> {
    s.points
        .iter()
        .map(|p| proj.screen_position(Vec3::new(p[0] as f32, p[1] as f32, p[2] as f32)))
        .collect()
}

/// Cells per side of the grid the editor tessellates curves for (drawing, picking): the solver's
/// curve as the 1024^2 rasteriser cuts it, finer than any stroke line on screen.
const CURVE_GRID: f64 = 1024.0;
/// Freehand samples are simplified to control points within this many cells (of the terrain being
/// drawn on) of every sample, in plan and in height.
const SIMPLIFY_CELLS: f32 = 2.0;

/// Stroke `i`'s curve as a polyline (the smooth curve through its points; a loop repeats its
/// first point), in metres.
pub fn stroke_curve_points(sketch: &Sketch, i: usize) -> Vec<[f64; 3]> {
    let cell = sketch.extent_m[0].max(sketch.extent_m[1]) / CURVE_GRID;
    terrasketch_sketch::stroke_curve(sketch, i, cell).points
}

/// Window positions of stroke `i`'s curve (None behind the camera).
fn curve_screen(proj: &Projection, sketch: &Sketch, i: usize) -> Vec<Option<Vec2>> {
    stroke_curve_points(sketch, i)
        .iter()
        .map(|p| proj.screen_position(Vec3::new(p[0] as f32, p[1] as f32, p[2] as f32)))
        .collect()
}

/// A stroke's curve options: how its points become a curve, whether it is a loop, and its slope
/// falloff.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Shape {
    /// Smooth curve or polyline.
    pub curve: CurveKind,
    /// A loop.
    pub closed: bool,
    /// Slope falloff towards the band edge.
    pub falloff: Falloff,
}

impl Shape {
    /// The options of `s`.
    pub fn of(s: &Stroke) -> Shape {
        Shape {
            curve: s.curve,
            closed: s.closed,
            falloff: s.falloff,
        }
    }
}

/// Whether stroke `s` has enough distinct points to be a loop (the format refuses a closed stroke
/// with fewer than 3).
pub fn can_close(s: &Stroke) -> bool {
    let mut probe = s.clone();
    probe.closed = true;
    terrasketch_sketch::validate(&Sketch {
        extent_m: [1.0, 1.0],
        base_elevation_m: 0.0,
        seed: 0,
        strokes: vec![probe],
    })
    .is_ok()
}

/// Sets stroke `i`'s curve options as one undoable edit (a loop only if it can close); returns
/// the rows to re-solve.
pub fn set_shape(doc: &mut Document, terrain: &Terrain, i: usize, shape: Shape) -> Range<usize> {
    let Some(s) = doc.sketch.strokes.get(i) else {
        return 0..0;
    };
    let closed = shape.closed && can_close(s);
    let before = doc.sketch.clone();
    let s = &mut doc.sketch.strokes[i];
    s.curve = shape.curve;
    s.closed = closed;
    s.falloff = shape.falloff;
    let rows = terrain.diff_rows(&before, &doc.sketch);
    doc.commit(before);
    rows
}

/// The handle (stroke, first?) under the pointer, nearest first.
pub fn pick_handle(proj: &Projection, sketch: &Sketch, px: Vec2) -> Option<(usize, bool)> {
    let mut best: Option<(f32, usize, bool)> = None;
    for (i, s) in sketch.strokes.iter().enumerate() {
        let (Some(a), Some(b)) = (s.points.first(), s.points.last()) else {
            continue;
        };
        for (p, first) in [(a, true), (b, false)] {
            if let Some(q) = proj.screen_position(Vec3::new(p[0] as f32, p[1] as f32, p[2] as f32))
            {
                let d = q.distance(px);
                if d < HANDLE_PICK_PX && best.is_none_or(|(bd, _, _)| d < bd) {
                    best = Some((d, i, first));
                }
            }
        }
    }
    best.map(|(_, i, f)| (i, f))
}

/// The stroke whose curve passes under the pointer.
pub fn pick_stroke(proj: &Projection, sketch: &Sketch, px: Vec2) -> Option<usize> {
    let mut best: Option<(f32, usize)> = None;
    for i in 0..sketch.strokes.len() {
        let pts = curve_screen(proj, sketch, i);
        for w in pts.windows(2) {
            let (Some(a), Some(b)) = (w[0], w[1]) else {
                continue;
            };
            let ab = b - a;
            let t = if ab.length_squared() > 0.0 {
                ((px - a).dot(ab) / ab.length_squared()).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let d = (a + ab * t).distance(px);
            if d < STROKE_PICK_PX && best.is_none_or(|(bd, _)| d < bd) {
                best = Some((d, i));
            }
        }
    }
    best.map(|(_, i)| i)
}

/// Starts a gesture for `tool` at `px`. Returns the gesture and the rows changed (delete).
pub fn begin(
    tool: Tool,
    px: Vec2,
    doc: &mut Document,
    terrain: &Terrain,
    proj: &Projection,
) -> (Gesture, Range<usize>) {
    if let Some(kind) = tool.stroke_kind() {
        let Some(frozen) = terrain.field() else {
            return (Gesture::Idle, 0..0);
        };
        let mut d = Drawing {
            kind,
            proj: *proj,
            frozen,
            samples: Vec::new(),
            index: None,
            before: doc.sketch.clone(),
        };
        add_sample(&mut d, px);
        return (Gesture::Draw(Box::new(d)), 0..0);
    }
    match tool {
        Tool::Select => {
            if let Some((i, first)) = pick_handle(proj, &doc.sketch, px) {
                doc.selected = Some(i);
                let orig = doc.sketch.strokes[i].clone();
                return (
                    Gesture::Handle {
                        stroke: i,
                        first,
                        orig,
                        before: doc.sketch.clone(),
                    },
                    0..0,
                );
            }
            if let Some(i) = pick_stroke(proj, &doc.sketch, px) {
                doc.selected = Some(i);
                let orig = doc.sketch.strokes[i].clone();
                let z =
                    orig.points.iter().map(|p| p[2]).sum::<f64>() / orig.points.len().max(1) as f64;
                if let Some(grab_m) = proj.ray(px).hit_horizontal(z as f32) {
                    return (
                        Gesture::Move {
                            stroke: i,
                            grab_m,
                            orig,
                            before: doc.sketch.clone(),
                        },
                        0..0,
                    );
                }
                return (Gesture::Idle, 0..0);
            }
            doc.selected = None;
            (Gesture::Idle, 0..0)
        }
        Tool::Delete => {
            if let Some(i) = pick_stroke(proj, &doc.sketch, px)
                .or_else(|| pick_handle(proj, &doc.sketch, px).map(|h| h.0))
            {
                return (Gesture::Idle, delete_stroke(doc, terrain, i));
            }
            (Gesture::Idle, 0..0)
        }
        _ => (Gesture::Idle, 0..0),
    }
}

/// Deletes stroke `i` as one undoable edit; returns the rows to re-solve.
pub fn delete_stroke(doc: &mut Document, terrain: &Terrain, i: usize) -> Range<usize> {
    if i >= doc.sketch.strokes.len() {
        return 0..0;
    }
    let before = doc.sketch.clone();
    doc.sketch.strokes.remove(i);
    doc.selected = None;
    let rows = terrain.diff_rows(&before, &doc.sketch);
    doc.commit(before);
    rows
}

fn add_sample(d: &mut Drawing, px: Vec2) {
    if d.samples.last().is_some_and(|s| s.px.distance(px) < 2.0) {
        return;
    }
    let ray = d.proj.ray(px);
    let hit = d.frozen.raycast(&ray);
    d.samples.push(Sample { px, ray, hit });
}

/// The stroke's control points from its samples (see the module comment), simplified
/// (Douglas-Peucker, `SIMPLIFY_CELLS`) so that a drawn stroke has a few points to edit.
fn project(d: &Drawing) -> Vec<[f64; 3]> {
    let Some(first) = d.samples.iter().position(|s| s.hit.is_some()) else {
        return Vec::new();
    };
    let p0 = d.samples[first].hit.unwrap_or(Vec3::ZERO);
    let end = d.samples.iter().rev().find_map(|s| s.hit).unwrap_or(p0);
    let size = d.frozen.extent_m[0].max(d.frozen.extent_m[1]);
    let cell = size / d.frozen.side as f32;
    let max_t = 4.0 * size + d.proj.eye_m.length();
    let normal = {
        let dxy = Vec2::new(end.x - p0.x, end.y - p0.y);
        if dxy.length() > cell {
            Vec3::new(-dxy.y, dxy.x, 0.0).normalize()
        } else {
            let f = d.samples[first].ray.dir;
            Vec3::new(f.x, f.y, 0.0).normalize_or(Vec3::Y)
        }
    };
    let mut out: Vec<[f64; 3]> = Vec::new();
    for s in &d.samples[first..] {
        let p = match d.kind {
            StrokeKind::Plateau => s
                .ray
                .hit_horizontal(p0.z)
                .filter(|p| (*p - s.ray.origin).length() < max_t),
            _ => s.ray.hit_plane(p0, normal, max_t),
        };
        let Some(p) = p.or(s.hit) else { continue };
        if let Some(last) = out.last()
            && Vec2::new(p.x - last[0] as f32, p.y - last[1] as f32).length() < 0.5 * cell
        {
            continue;
        }
        out.push([p.x as f64, p.y as f64, p.z as f64]);
    }
    let tol = (SIMPLIFY_CELLS * cell) as f64;
    terrasketch_sketch::simplify(&out, tol, tol)
}

/// Continues a gesture at `px`; returns the level-0 rows whose constraints changed.
pub fn update(
    g: &mut Gesture,
    px: Vec2,
    doc: &mut Document,
    terrain: &Terrain,
    proj: &Projection,
) -> Range<usize> {
    let before = doc.sketch.clone();
    match g {
        Gesture::Idle => return 0..0,
        Gesture::Draw(d) => {
            add_sample(d, px);
            let points = project(d);
            match (d.index, points.len() >= 2) {
                (Some(i), true) => doc.sketch.strokes[i].points = points,
                (Some(i), false) => {
                    doc.sketch.strokes.remove(i);
                    d.index = None;
                }
                (None, true) => {
                    doc.sketch.strokes.push(Stroke::new(d.kind, points));
                    d.index = Some(doc.sketch.strokes.len() - 1);
                    doc.selected = d.index;
                }
                (None, false) => {}
            }
        }
        Gesture::Handle {
            stroke,
            first,
            orig,
            ..
        } => {
            let (a, e) = if *first {
                (*orig.points.last().unwrap_or(&[0.0; 3]), orig.points[0])
            } else {
                (orig.points[0], *orig.points.last().unwrap_or(&[0.0; 3]))
            };
            let Some(e2) = proj.ray(px).hit_horizontal(e[2] as f32) else {
                return 0..0;
            };
            let w = (e[0] - a[0], e[1] - a[1]);
            let w2 = (e2.x as f64 - a[0], e2.y as f64 - a[1]);
            let ww = w.0 * w.0 + w.1 * w.1;
            let s = &mut doc.sketch.strokes[*stroke];
            if ww < 1e-6 {
                let (dx, dy) = (e2.x as f64 - e[0], e2.y as f64 - e[1]);
                for (p, o) in s.points.iter_mut().zip(&orig.points) {
                    *p = [o[0] + dx, o[1] + dy, o[2]];
                }
            } else {
                // Complex ratio w2 / w: rotation and scale about the fixed end.
                let r = (
                    (w2.0 * w.0 + w2.1 * w.1) / ww,
                    (w2.1 * w.0 - w2.0 * w.1) / ww,
                );
                for (p, o) in s.points.iter_mut().zip(&orig.points) {
                    let v = (o[0] - a[0], o[1] - a[1]);
                    *p = [
                        a[0] + v.0 * r.0 - v.1 * r.1,
                        a[1] + v.0 * r.1 + v.1 * r.0,
                        o[2],
                    ];
                }
            }
        }
        Gesture::Move {
            stroke,
            grab_m,
            orig,
            ..
        } => {
            let Some(p) = proj.ray(px).hit_horizontal(grab_m.z) else {
                return 0..0;
            };
            let (dx, dy) = ((p.x - grab_m.x) as f64, (p.y - grab_m.y) as f64);
            for (q, o) in doc.sketch.strokes[*stroke]
                .points
                .iter_mut()
                .zip(&orig.points)
            {
                *q = [o[0] + dx, o[1] + dy, o[2]];
            }
        }
    }
    terrain.diff_rows(&before, &doc.sketch)
}

/// Ends a gesture: records the undo step.
pub fn end(g: Gesture, doc: &mut Document) {
    match g {
        Gesture::Idle => {}
        Gesture::Draw(d) => doc.commit(d.before),
        Gesture::Handle { before, .. } | Gesture::Move { before, .. } => doc.commit(before),
    }
}

/// Cancels a gesture: restores the sketch; returns the rows to re-solve.
pub fn cancel(g: Gesture, doc: &mut Document, terrain: &Terrain) -> Range<usize> {
    let before = match g {
        Gesture::Idle => return 0..0,
        Gesture::Draw(d) => d.before,
        Gesture::Handle { before, .. } | Gesture::Move { before, .. } => before,
    };
    let rows = terrain.diff_rows(&doc.sketch, &before);
    doc.sketch = before;
    doc.selected = doc.selected.filter(|&i| i < doc.sketch.strokes.len());
    rows
}
