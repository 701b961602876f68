//! The optional detail `seed`: absent is 0, any u64 round-trips, anything else is refused.

use terrasketch_sketch::{SketchError, example_sketch, parse_sketch, to_json};

fn with_seed(seed: &str) -> String {
    let text = to_json(&example_sketch());
    text.replacen(
        "\"strokes\": [",
        &format!("\"seed\": {seed},\n  \"strokes\": ["),
        1,
    )
}

#[test]
fn a_file_without_a_seed_loads_with_seed_0_and_is_written_as_before() {
    let text = to_json(&example_sketch());
    assert!(!text.contains("\"seed\""));
    let parsed = parse_sketch(&text).expect("loads");
    assert_eq!(parsed.sketch.seed, 0);
    assert!(parsed.warnings.is_empty(), "{:?}", parsed.warnings);
    assert_eq!(to_json(&parsed.sketch), text);
}

#[test]
fn every_seed_round_trips() {
    for seed in [1u64, 42, u32::MAX as u64 + 7, u64::MAX] {
        let parsed = parse_sketch(&with_seed(&seed.to_string())).expect("loads");
        assert_eq!(parsed.sketch.seed, seed);
        assert!(parsed.warnings.is_empty(), "{:?}", parsed.warnings);
        let again = parse_sketch(&to_json(&parsed.sketch)).expect("reloads");
        assert_eq!(again.sketch, parsed.sketch);
    }
}

#[test]
fn a_seed_that_is_not_a_whole_number_is_refused() {
    for bad in ["-1", "1.5", "\"7\"", "null", "18446744073709551616"] {
        match parse_sketch(&with_seed(bad)) {
            Err(SketchError::WrongType { path, .. }) => assert_eq!(path, "seed", "{bad}"),
            Err(SketchError::NumberOutOfRange { .. }) => assert_eq!(bad, "18446744073709551616"),
            other => panic!("{bad}: {other:?}"),
        }
    }
}
