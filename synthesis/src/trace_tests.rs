//! `trace` on analytic terrains whose valleys and ridges, slopes and widths are known.

use terrasketch_sketch::{Falloff, StrokeKind};

use crate::trace::{TraceError, TraceGrid, TraceParams, Traced, trace};
use crate::trace_profile::{cumulative, cumulative_raw};

const N: usize = 128;
const CELL: f64 = 30.0;
/// The valley (or ridge) axis: the centre of column 64.
const AXIS: usize = 64;

/// A north-south terrain `f(d, row)`, `d` the signed distance east of the axis in metres.
fn terrain(f: impl Fn(f64, usize) -> f64) -> Vec<f32> {
    (0..N * N)
        .map(|i| f(((i % N) as f64 - AXIS as f64) * CELL, i / N) as f32)
        .collect()
}

fn run(heights: &[f32], params: &TraceParams) -> Result<Traced, TraceError> {
    trace(
        &TraceGrid {
            heights,
            width: N,
            height: N,
            cell_size_m: [CELL, CELL],
        },
        params,
    )
}

fn tan(deg: f64) -> f64 {
    deg.to_radians().tan()
}

/// A V valley along the axis, its floor falling 2 degrees to the south; the west side rises at
/// `west(row)` degrees and the east side at `east(row)` to ridges 40 cells away, beyond which the
/// land falls again.
fn v_valley(west: impl Fn(usize) -> f64, east: impl Fn(usize) -> f64) -> Vec<f32> {
    let w = 40.0 * CELL;
    terrain(|d, row| {
        let floor = 500.0 + tan(2.0) * CELL * (N - 1 - row) as f64;
        let (up, down) = if d < 0.0 {
            (tan(west(row)), tan(east(row)))
        } else {
            (tan(east(row)), tan(west(row)))
        };
        let a = d.abs();
        floor
            + if a <= w {
                up * a
            } else {
                up * w - down * (a - w)
            }
    })
}

fn params(max_strokes: usize, falloff: Option<Falloff>) -> TraceParams {
    TraceParams {
        max_strokes,
        falloff,
        // Flow lines on the planar sides drain up to 64 cells: they are not channels.
        channel_cells: Some(200),
        ..TraceParams::default()
    }
}

#[test]
fn a_v_valley_is_traced_along_its_axis_with_its_slopes_width_and_heights() {
    let dem = v_valley(|_| 20.0, |_| 30.0);
    for falloff in [Some(Falloff::None), None] {
        let t = run(&dem, &params(2, falloff)).unwrap();
        assert_eq!((t.valleys, t.ridges), (1, 1), "{:?}", t.warnings);
        let v = &t.sketch.strokes[1];
        assert_eq!(v.kind, StrokeKind::Valley);
        // A straight line: few control points, all on the axis, the DEM's heights.
        assert!(v.points.len() <= 4, "{} points", v.points.len());
        for p in &v.points {
            let col = p[0] / CELL - 0.5;
            let row = N as f64 - p[1] / CELL - 0.5;
            assert!((col - AXIS as f64).abs() < 0.01, "{p:?} off the axis");
            let dem_h = f64::from(dem[row.round() as usize * N + AXIS]);
            assert!((p[2] - dem_h).abs() < 1e-3, "{p:?}: the DEM has {dem_h}");
        }
        let (first, last) = (v.points[0], v.points[v.points.len() - 1]);
        assert!(first[1] > last[1], "drawn downstream (north to south)");
        assert!(first[1] - last[1] > 100.0 * CELL, "{first:?} .. {last:?}");
        // Travelling south, the left is the east side (30 degrees), the right the west (20), both
        // rising 40 cells to the crests; a fading falloff keeps that rise with a steeper start.
        assert!((v.width_m - 1200.0).abs() <= CELL, "{}", v.width_m);
        assert_eq!(v.falloff, falloff.unwrap_or(Falloff::Foot));
        let k = cumulative_raw(v.falloff, 1.0);
        for (slope, deg) in [(v.slope_left_deg, 30.0), (v.slope_right_deg, 20.0)] {
            let rise = tan(slope) * k * v.width_m;
            let want = tan(deg) * 1200.0;
            assert!(
                (rise - want).abs() < 0.02 * want,
                "{slope} deg: rise {rise}, DEM {want}"
            );
        }
    }
}

#[test]
fn a_ridge_gets_the_falloff_of_its_profile_and_its_slope() {
    let (w, slope) = (20.0 * CELL, 25.0);
    for shape in [Falloff::Foot, Falloff::Sigmoid] {
        // Heights below the crest: the band's rise with this falloff, flat beyond the band.
        let k = cumulative_raw(shape, 1.0);
        let drop = |d: f64| tan(slope) * w * k * cumulative(shape, (d.abs() / w).min(1.0));
        let dem = terrain(|d, row| 900.0 + tan(1.0) * CELL * (N - 1 - row) as f64 - drop(d));
        let t = run(&dem, &params(2, None)).unwrap();
        let r = &t.sketch.strokes[0];
        assert_eq!(r.kind, StrokeKind::Ridge);
        assert!(
            r.points
                .iter()
                .all(|p| (p[0] / CELL - 0.5 - AXIS as f64).abs() < 0.01)
        );
        assert_eq!(r.falloff, shape);
        for s in [r.slope_left_deg, r.slope_right_deg] {
            assert!((s - slope).abs() < 1.0, "{shape:?}: {s}");
        }
        assert!((r.width_m - w).abs() <= CELL, "{}", r.width_m);
    }
}

#[test]
fn a_valley_whose_slopes_change_is_cut_where_they_change() {
    let side = |row: usize| if row < 64 { 10.0 } else { 35.0 };
    let dem = v_valley(side, side);
    let t = run(&dem, &params(4, Some(Falloff::None))).unwrap();
    assert_eq!(t.lines_split, 1);
    let valleys: Vec<_> = t
        .sketch
        .strokes
        .iter()
        .filter(|s| s.kind == StrokeKind::Valley)
        .collect();
    assert_eq!(valleys.len(), 2);
    // Downstream pieces come first.
    let (north, south) = (valleys[1], valleys[0]);
    assert_eq!(north.points.last(), south.points.first(), "the pieces join");
    let cut_row = N as f64 - south.points[0][1] / CELL - 0.5;
    assert!((cut_row - 64.0).abs() <= 8.0, "cut at row {cut_row}");
    for s in [north.slope_left_deg, north.slope_right_deg] {
        assert!((s - 10.0).abs() < 1.5, "north {s}");
    }
    for s in [south.slope_left_deg, south.slope_right_deg] {
        assert!((s - 35.0).abs() < 1.5, "south {s}");
    }
}

#[test]
fn a_flat_dem_gives_an_empty_sketch_with_a_warning() {
    let t = run(&vec![321.0; N * N], &TraceParams::default()).unwrap();
    assert!(t.sketch.strokes.is_empty());
    assert_eq!(t.sketch.base_elevation_m, 321.0);
    assert_eq!(t.sketch.extent_m, [N as f64 * CELL; 2]);
    assert!(
        t.warnings.iter().any(|w| w.contains("flat")),
        "{:?}",
        t.warnings
    );
}

#[test]
fn bad_grids_and_options_are_refused() {
    let tiny = TraceGrid {
        heights: &[0.0; 64],
        width: 8,
        height: 8,
        cell_size_m: [CELL, CELL],
    };
    assert!(matches!(
        trace(&tiny, &TraceParams::default()),
        Err(TraceError::TooSmall { .. })
    ));
    let mut dem = v_valley(|_| 20.0, |_| 30.0);
    for p in [params(0, None), params(1_000_000, None)] {
        assert!(matches!(run(&dem, &p), Err(TraceError::BadInput(_))));
    }
    let p = TraceParams {
        min_length_m: Some(f64::NAN),
        ..TraceParams::default()
    };
    assert!(matches!(run(&dem, &p), Err(TraceError::BadInput(_))));
    let short = TraceGrid {
        heights: &dem[..N * N - 1],
        width: N,
        height: N,
        cell_size_m: [CELL, CELL],
    };
    assert!(matches!(
        trace(&short, &TraceParams::default()),
        Err(TraceError::BadInput(_))
    ));
    dem[5] = f32::NAN;
    assert!(matches!(
        run(&dem, &TraceParams::default()),
        Err(TraceError::BadInput(_))
    ));
    // Heights past the format's +-100 km: the sketch is refused, not written.
    let absurd = vec![1e6f32; N * N];
    let mut ramp = absurd.clone();
    ramp.iter_mut()
        .enumerate()
        .for_each(|(i, h)| *h += (i % N) as f32 * 100.0);
    assert!(matches!(
        run(&ramp, &TraceParams::default()),
        Err(TraceError::Sketch(_))
    ));
}
