//! The optional `refined` record: exact round trip, old files unchanged, bad records dropped with
//! a warning while the sketch still opens.

use terrasketch_sketch::{
    RefinedRecord, Warning, example_sketch, heights_digest, parse_sketch, save_sketch_atomic_with,
    sketch_digest, to_json, to_json_with,
};

fn record() -> RefinedRecord {
    RefinedRecord {
        seed: u64::MAX,
        size: 128,
        exemplars: vec!["alps_dhm25.tif".into(), "näme \"quoted\".hgt".into()],
        params: vec![("jitter".into(), 0.15), ("patch_size".into(), 64.0)],
        sketch_digest: sketch_digest(&example_sketch()),
        heights_digest: Some(heights_digest(&[1.0, -0.0, 2.5])),
    }
}

#[test]
fn a_record_round_trips_exactly_and_leaves_the_sketch_alone() {
    let sketch = example_sketch();
    let r = record();
    let text = to_json_with(&sketch, Some(&r));
    let parsed = parse_sketch(&text).unwrap();
    assert_eq!(parsed.sketch, sketch);
    assert_eq!(parsed.refined.as_ref(), Some(&r));
    assert!(parsed.warnings.is_empty(), "{:?}", parsed.warnings);
    // Writing it again gives the same text; without the record, the plain format.
    assert_eq!(to_json_with(&parsed.sketch, parsed.refined.as_ref()), text);
    assert_eq!(to_json_with(&sketch, None), to_json(&sketch));
    // The record is not part of the sketch's digest.
    assert_eq!(sketch_digest(&parsed.sketch), r.sketch_digest);
    // No heights digest, no params: still a valid record.
    let bare = RefinedRecord {
        heights_digest: None,
        params: Vec::new(),
        ..r
    };
    let parsed = parse_sketch(&to_json_with(&sketch, Some(&bare))).unwrap();
    assert_eq!(parsed.refined, Some(bare));
}

#[test]
fn old_files_load_without_a_record() {
    let parsed = parse_sketch(&to_json(&example_sketch())).unwrap();
    assert!(parsed.refined.is_none());
    assert!(parsed.warnings.is_empty());
}

#[test]
fn digests_follow_the_content() {
    let a = example_sketch();
    let mut b = a.clone();
    b.strokes[0].points[0][2] += 1.0;
    assert_ne!(sketch_digest(&a), sketch_digest(&b));
    assert_eq!(sketch_digest(&a).len(), 16);
    assert_ne!(heights_digest(&[0.0]), heights_digest(&[-0.0]));
}

#[test]
fn bad_records_are_dropped_with_a_warning_naming_the_field() {
    let good = to_json_with(&example_sketch(), Some(&record()));
    let cases: [(&str, &str, &str); 9] = [
        ("\"size\": 128", "\"size\": 100", "refined.size"),
        ("\"size\": 128", "\"size\": 1099511627776", "refined.size"),
        (
            "\"seed\": 18446744073709551615",
            "\"seed\": -1",
            "refined.seed",
        ),
        (
            "\"seed\": 18446744073709551615",
            "\"sed\": 1",
            "refined.sed",
        ),
        (
            "\"exemplars\": [",
            "\"exemplars\": [\"\", ",
            "refined.exemplars",
        ),
        (
            "\"jitter\": 0.15",
            "\"jitter\": \"high\"",
            "refined.params.jitter",
        ),
        (
            "\"sketch_digest\": \"",
            "\"sketch_digest\": \"zz",
            "refined.sketch_digest",
        ),
        (
            "\"heights_digest\": \"",
            "\"heights_digest\": \"A",
            "refined.heights_digest",
        ),
        ("\"refined\": {", "\"refined\": [{", "refined"),
    ];
    for (from, to, field) in cases {
        assert!(good.contains(from), "{from}");
        let mut text = good.replacen(from, to, 1);
        if to.ends_with("[{") {
            text = text.replacen("\n  }\n}", "\n  }]\n}", 1);
        }
        let parsed = parse_sketch(&text).unwrap_or_else(|e| panic!("{to}: {e}"));
        assert!(parsed.refined.is_none(), "{to}");
        assert_eq!(parsed.sketch, example_sketch());
        let w: Vec<String> = parsed
            .warnings
            .iter()
            .filter(|w| matches!(w, Warning::RefinedIgnored { .. }))
            .map(|w| w.to_string())
            .collect();
        assert_eq!(w.len(), 1, "{to}: {:?}", parsed.warnings);
        assert!(w[0].contains(&format!("`{field}`")), "{to}: {}", w[0]);
    }
    // A missing field is named too.
    let text = good.replacen("    \"size\": 128,\n", "", 1);
    let w = parse_sketch(&text).unwrap().warnings;
    assert!(w[0].to_string().contains("refined.size"), "{}", w[0]);
}

#[test]
fn the_atomic_save_writes_the_record() {
    let dir = std::env::temp_dir().join(format!("ts-refined-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("s.json");
    save_sketch_atomic_with(&example_sketch(), Some(&record()), &path).unwrap();
    let parsed = terrasketch_sketch::load_sketch(&path).unwrap();
    assert_eq!(parsed.refined, Some(record()));
    std::fs::remove_dir_all(&dir).unwrap();
}
