//! The built-in sketches keep the properties the benchmark and the editor rely on.

use terrasketch_sketch::{Sketch, StrokeKind, benchmark_sketch, example_sketch, to_json, validate};

/// Heights `(z_a, z_b)` where polylines `a` and `b` cross in plan.
fn crossings(a: &[[f64; 3]], b: &[[f64; 3]]) -> Vec<(f64, f64)> {
    let mut found = Vec::new();
    for sa in a.windows(2) {
        for sb in b.windows(2) {
            let (p, r) = (sa[0], [sa[1][0] - sa[0][0], sa[1][1] - sa[0][1]]);
            let (q, s) = (sb[0], [sb[1][0] - sb[0][0], sb[1][1] - sb[0][1]]);
            let denom = r[0] * s[1] - r[1] * s[0];
            if denom == 0.0 {
                continue;
            }
            let (qp0, qp1) = (q[0] - p[0], q[1] - p[1]);
            let t = (qp0 * s[1] - qp1 * s[0]) / denom;
            let u = (qp0 * r[1] - qp1 * r[0]) / denom;
            if (0.0..=1.0).contains(&t) && (0.0..=1.0).contains(&u) {
                let za = sa[0][2] + t * (sa[1][2] - sa[0][2]);
                let zb = sb[0][2] + u * (sb[1][2] - sb[0][2]);
                found.push((za, zb));
            }
        }
    }
    found
}

fn points_of(sketch: &Sketch, kind: StrokeKind) -> Vec<&Vec<[f64; 3]>> {
    sketch
        .strokes
        .iter()
        .filter(|s| s.kind == kind)
        .map(|s| &s.points)
        .collect()
}

#[test]
fn benchmark_is_deterministic() {
    assert_eq!(benchmark_sketch(), benchmark_sketch());
    assert_eq!(to_json(&benchmark_sketch()), to_json(&benchmark_sketch()));
    assert_eq!(example_sketch(), example_sketch());
}

#[test]
fn benchmark_validates_without_warnings() {
    assert_eq!(validate(&benchmark_sketch()).unwrap(), vec![]);
}

#[test]
fn benchmark_shape() {
    let sketch = benchmark_sketch();
    assert_eq!(sketch.extent_m, [20480.0, 20480.0]);
    assert_eq!(sketch.base_elevation_m, 0.0);
    let ridges = points_of(&sketch, StrokeKind::Ridge);
    let valleys = points_of(&sketch, StrokeKind::Valley);
    let plateaus = points_of(&sketch, StrokeKind::Plateau);
    assert!((3..=4).contains(&ridges.len()), "{} ridges", ridges.len());
    assert_eq!((valleys.len(), plateaus.len()), (1, 1));

    for stroke in &sketch.strokes {
        for &[x, y, _] in &stroke.points {
            assert!(
                (1000.0..=19480.0).contains(&x) && (1000.0..=19480.0).contains(&y),
                "({x}, {y}) near the edge"
            );
        }
    }
    for ridge in &ridges {
        assert!((20..=60).contains(&ridge.len()));
        for &[_, _, z] in ridge.iter() {
            assert!((900.0..=1800.0).contains(&z), "crest at {z}");
        }
    }
    let valley = valleys[0];
    assert!(
        (valley[0][2] - 300.0).abs() < 1e-9 && (valley[valley.len() - 1][2] - 100.0).abs() < 1e-9
    );
    assert!(
        valley.windows(2).all(|w| w[1][2] < w[0][2]),
        "valley does not fall all along"
    );
    assert!(plateaus[0].iter().all(|p| p[2] == 600.0));
}

#[test]
fn benchmark_ridges_cross_at_different_heights() {
    let sketch = benchmark_sketch();
    let ridges = points_of(&sketch, StrokeKind::Ridge);
    let mut crossing_pairs = 0;
    for i in 0..ridges.len() {
        for j in i + 1..ridges.len() {
            let found = crossings(ridges[i], ridges[j]);
            if !found.is_empty() {
                crossing_pairs += 1;
            }
            for (za, zb) in found {
                assert!(
                    (za - zb).abs() >= 100.0,
                    "ridges {i} and {j} cross at nearly equal heights {za} / {zb}"
                );
            }
        }
    }
    assert!(
        crossing_pairs >= 3,
        "only {crossing_pairs} pairs of ridges cross"
    );
    // The valley crosses ridges too, far below them.
    let valley = points_of(&sketch, StrokeKind::Valley)[0];
    assert!(
        ridges
            .iter()
            .filter(|r| !crossings(r, valley).is_empty())
            .count()
            >= 2
    );
}

#[test]
fn example_validates_and_has_each_kind() {
    let sketch = example_sketch();
    assert_eq!(validate(&sketch).unwrap(), vec![]);
    for kind in [StrokeKind::Ridge, StrokeKind::Valley, StrokeKind::Plateau] {
        assert!(!points_of(&sketch, kind).is_empty(), "no {kind:?}");
    }
    let valley = points_of(&sketch, StrokeKind::Valley)[0];
    assert!(
        valley.windows(2).all(|w| w[1][2] < w[0][2]),
        "river runs uphill"
    );
    // The spur starts exactly on the main range.
    let ridges = points_of(&sketch, StrokeKind::Ridge);
    assert!(ridges[0].contains(&ridges[1][0]));
}
