//! The rules every sketch obeys, whether it came from a file or from the editor.

use crate::error::{SketchError, Warning};
use crate::model::{Sketch, Stroke};
use crate::spec::{MAX_POINTS, MAX_STROKES};

/// Steepest allowed slope, degrees (slopes lie in `[0, MAX_SLOPE_DEG]`).
pub const MAX_SLOPE_DEG: f64 = 85.0;
/// Largest accepted elevation magnitude, metres: heights and `base_elevation_m` lie in
/// `[-MAX_ABS_ELEVATION_M, MAX_ABS_ELEVATION_M]` (100 km, far past any planet's relief).
pub const MAX_ABS_ELEVATION_M: f64 = 100_000.0;
/// Smallest accepted side of the extent, metres.
pub const MIN_EXTENT_M: f64 = 1.0;
/// Largest accepted side of the extent, metres (40,000 km, the Earth's circumference).
pub const MAX_EXTENT_M: f64 = 40_000_000.0;
/// Smallest accepted cell of a solve or an export, metres (1 cm).
pub const MIN_CELL_SIZE_M: f64 = 0.01;

/// Checks `sketch` against the format's rules.
///
/// Refuses (first problem found, in this order): an extent side outside
/// [[`MIN_EXTENT_M`], [`MAX_EXTENT_M`]] (or not finite), a base elevation that is not finite or
/// outside +-[`MAX_ABS_ELEVATION_M`], too many strokes or points, then per stroke in order: fewer
/// than two points, a non-finite coordinate, a height `z` outside +-[`MAX_ABS_ELEVATION_M`], an
/// attribute out of range (slopes in [0, 85] degrees, `width_m` > 0 and finite, roughness in
/// [0, 1]).
///
/// Returns the warnings, per stroke in order: [`Warning::StrokeLeavesExtent`] when a point lies
/// outside `[0, extent]` in x or y, [`Warning::DuplicatePoints`] when two consecutive points share
/// x and y (whatever their z).
pub fn validate(sketch: &Sketch) -> Result<Vec<Warning>, SketchError> {
    let [width_m, height_m] = sketch.extent_m;
    // Written so that NaN fails the test.
    let extent_ok = |side: f64| (MIN_EXTENT_M..=MAX_EXTENT_M).contains(&side);
    if !(extent_ok(width_m) && extent_ok(height_m)) {
        return Err(SketchError::BadExtent {
            extent_m: sketch.extent_m,
        });
    }
    if !sketch.base_elevation_m.is_finite() {
        return Err(SketchError::NonFinite {
            field: "base_elevation_m",
            value: sketch.base_elevation_m,
        });
    }
    if !elevation_ok(sketch.base_elevation_m) {
        return Err(SketchError::ElevationOutOfRange {
            field: "base_elevation_m".to_owned(),
            value: sketch.base_elevation_m,
        });
    }
    check_counts(
        sketch.strokes.len(),
        sketch.strokes.iter().map(|s| s.points.len()),
    )?;

    let mut warnings = Vec::new();
    for (index, stroke) in sketch.strokes.iter().enumerate() {
        check_stroke(index, stroke)?;
        check_loop(index, stroke)?;
        let leaves = stroke
            .points
            .iter()
            .any(|&[x, y, _]| !(0.0..=width_m).contains(&x) || !(0.0..=height_m).contains(&y));
        if leaves {
            warnings.push(Warning::StrokeLeavesExtent { stroke: index });
        }
        let duplicates = stroke
            .points
            .windows(2)
            .any(|w| w[0][0] == w[1][0] && w[0][1] == w[1][1]);
        if duplicates {
            warnings.push(Warning::DuplicatePoints { stroke: index });
        }
    }
    Ok(warnings)
}

/// Refuses more than [`MAX_STROKES`] strokes or more than [`MAX_POINTS`] points in total, given
/// the stroke count and each stroke's point count. Shared with the parser, which calls it before
/// converting anything.
pub(crate) fn check_counts(
    stroke_count: usize,
    point_counts: impl Iterator<Item = usize>,
) -> Result<(), SketchError> {
    if stroke_count > MAX_STROKES {
        return Err(SketchError::TooManyStrokes {
            count: stroke_count,
        });
    }
    let total = point_counts.fold(0usize, usize::saturating_add);
    if total > MAX_POINTS {
        return Err(SketchError::TooManyPoints { count: total });
    }
    Ok(())
}

fn check_stroke(index: usize, stroke: &Stroke) -> Result<(), SketchError> {
    if stroke.points.len() < 2 {
        return Err(SketchError::TooFewPoints {
            stroke: index,
            count: stroke.points.len(),
        });
    }
    for (point, coords) in stroke.points.iter().enumerate() {
        for (axis, &value) in ["x", "y", "z"].into_iter().zip(coords) {
            if !value.is_finite() {
                return Err(SketchError::NonFinitePoint {
                    stroke: index,
                    point,
                    axis,
                    value,
                });
            }
        }
        if !elevation_ok(coords[2]) {
            return Err(SketchError::ElevationOutOfRange {
                field: format!("strokes[{index}].points[{point}] z"),
                value: coords[2],
            });
        }
    }
    let out_of_range = |attribute, value, allowed| SketchError::AttributeOutOfRange {
        stroke: index,
        attribute,
        value,
        allowed,
    };
    const SLOPE_RANGE: &str = "0 to 85 degrees";
    for (name, slope) in [
        ("slope_left_deg", stroke.slope_left_deg),
        ("slope_right_deg", stroke.slope_right_deg),
    ] {
        // Written so that NaN fails the test.
        if !(0.0..=MAX_SLOPE_DEG).contains(&slope) {
            return Err(out_of_range(name, slope, SLOPE_RANGE));
        }
    }
    if !is_positive_finite(stroke.width_m) {
        return Err(out_of_range(
            "width_m",
            stroke.width_m,
            "more than 0 m, finite",
        ));
    }
    if !(0.0..=1.0).contains(&stroke.roughness) {
        return Err(out_of_range("roughness", stroke.roughness, "0 to 1"));
    }
    if !(0.0..=crate::model::MAX_HEIGHT_TOLERANCE_M).contains(&stroke.height_tolerance_m) {
        return Err(out_of_range(
            "height_tolerance_m",
            stroke.height_tolerance_m,
            "0 to 10000 m, finite",
        ));
    }
    Ok(())
}

/// Refuses a solve or export of `cells` cells per side over `extent_m` whose cells would be
/// smaller than [`MIN_CELL_SIZE_M`] on either axis (`cells` > 0).
pub fn check_cell_size(extent_m: [f64; 2], cells: usize) -> Result<(), SketchError> {
    let cell_size_m = extent_m.map(|side| side / cells.max(1) as f64);
    // Written so that NaN fails the test.
    if !cell_size_m.iter().all(|&cell| cell >= MIN_CELL_SIZE_M) {
        return Err(SketchError::CellTooSmall {
            cell_size_m: cell_size_m[0].min(cell_size_m[1]),
            extent_m,
            cells,
        });
    }
    Ok(())
}

/// Refuses a closed stroke with fewer than three distinct points seen from above (consecutive
/// repeats, and trailing points on the first one, count once): it cannot enclose anything.
fn check_loop(index: usize, stroke: &Stroke) -> Result<(), SketchError> {
    if !stroke.closed {
        return Ok(());
    }
    let count = crate::curve::distinct_points(stroke).0.len();
    if count < 3 {
        return Err(SketchError::LoopTooSmall {
            stroke: index,
            count,
        });
    }
    Ok(())
}

fn elevation_ok(value: f64) -> bool {
    (-MAX_ABS_ELEVATION_M..=MAX_ABS_ELEVATION_M).contains(&value)
}

fn is_positive_finite(value: f64) -> bool {
    value.is_finite() && value > 0.0
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::StrokeKind;

    fn sketch_with(stroke: Stroke) -> Sketch {
        let mut sketch = Sketch::empty([1000.0, 2000.0], 0.0);
        sketch.strokes.push(stroke);
        sketch
    }

    #[test]
    fn nan_attributes_are_refused() {
        for field in 0..4 {
            let mut stroke = Stroke::new(StrokeKind::Ridge, vec![[1.0, 1.0, 1.0], [2.0, 2.0, 2.0]]);
            match field {
                0 => stroke.slope_left_deg = f64::NAN,
                1 => stroke.slope_right_deg = f64::NAN,
                2 => stroke.width_m = f64::INFINITY,
                _ => stroke.roughness = f64::NAN,
            }
            let err = validate(&sketch_with(stroke)).unwrap_err();
            assert!(
                matches!(err, SketchError::AttributeOutOfRange { stroke: 0, .. }),
                "{err}"
            );
        }
    }

    #[test]
    fn range_bounds_are_inclusive() {
        let mut stroke = Stroke::new(
            StrokeKind::Ridge,
            vec![[0.0, 0.0, 1.0], [1000.0, 2000.0, 2.0]],
        );
        stroke.slope_left_deg = 0.0;
        stroke.slope_right_deg = 85.0;
        stroke.roughness = 1.0;
        stroke.width_m = f64::MIN_POSITIVE;
        // Points exactly on the extent's corners are inside.
        assert_eq!(validate(&sketch_with(stroke)).unwrap(), vec![]);
    }

    #[test]
    fn bounds_of_extent_elevation_and_cell_size_are_inclusive() {
        let mut stroke = Stroke::new(
            StrokeKind::Ridge,
            vec![
                [0.0, 0.0, -MAX_ABS_ELEVATION_M],
                [1.0, 1.0, MAX_ABS_ELEVATION_M],
            ],
        );
        stroke.width_m = 0.5;
        let mut sketch = Sketch::empty([MIN_EXTENT_M, MAX_EXTENT_M], -MAX_ABS_ELEVATION_M);
        sketch.strokes.push(stroke);
        assert!(validate(&sketch).is_ok());
        assert!(check_cell_size([1.0, 1.0], 100).is_ok());
        let err = check_cell_size([1.0, 1.0], 101).unwrap_err();
        assert!(
            matches!(err, SketchError::CellTooSmall { cells: 101, .. }),
            "{err}"
        );
        assert!(check_cell_size([f64::NAN, 1.0], 64).is_err());
    }

    #[test]
    fn vertical_step_counts_as_duplicate() {
        let stroke = Stroke::new(
            StrokeKind::Valley,
            vec![[5.0, 5.0, 1.0], [5.0, 5.0, 9.0], [6.0, 5.0, 9.0]],
        );
        assert_eq!(
            validate(&sketch_with(stroke)).unwrap(),
            vec![Warning::DuplicatePoints { stroke: 0 }]
        );
    }
}
