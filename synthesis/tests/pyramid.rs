//! The multi-resolution refinement: levels run coarse to fine and are reported, the guide
//! weight schedule, per-cell height tolerances, exemplars too small for a level.

use std::sync::Mutex;
use std::sync::atomic::AtomicBool;

use terrasketch_synthesis::refine::levels::guide_weight;
use terrasketch_synthesis::refine::{
    LevelView, PreparedExemplar, RefineError, RefineInput, RefineOutput, RefineParams,
    prepare_exemplars, refine_levels,
};
use terrasketch_synthesis::{Dem, LoadOptions, load_dem, shipped_exemplar_dir};

mod common;
use common::ridge_input;

fn shipped(name: &str) -> Dem {
    load_dem(&shipped_exemplar_dir().join(name), &LoadOptions::default()).unwrap()
}

fn params() -> RefineParams {
    RefineParams {
        seed: 3,
        patch_size: 32,
        sites_per_exemplar: 200,
        feature_sites_per_exemplar: 60,
        ..RefineParams::default()
    }
}

fn run(
    input: &RefineInput,
    ex: &[PreparedExemplar],
    params: &RefineParams,
) -> (RefineOutput, Vec<(usize, usize, usize)>) {
    let seen = Mutex::new(Vec::new());
    let on_level = |l: &LevelView| {
        assert_eq!(l.heights.len(), l.level.side * l.level.side);
        assert!(l.heights.iter().all(|v| v.is_finite()));
        seen.lock().unwrap().push((l.index, l.count, l.level.side));
    };
    let out = refine_levels(
        input,
        ex,
        params,
        &|_, _| {},
        &on_level,
        &AtomicBool::new(false),
    )
    .unwrap();
    (out, seen.into_inner().unwrap())
}

#[test]
fn guide_weight_halves_per_level_and_vanishes_at_the_finest() {
    assert_eq!(guide_weight(0.8, 0, 4), 0.0);
    assert!((guide_weight(0.8, 4, 4) - 0.8).abs() < 1e-6);
    for k in 1..4 {
        let r = guide_weight(1.0, k + 1, 4) / guide_weight(1.0, k, 4);
        assert!((2.0..=3.0).contains(&r), "ratio {r} at {k}");
    }
    assert_eq!(guide_weight(1.0, 0, 0), 0.0);
}

#[test]
fn levels_run_coarse_to_fine_and_tolerances_hold() {
    let (n, cell) = (256, 40.0);
    let dems = [
        shipped("jacksboro_fault_srtm3.tif"),
        shipped("zurich_dhm25.tif"),
    ];
    let ex = prepare_exemplars(&dems, cell, None, &|_, _| {}).unwrap();
    // Exact constraints: every level reported, coarsest first, sides doubling.
    let exact = ridge_input(n, cell, None);
    let (a, seen) = run(&exact, &ex, &params());
    assert!(seen.len() >= 3, "{seen:?}");
    assert_eq!(seen.len(), a.stats.levels.len());
    for (i, w) in seen.windows(2).enumerate() {
        assert_eq!((w[0].0, w[1].0), (i, i + 1));
        assert_eq!(w[1].2, 2 * w[0].2, "{seen:?}");
    }
    assert_eq!(seen.last().map(|s| (s.1, s.2)), Some((seen.len(), n)));
    let mask = exact.constraint_mask.as_ref().unwrap();
    let values = exact.constraint_values.as_ref().unwrap();
    for i in (0..n * n).filter(|&i| mask[i]) {
        assert_eq!(a.heights.data[i], values[i], "cell {i} must hold exactly");
    }
    // Same seed, same bits through the pyramid.
    let (b, _) = run(&exact, &ex, &params());
    assert!(
        a.heights
            .data
            .iter()
            .zip(&b.heights.data)
            .all(|(x, y)| x.to_bits() == y.to_bits())
    );
    // A 4 m tolerance: every constrained cell within it, and detail plays along the crest.
    let loose = ridge_input(n, cell, Some(4.0));
    let (c, _) = run(&loose, &ex, &params());
    let mut moved = 0;
    for i in (0..n * n).filter(|&i| mask[i]) {
        let e = (c.heights.data[i] - values[i]).abs();
        assert!(e <= 4.0 + 1e-3, "cell {i}: {e} m off");
        moved += usize::from(e > 0.5);
    }
    assert!(moved > 20, "only {moved} crest cells moved by detail");
    assert_eq!(c.stats.constraint_max_excess_m, 0.0);
    assert_eq!(c.stats.constraint_tolerance_max_m, 4.0);
    // One level (no pyramid) still runs and reports one level.
    let single = RefineParams {
        levels: 1,
        ..params()
    };
    let (d, seen) = run(&exact, &ex, &single);
    assert_eq!(seen.len(), 1);
    assert_eq!(d.stats.levels.len(), 1);
}

#[test]
fn bad_tolerances_and_exemplars_too_small_for_a_level() {
    let (n, cell) = (128, 25.0);
    let mut zurich = shipped("zurich_dhm25.tif");
    let ex = prepare_exemplars(std::slice::from_ref(&zurich), cell, None, &|_, _| {}).unwrap();
    let mut bad = ridge_input(n, cell, Some(1.0));
    if let Some(t) = bad.constraint_tolerance.as_mut() {
        t[5] = -1.0;
    }
    let err = refine_levels(
        &bad,
        &ex,
        &params(),
        &|_, _| {},
        &|_| {},
        &AtomicBool::new(false),
    )
    .unwrap_err();
    assert!(matches!(err, RefineError::BadInput(_)), "{err}");
    // A 50 x 50 cell crop beside the full DEM: too small for the 32-cell patches at 50 m, so
    // it is named and left out there; alone, the pyramid stops above it, no panic.
    let (w, h) = (50, 50);
    zurich.heights_m = (0..h)
        .flat_map(|y| zurich.heights_m[y * zurich.width..y * zurich.width + w].to_vec())
        .collect();
    zurich.width = w;
    zurich.height = h;
    zurich.name = "tiny".into();
    let both = prepare_exemplars(
        &[shipped("jacksboro_fault_srtm3.tif"), zurich.clone()],
        cell,
        None,
        &|_, _| {},
    )
    .unwrap();
    let input = ridge_input(n, cell, None);
    let (out, _) = run(&input, &both, &params());
    assert!(
        out.stats.warnings.iter().any(|w| w.contains("tiny")),
        "{:?}",
        out.stats.warnings
    );
    let alone = prepare_exemplars(&[zurich], cell, None, &|_, _| {}).unwrap();
    let res = refine_levels(
        &input,
        &alone,
        &RefineParams {
            patch_size: 16,
            ..params()
        },
        &|_, _| {},
        &|_| {},
        &AtomicBool::new(false),
    );
    match res {
        Ok(o) => assert!(o.heights.data.iter().all(|v| v.is_finite())),
        Err(e) => assert!(matches!(e, RefineError::BadInput(_)), "{e}"),
    }
}
