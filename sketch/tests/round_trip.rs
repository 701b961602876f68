//! Reading and writing the format: defaults, exact round trips, warnings.

use terrasketch_sketch::{
    Sketch, Stroke, StrokeKind, Warning, benchmark_sketch, example_sketch, parse_sketch, to_json,
};

/// The format reference example, with only the first stroke's attributes given.
const REFERENCE: &str = r#"{ "format": "terrasketch-sketch", "version": 1,
  "extent_m": [20480.0, 20480.0], "base_elevation_m": 0.0,
  "strokes": [
    { "kind": "ridge", "points": [[1000, 2000, 900], [5000, 6000.5, 1200]], "slope_left_deg": 25,
      "slope_right_deg": 30, "width_m": 1500, "roughness": 0.5 },
    { "kind": "valley", "points": [[100, 200, 300], [400, 500, 100]] },
    { "kind": "plateau", "points": [[3000, 3000, 600], [4000, 3500, 600]] } ] }"#;

/// Compares two sketches bit for bit (so `-0.0 != 0.0` and NaN payloads count).
fn assert_same_bits(a: &Sketch, b: &Sketch) {
    let bits = |s: &Sketch| {
        let mut v = vec![
            s.extent_m[0].to_bits(),
            s.extent_m[1].to_bits(),
            s.base_elevation_m.to_bits(),
        ];
        for stroke in &s.strokes {
            v.push(stroke.kind as u64);
            v.extend(
                [
                    stroke.slope_left_deg,
                    stroke.slope_right_deg,
                    stroke.width_m,
                    stroke.roughness,
                ]
                .map(f64::to_bits),
            );
            v.push(stroke.points.len() as u64);
            v.extend(stroke.points.iter().flatten().map(|x| x.to_bits()));
        }
        v
    };
    assert_eq!(a, b);
    assert!(bits(a) == bits(b), "sketches equal but not bit for bit");
}

fn round_trip(sketch: &Sketch) -> Sketch {
    let text = to_json(sketch);
    let parsed = parse_sketch(&text).unwrap_or_else(|e| panic!("{e}\n{text:.2000}"));
    parsed.sketch
}

#[test]
fn defaults_are_filled_in_and_written_out() {
    let parsed = parse_sketch(REFERENCE).unwrap();
    assert_eq!(parsed.warnings, vec![]);
    let s = &parsed.sketch;
    assert_eq!(s.extent_m, [20480.0, 20480.0]);
    assert_eq!(s.strokes.len(), 3);
    assert_eq!(s.strokes[0].slope_right_deg, 30.0);
    assert_eq!(s.strokes[0].roughness, 0.5);
    assert_eq!(
        s.strokes[1],
        Stroke::new(
            StrokeKind::Valley,
            vec![[100.0, 200.0, 300.0], [400.0, 500.0, 100.0]]
        )
    );
    let plateau = &s.strokes[2];
    assert_eq!(
        (
            plateau.kind,
            plateau.slope_left_deg,
            plateau.width_m,
            plateau.roughness
        ),
        (StrokeKind::Plateau, 0.0, 800.0, 0.2)
    );

    let text = to_json(s);
    assert!(
        text.starts_with("{\n  \"format\": \"terrasketch-sketch\",\n  \"version\": 1,\n"),
        "{text}"
    );
    // The valley's defaults are written explicitly.
    assert!(text.contains("\"kind\": \"valley\",\n      \"slope_left_deg\": 20.0,\n      \"slope_right_deg\": 20.0,\n      \"width_m\": 1000.0,\n      \"roughness\": 0.4,"), "{text}");
    assert!(text.contains("[5000.0, 6000.5, 1200.0]"), "{text}");
    assert!(text.ends_with("}\n"));
    assert_same_bits(&round_trip(s), s);
}

#[test]
fn base_elevation_defaults_to_zero() {
    let text =
        r#"{"format": "terrasketch-sketch", "version": 1, "extent_m": [10, 20], "strokes": []}"#;
    let sketch = parse_sketch(text).unwrap().sketch;
    assert_eq!(sketch, Sketch::empty([10.0, 20.0], 0.0));
    assert_same_bits(&round_trip(&sketch), &sketch);
}

#[test]
fn awkward_floats_round_trip_bit_for_bit() {
    let mut values = vec![
        0.1,
        1.0 / 3.0,
        2131.3778344726566,
        1048.4005273437501,
        -0.0,
        0.0,
        1e-300,
        5e-324,
        f64::MIN_POSITIVE,
        f64::MAX,
        f64::MIN,
        1e21,
        123456789012345680.0,
        -7.0e-8,
        9007199254740993.0,
    ];
    // Pseudo-random bit patterns (xorshift): any finite f64 must survive. Without serde_json's
    // `float_roundtrip` feature about one in five of these fails.
    let mut state: u64 = 0x2545_f491_4f6c_dd1d;
    while values.len() < 30_000 {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        let value = f64::from_bits(state);
        if value.is_finite() {
            values.push(value);
            values.push((state % 40_000_000) as f64 / 1953.0); // map-like coordinates
        }
    }
    values.truncate(values.len() / 150 * 150);
    let mut sketch = Sketch::empty([20480.123456789, 1.0 + 0.1 + 0.2], -0.0);
    for chunk in values.chunks(3 * 50) {
        // Heights must lie within +-100 km; the remainder keeps them awkward.
        let points = chunk
            .chunks_exact(3)
            .map(|p| [p[0], p[1], p[2] % 100_000.0])
            .collect();
        let mut stroke = Stroke::new(StrokeKind::Valley, points);
        stroke.slope_left_deg = 84.99999999999999;
        stroke.slope_right_deg = 1e-310;
        stroke.width_m = 1.0 / 7.0;
        stroke.roughness = 0.30000000000000004;
        sketch.strokes.push(stroke);
    }
    assert_same_bits(&round_trip(&sketch), &sketch);
}

#[test]
fn builtin_sketches_round_trip() {
    for sketch in [benchmark_sketch(), example_sketch()] {
        assert_same_bits(&round_trip(&sketch), &sketch);
    }
}

#[test]
fn parse_write_parse_is_stable() {
    let first = parse_sketch(REFERENCE).unwrap().sketch;
    let text = to_json(&first);
    let second = parse_sketch(&text).unwrap().sketch;
    assert_same_bits(&first, &second);
    assert_eq!(to_json(&second), text);
}

#[test]
fn unknown_fields_warn_with_their_path() {
    let text = REFERENCE
        .replace(
            "\"version\": 1,",
            "\"version\": 1, \"author\": {\"name\": \"x\"},",
        )
        .replace(
            "\"kind\": \"plateau\",",
            "\"kind\": \"plateau\", \"colour\": \"red\", \"Width_m\": 3,",
        );
    let parsed = parse_sketch(&text).unwrap();
    assert_eq!(
        parsed.warnings,
        vec![
            Warning::UnknownField {
                path: "author".into()
            },
            Warning::UnknownField {
                path: "strokes[2].Width_m".into()
            },
            Warning::UnknownField {
                path: "strokes[2].colour".into()
            },
        ]
    );
    // Ignored: the misspelt width does not change the default.
    assert_eq!(parsed.sketch.strokes[2].width_m, 800.0);
    assert_eq!(
        parsed.warnings[2].to_string(),
        "unknown field `strokes[2].colour` ignored"
    );
}

#[test]
fn stroke_leaving_the_extent_warns() {
    let text = REFERENCE
        .replace("[400, 500, 100]", "[400, 20480.5, 100]")
        .replace("[3000, 3000, 600]", "[-1, 3000, 600]");
    let parsed = parse_sketch(&text).unwrap();
    assert_eq!(
        parsed.warnings,
        vec![
            Warning::StrokeLeavesExtent { stroke: 1 },
            Warning::StrokeLeavesExtent { stroke: 2 }
        ]
    );
    // Kept as drawn: the solver clips.
    assert_eq!(parsed.sketch.strokes[1].points[1], [400.0, 20480.5, 100.0]);
    assert!(
        parsed.warnings[0]
            .to_string()
            .contains("stroke 1 leaves the terrain extent")
    );
}

#[test]
fn duplicate_points_warn_and_are_kept() {
    let text = REFERENCE.replace(
        "[[100, 200, 300], [400, 500, 100]]",
        "[[100, 200, 300], [100, 200, 300], [400, 500, 100]]",
    );
    let parsed = parse_sketch(&text).unwrap();
    assert_eq!(
        parsed.warnings,
        vec![Warning::DuplicatePoints { stroke: 1 }]
    );
    assert_eq!(parsed.sketch.strokes[1].points.len(), 3);
    assert!(parsed.warnings[0].to_string().contains("stroke 1"));
}

#[test]
fn curve_closed_and_falloff_default_and_round_trip() {
    use terrasketch_sketch::{CurveKind, Falloff};
    // Old files (no such fields) load as smooth, open curves with the foot falloff.
    let parsed = parse_sketch(REFERENCE).unwrap();
    for s in &parsed.sketch.strokes {
        assert_eq!(
            (s.curve, s.closed, s.falloff),
            (CurveKind::Smooth, false, Falloff::Foot)
        );
    }
    let mut sketch = parsed.sketch;
    sketch.strokes[0].curve = CurveKind::Polyline;
    sketch.strokes[1].falloff = Falloff::Sigmoid;
    sketch.strokes[2].points.push([3500.0, 4000.0, 600.0]);
    sketch.strokes[2].closed = true;
    let text = to_json(&sketch);
    assert!(
        text.contains(
            "\"curve\": \"polyline\",\n      \"closed\": false,\n      \"falloff\": \"foot\","
        ),
        "{text}"
    );
    assert_eq!(parse_sketch(&text).unwrap().sketch, sketch);
}

#[test]
fn height_tolerance_defaults_round_trips_and_is_checked() {
    use terrasketch_sketch::{DEFAULT_HEIGHT_TOLERANCE_M, SketchError};
    // Old files (no such field) load with the default tolerance.
    let parsed = parse_sketch(REFERENCE).unwrap();
    assert!(parsed.warnings.is_empty());
    for s in &parsed.sketch.strokes {
        assert_eq!(s.height_tolerance_m, DEFAULT_HEIGHT_TOLERANCE_M);
    }
    let mut sketch = parsed.sketch;
    sketch.strokes[0].height_tolerance_m = 0.0;
    sketch.strokes[1].height_tolerance_m = 7.25;
    let text = to_json(&sketch);
    assert!(text.contains("\"height_tolerance_m\": 0.0,"), "{text}");
    assert!(text.contains("\"height_tolerance_m\": 7.25,"), "{text}");
    let back = parse_sketch(&text).unwrap().sketch;
    assert_eq!(back, sketch);
    assert_eq!(
        back.strokes[0].height_tolerance_m.to_bits(),
        0.0f64.to_bits()
    );
    for bad in ["-1", "1e9", "\"2\"", "null"] {
        let text = REFERENCE.replace(
            "\"roughness\": 0.5 }",
            &format!("\"roughness\": 0.5, \"height_tolerance_m\": {bad} }}"),
        );
        let err = parse_sketch(&text).unwrap_err();
        assert!(
            matches!(
                err,
                SketchError::AttributeOutOfRange { .. } | SketchError::WrongType { .. }
            ),
            "{bad}: {err}"
        );
    }
}
