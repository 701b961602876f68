//! Every way a sketch file can be refused, with the message the user sees.

use terrasketch_sketch::{
    MAX_POINTS, MAX_STROKES, Sketch, SketchError, Stroke, StrokeKind, check_cell_size,
    parse_sketch, validate,
};

/// A complete document around the given `strokes` array text.
fn doc(strokes: &str) -> String {
    format!(
        r#"{{"format": "terrasketch-sketch", "version": 1, "extent_m": [1000.0, 1000.0], "strokes": {strokes}}}"#
    )
}

fn refuse(text: &str) -> SketchError {
    match parse_sketch(text) {
        Ok(parsed) => panic!("accepted {text:.200}: {:?}", parsed.sketch),
        Err(err) => err,
    }
}

fn assert_mentions(err: &SketchError, parts: &[&str]) {
    let message = err.to_string();
    for part in parts {
        assert!(
            message.contains(part),
            "message {message:?} does not mention {part:?}"
        );
    }
}

#[test]
fn malformed_json_gives_line_and_column() {
    let text = "{\n  \"format\": \"terrasketch-sketch\",\n  \"version\": 1,,\n}";
    let err = refuse(text);
    let SketchError::Json {
        line,
        column,
        ref message,
    } = err
    else {
        panic!("{err:?}")
    };
    assert_eq!((line, column), (3, 16)); // the second comma
    assert!(
        !message.contains("at line"),
        "position repeated in {message:?}"
    );
    assert_mentions(&err, &["malformed JSON", "line 3", "column 16"]);
}

#[test]
fn empty_text_and_nan_literal_are_malformed_json() {
    assert!(matches!(refuse(""), SketchError::Json { line: 1, .. }));
    let err = refuse(&doc(
        r#"[{"kind": "ridge", "points": [[NaN, 0, 0], [1, 1, 1]]}]"#,
    ));
    assert!(matches!(err, SketchError::Json { line: 1, .. }), "{err:?}");
}

#[test]
fn overflowing_number_is_a_clear_error() {
    let text = doc("[\n{\"kind\": \"ridge\", \"points\": [[1e999, 0, 0], [1, 1, 1]]}]");
    let err = refuse(&text);
    assert!(
        matches!(err, SketchError::NumberOutOfRange { line: 2, .. }),
        "{err:?}"
    );
    assert_mentions(&err, &["line 2", "finite"]);
    assert!(matches!(
        refuse(&doc("[]").replace("1000.0]", "-1e400]")),
        SketchError::NumberOutOfRange { .. }
    ));
}

#[test]
fn document_must_be_an_object() {
    let err = refuse("[1, 2]");
    assert_mentions(&err, &["(document)", "object", "an array of 2 values"]);
}

#[test]
fn wrong_or_missing_format() {
    let err = refuse(&doc("[]").replace("terrasketch-sketch", "geojson"));
    assert!(
        matches!(err, SketchError::Format { found: Some(_) }),
        "{err:?}"
    );
    assert_mentions(&err, &["\"geojson\"", "expected", "\"terrasketch-sketch\""]);

    let err = refuse(r#"{"version": 1, "extent_m": [1, 1], "strokes": []}"#);
    assert!(
        matches!(err, SketchError::Format { found: None }),
        "{err:?}"
    );
    assert_mentions(&err, &["missing", "terrasketch-sketch"]);

    let err = refuse(&doc("[]").replace("\"terrasketch-sketch\"", "3"));
    assert_mentions(&err, &["a number (3)", "terrasketch-sketch"]);
}

#[test]
fn unsupported_or_missing_version() {
    let err = refuse(&doc("[]").replace("\"version\": 1", "\"version\": 2"));
    assert!(
        matches!(err, SketchError::UnsupportedVersion { ref found } if found == "2"),
        "{err:?}"
    );
    assert_mentions(&err, &["version 2", "reads version 1"]);

    let err = refuse(&doc("[]").replace("\"version\": 1", "\"version\": \"1\""));
    assert_mentions(&err, &["`version`", "a number", "a string (\"1\")"]);

    let err = refuse(&doc("[]").replace("\"version\": 1,", ""));
    assert!(
        matches!(err, SketchError::MissingField { ref path } if path == "version"),
        "{err:?}"
    );
    // 1.0 is version 1.
    assert!(parse_sketch(&doc("[]").replace("\"version\": 1", "\"version\": 1.0")).is_ok());
}

#[test]
fn non_finite_numbers_name_stroke_and_point() {
    let mut sketch = Sketch::empty([100.0, 100.0], 0.0);
    sketch.strokes.push(Stroke::new(
        StrokeKind::Ridge,
        vec![[1.0, 1.0, 1.0], [2.0, 2.0, 2.0]],
    ));
    sketch.strokes.push(Stroke::new(
        StrokeKind::Valley,
        vec![
            [1.0, 1.0, 1.0],
            [2.0, 2.0, 2.0],
            [3.0, 3.0, 3.0],
            [4.0, 4.0, f64::NAN],
        ],
    ));
    let err = validate(&sketch).unwrap_err();
    assert!(
        matches!(
            err,
            SketchError::NonFinitePoint {
                stroke: 1,
                point: 3,
                axis: "z",
                ..
            }
        ),
        "{err:?}"
    );
    assert_mentions(&err, &["stroke 1", "point 3", "NaN", "finite"]);

    sketch.strokes[1].points[3][2] = 4.0;
    sketch.strokes[1].points[0][0] = f64::NEG_INFINITY;
    assert_mentions(
        &validate(&sketch).unwrap_err(),
        &["stroke 1, point 0", "coordinate x", "-inf"],
    );

    sketch.strokes[1].points[0][0] = 1.0;
    sketch.base_elevation_m = f64::INFINITY;
    assert_mentions(
        &validate(&sketch).unwrap_err(),
        &["base_elevation_m", "inf", "finite"],
    );
}

#[test]
fn too_few_points() {
    let strokes = r#"[{"kind": "ridge", "points": [[1, 1, 1], [2, 2, 2]]},
                      {"kind": "valley", "points": [[1, 1, 1], [2, 2, 2]]},
                      {"kind": "plateau", "points": [[1, 1, 1]]}]"#;
    let err = refuse(&doc(strokes));
    assert!(
        matches!(
            err,
            SketchError::TooFewPoints {
                stroke: 2,
                count: 1
            }
        ),
        "{err:?}"
    );
    assert_mentions(&err, &["stroke 2", "1 point", "at least 2"]);
    let err = refuse(&doc(r#"[{"kind": "ridge", "points": []}]"#));
    assert!(
        matches!(
            err,
            SketchError::TooFewPoints {
                stroke: 0,
                count: 0
            }
        ),
        "{err:?}"
    );
}

#[test]
fn unknown_kind_lists_allowed_kinds() {
    let strokes = r#"[{"kind": "ridge", "points": [[1, 1, 1], [2, 2, 2]]},
                      {"kind": "mesa", "points": [[1, 1, 1], [2, 2, 2]]}]"#;
    let err = refuse(&doc(strokes));
    assert!(
        matches!(err, SketchError::UnknownKind { stroke: 1, ref kind } if kind == "mesa"),
        "{err:?}"
    );
    assert_mentions(
        &err,
        &[
            "stroke 1",
            "\"mesa\"",
            "\"ridge\"",
            "\"valley\"",
            "\"plateau\"",
        ],
    );

    let long = "x".repeat(10_000);
    let err = refuse(&doc(&format!(r#"[{{"kind": "{long}", "points": []}}]"#)));
    assert!(err.to_string().len() < 300, "hostile kind repeated in full");
}

#[test]
fn extent_must_be_positive_and_finite() {
    for extent in ["[0, 100]", "[100, -5]", "[-0.0, 1]"] {
        let err = refuse(&doc("[]").replace("[1000.0, 1000.0]", extent));
        assert!(
            matches!(err, SketchError::BadExtent { .. }),
            "{extent}: {err:?}"
        );
        assert_mentions(&err, &["extent_m", "positive"]);
    }
    let err = validate(&Sketch::empty([f64::INFINITY, 1.0], 0.0)).unwrap_err();
    assert!(matches!(err, SketchError::BadExtent { .. }), "{err:?}");
    for extent in ["[1, 2, 3]", "\"big\"", "[1, null]"] {
        let err = refuse(&doc("[]").replace("[1000.0, 1000.0]", extent));
        assert!(
            matches!(err, SketchError::WrongType { ref path, .. } if path == "extent_m"),
            "{err:?}"
        );
        assert_mentions(&err, &["two numbers"]);
    }
    let err = refuse(r#"{"format": "terrasketch-sketch", "version": 1, "strokes": []}"#);
    assert!(
        matches!(err, SketchError::MissingField { ref path } if path == "extent_m"),
        "{err:?}"
    );
}

#[test]
fn extent_must_lie_between_one_metre_and_40000_km() {
    for extent in ["[0.5, 100]", "[100, 4.0000001e7]", "[1e30, 1e30]"] {
        let err = refuse(&doc("[]").replace("[1000.0, 1000.0]", extent));
        assert!(
            matches!(err, SketchError::BadExtent { .. }),
            "{extent}: {err:?}"
        );
        assert_mentions(&err, &["extent_m", "1 m", "40,000 km"]);
    }
    for extent in ["[1, 1]", "[4e7, 4e7]"] {
        assert!(parse_sketch(&doc("[]").replace("[1000.0, 1000.0]", extent)).is_ok());
    }
}

#[test]
fn elevations_past_100_km_name_the_field() {
    let text = doc("[]").replace("\"strokes\"", "\"base_elevation_m\": 1e30, \"strokes\"");
    let err = refuse(&text);
    assert!(
        matches!(err, SketchError::ElevationOutOfRange { ref field, .. } if field == "base_elevation_m"),
        "{err:?}"
    );
    assert_mentions(
        &err,
        &[
            "`base_elevation_m`",
            "1000000000000000000000000000000",
            "100 km",
        ],
    );
    let text = doc("[]").replace(
        "\"strokes\"",
        "\"base_elevation_m\": -100000.5, \"strokes\"",
    );
    assert!(matches!(
        refuse(&text),
        SketchError::ElevationOutOfRange { .. }
    ));

    let strokes = r#"[{"kind": "ridge", "points": [[1, 1, 1], [2, 2, 2]]},
                      {"kind": "valley", "points": [[1, 1, 1], [2, 2, 2], [3, 3, -2e5]]}]"#;
    let err = refuse(&doc(strokes));
    assert!(
        matches!(err, SketchError::ElevationOutOfRange { ref field, value, .. }
            if field == "strokes[1].points[2] z" && value == -2e5),
        "{err:?}"
    );
    assert_mentions(&err, &["strokes[1].points[2] z", "-200000", "allowed"]);
    let strokes = r#"[{"kind": "ridge", "points": [[1, 1, -100000], [2, 2, 100000]]}]"#;
    assert!(parse_sketch(&doc(strokes)).is_ok());
}

#[test]
fn cells_below_one_centimetre_are_refused() {
    assert!(check_cell_size([1000.0, 1000.0], 16384).is_ok());
    assert!(check_cell_size([163.84, 163.84], 16384).is_ok());
    let err = check_cell_size([100.0, 163.84], 16384).unwrap_err();
    assert!(
        matches!(err, SketchError::CellTooSmall { cells: 16384, .. }),
        "{err:?}"
    );
    assert_mentions(&err, &["cell size", "1 cm", "--size", "extent_m"]);
}

#[test]
fn attributes_out_of_range() {
    let cases = [
        ("slope_left_deg", "85.5"),
        ("slope_left_deg", "-1"),
        ("slope_right_deg", "90"),
        ("width_m", "0"),
        ("width_m", "-3"),
        ("roughness", "1.5"),
        ("roughness", "-0.1"),
    ];
    for (field, value) in cases {
        let strokes = format!(
            r#"[{{"kind": "ridge", "points": [[1, 1, 1], [2, 2, 2]]}},
                {{"kind": "valley", "points": [[1, 1, 1], [2, 2, 2]], "{field}": {value}}}]"#
        );
        let err = refuse(&doc(&strokes));
        assert!(
            matches!(err, SketchError::AttributeOutOfRange { stroke: 1, attribute, .. } if attribute == field),
            "{field} = {value}: {err:?}"
        );
        assert_mentions(&err, &["stroke 1", field, "allowed"]);
    }
    // The bounds themselves are allowed.
    let strokes = r#"[{"kind": "ridge", "points": [[1, 1, 1], [2, 2, 2]],
        "slope_left_deg": 0, "slope_right_deg": 85, "width_m": 0.001, "roughness": 1}]"#;
    assert!(parse_sketch(&doc(strokes)).is_ok());
}

#[test]
fn too_many_strokes_refused_before_conversion() {
    // Empty objects would be refused for their missing fields: the count is checked first.
    let strokes = format!("[{}{{}}]", "{},".repeat(MAX_STROKES));
    let err = refuse(&doc(&strokes));
    assert!(
        matches!(err, SketchError::TooManyStrokes { count } if count == MAX_STROKES + 1),
        "{err:?}"
    );
    assert_mentions(&err, &["100001 strokes", "at most 100000"]);

    let stroke = Stroke::new(StrokeKind::Ridge, vec![[1.0, 1.0, 1.0], [2.0, 2.0, 2.0]]);
    let mut sketch = Sketch::empty([10.0, 10.0], 0.0);
    sketch.strokes = vec![stroke; MAX_STROKES];
    assert!(validate(&sketch).is_ok());
    sketch.strokes.push(sketch.strokes[0].clone());
    assert!(matches!(
        validate(&sketch),
        Err(SketchError::TooManyStrokes { .. })
    ));
}

#[test]
fn too_many_points_refused() {
    let half = MAX_POINTS / 2;
    let points = |n: usize| format!("[{}[0, 0, 0]]", "[0, 0, 0],".repeat(n - 1));
    let strokes = format!(
        r#"[{{"kind": "ridge", "points": {}}}, {{"kind": "ridge", "points": {}}}]"#,
        points(half),
        points(MAX_POINTS - half + 1)
    );
    let err = refuse(&doc(&strokes));
    assert!(
        matches!(err, SketchError::TooManyPoints { count } if count == MAX_POINTS + 1),
        "{err:?}"
    );
    assert_mentions(&err, &["1000001 points", "at most 1000000"]);

    let mut sketch = Sketch::empty([10.0, 10.0], 0.0);
    sketch.strokes.push(Stroke::new(
        StrokeKind::Ridge,
        vec![[1.0, 2.0, 3.0]; MAX_POINTS],
    ));
    assert!(validate(&sketch).is_ok());
    sketch
        .strokes
        .push(Stroke::new(StrokeKind::Ridge, vec![[1.0, 2.0, 3.0]; 2]));
    assert!(
        matches!(validate(&sketch), Err(SketchError::TooManyPoints { count }) if count == MAX_POINTS + 2)
    );
}

#[test]
fn points_must_be_three_numbers() {
    let cases = [
        ("[1, 2]", "an array of 2 values"),
        ("[1, 2, 3, 4]", "an array of 4 values"),
        ("[1, 2, \"3\"]", "element 2 is a string (\"3\")"),
        ("[null, 2, 3]", "element 0 is null"),
        ("\"here\"", "a string (\"here\")"),
        ("{\"x\": 1}", "an object"),
    ];
    for (point, found) in cases {
        let strokes =
            format!(r#"[{{"kind": "ridge", "points": [[0, 0, 0], [1, 1, 1], {point}]}}]"#);
        let err = refuse(&doc(&strokes));
        assert!(
            matches!(
                err,
                SketchError::BadPoint {
                    stroke: 0,
                    point: 2,
                    ..
                }
            ),
            "{point}: {err:?}"
        );
        assert_mentions(
            &err,
            &[
                "stroke 0, point 2",
                "strokes[0].points[2]",
                "3 numbers",
                found,
            ],
        );
    }
}

#[test]
fn wrong_types_name_the_field() {
    let ok = r#"{"kind": "ridge", "points": [[0, 0, 0], [1, 1, 1]]}"#;
    let cases = [
        (doc("{}"), "strokes", "an array of strokes", "an object"),
        (doc("[3]"), "strokes[0]", "a stroke object", "a number (3)"),
        (
            doc(&format!("[{ok}, {{\"kind\": 7, \"points\": []}}]")),
            "strokes[1].kind",
            "a string",
            "a number (7)",
        ),
        (
            doc(r#"[{"kind": "ridge", "points": {}}]"#),
            "strokes[0].points",
            "an array",
            "an object",
        ),
        (
            doc(&format!("[{}]", ok.replace('}', r#", "width_m": "wide"}"#))),
            "strokes[0].width_m",
            "a number",
            "a string (\"wide\")",
        ),
        (
            doc(&format!("[{}]", ok.replace('}', r#", "roughness": null}"#))),
            "strokes[0].roughness",
            "a number",
            "null",
        ),
        (
            doc(&format!(
                "[{}]",
                ok.replace('}', r#", "slope_left_deg": [25]}"#)
            )),
            "strokes[0].slope_left_deg",
            "a number",
            "an array of 1 value",
        ),
        (
            doc("[]").replace("\"strokes\"", "\"base_elevation_m\": true, \"strokes\""),
            "base_elevation_m",
            "a number",
            "a boolean (true)",
        ),
    ];
    for (text, path, expected, found) in cases {
        let err = refuse(&text);
        assert!(
            matches!(err, SketchError::WrongType { path: ref p, .. } if p == path),
            "{path}: {err:?}"
        );
        assert_mentions(&err, &[&format!("`{path}`"), expected, found]);
    }
}

#[test]
fn missing_required_fields_name_the_path() {
    let cases = [
        (
            r#"{"format": "terrasketch-sketch", "version": 1, "extent_m": [1, 1]}"#.to_owned(),
            "strokes",
        ),
        (
            doc(r#"[{"points": [[0, 0, 0], [1, 1, 1]]}]"#),
            "strokes[0].kind",
        ),
        (doc(r#"[{"kind": "valley"}]"#), "strokes[0].points"),
    ];
    for (text, path) in cases {
        let err = refuse(&text);
        assert!(
            matches!(err, SketchError::MissingField { path: ref p } if p == path),
            "{path}: {err:?}"
        );
        assert_mentions(&err, &["missing field", path]);
    }
}

#[test]
fn load_error_names_the_path() {
    let path = std::env::temp_dir().join("terrasketch-sketch-does-not-exist/nothing.json");
    let err = terrasketch_sketch::load_sketch(&path).unwrap_err();
    assert!(
        matches!(err, SketchError::Io { path: ref p, .. } if *p == path),
        "{err:?}"
    );
    assert_mentions(&err, &["nothing.json", "I/O error"]);
}

#[test]
fn curve_closed_and_falloff_are_checked() {
    let ok = r#"{"kind": "ridge", "points": [[0, 0, 1], [10, 0, 1], [10, 10, 1]]}"#;
    let with = |extra: &str| doc(&format!("[{}]", ok.replace('}', &format!(", {extra}}}"))));
    // Unknown names list the allowed ones.
    let err = refuse(&with(r#""curve": "bezier""#));
    assert!(matches!(err, SketchError::UnknownChoice { .. }), "{err:?}");
    assert_mentions(
        &err,
        &["strokes[0].curve", "bezier", "\"smooth\" or \"polyline\""],
    );
    let err = refuse(&with(r#""falloff": "cliff""#));
    assert_mentions(
        &err,
        &[
            "strokes[0].falloff",
            "cliff",
            "\"foot\", \"sigmoid\" or \"none\"",
        ],
    );
    // Wrong types.
    let err = refuse(&with(r#""closed": 1"#));
    assert_mentions(&err, &["strokes[0].closed", "a boolean", "a number"]);
    let err = refuse(&with(r#""curve": true"#));
    assert_mentions(&err, &["strokes[0].curve", "a string"]);
    let err = refuse(&with(r#""closed": null"#));
    assert_mentions(&err, &["strokes[0].closed", "null"]);
    // A loop needs three distinct points; a last point on the first one does not count.
    let two = r#"{"kind": "ridge", "closed": true, "points": [[0, 0, 1], [10, 0, 1], [0, 0, 5]]}"#;
    let err = refuse(&doc(&format!("[{two}]")));
    assert!(
        matches!(
            err,
            SketchError::LoopTooSmall {
                stroke: 0,
                count: 2
            }
        ),
        "{err:?}"
    );
    assert_mentions(&err, &["stroke 0", "closed", "at least 3"]);
    // Good values are read.
    let parsed = parse_sketch(&with(
        r#""curve": "polyline", "closed": true, "falloff": "none""#,
    ))
    .unwrap_or_else(|e| panic!("{e}"));
    let s = &parsed.sketch.strokes[0];
    assert_eq!(s.curve, terrasketch_sketch::CurveKind::Polyline);
    assert!(s.closed);
    assert_eq!(s.falloff, terrasketch_sketch::Falloff::None);
    assert!(parsed.warnings.is_empty(), "{:?}", parsed.warnings);
}
