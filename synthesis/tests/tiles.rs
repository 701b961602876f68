//! A world refined in pieces: its coarse levels once (`refine_coarse`), its finest level per
//! region (`refine_region`), seeded by world position.

use std::sync::atomic::AtomicBool;

use terrasketch_raster::Heightmap;
use terrasketch_synthesis::refine::field::Field;
use terrasketch_synthesis::refine::levels::{level1_window, upsample2_region};
use terrasketch_synthesis::refine::{
    RefineInput, RefineParams, prepare_exemplars, refine_coarse, refine_levels, refine_region,
};
use terrasketch_synthesis::{LoadOptions, load_dem, shipped_exemplar_dir};

mod common;
use common::ridge_input;

fn params() -> RefineParams {
    RefineParams {
        seed: 5,
        patch_size: 32,
        sites_per_exemplar: 200,
        feature_sites_per_exemplar: 60,
        ..RefineParams::default()
    }
}

/// The `side` square at `origin` (column, row) of the world input.
fn region(input: &RefineInput, origin: [usize; 2], side: usize) -> RefineInput {
    let n = input.target.width;
    let crop = |v: &[f32]| -> Vec<f32> {
        (origin[1]..origin[1] + side)
            .flat_map(|y| {
                v[y * n + origin[0]..y * n + origin[0] + side]
                    .iter()
                    .copied()
            })
            .collect()
    };
    let mask = input.constraint_mask.as_ref().map(|m| {
        (origin[1]..origin[1] + side)
            .flat_map(|y| {
                m[y * n + origin[0]..y * n + origin[0] + side]
                    .iter()
                    .copied()
            })
            .collect()
    });
    RefineInput {
        target: Heightmap {
            width: side,
            height: side,
            data: crop(&input.target.data),
            cell_size_m: input.target.cell_size_m,
        },
        constraint_mask: mask,
        constraint_values: input.constraint_values.as_deref().map(crop),
        roughness: None,
        sinks: None,
        constraint_tolerance: None,
    }
}

#[test]
fn a_world_in_pieces_is_the_world_and_regions_share_the_world_lattice() {
    let (n, cell) = (256, 20.0);
    let dems = [load_dem(
        &shipped_exemplar_dir().join("zurich_dhm25.tif"),
        &LoadOptions::default(),
    )
    .unwrap()];
    let ex = prepare_exemplars(&dems, cell, None, &|_, _| {}).unwrap();
    let input = ridge_input(n, cell, None);
    let p = params();
    let cancel = AtomicBool::new(false);
    let whole = refine_levels(&input, &ex, &p, &|_, _| {}, &|_| {}, &cancel).unwrap();
    let coarse = refine_coarse(&input, &ex, &p, &|_, _| {}, &|_| {}, &cancel).unwrap();
    assert!(coarse.plan.len() > 1, "{:?}", coarse.plan);
    let level1 = coarse.level1.as_ref().unwrap();
    // The coarse levels plus the finest level on a region that is the whole world: the world's
    // own refinement, bit for bit.
    let (c0, c1) = level1_window([0, 0], n, n / 2);
    assert_eq!((c0, c1), ([0, 0], [n / 2, n / 2]));
    let start = upsample2_region(level1, c0, [0, 0], n);
    let one = refine_region(&input, &ex, &p, &coarse, Some(start), &|_, _| {}, &cancel).unwrap();
    assert!(
        one.heights.data.iter().map(|v| v.to_bits()).eq(whole
            .heights
            .data
            .iter()
            .map(|v| v.to_bits())),
        "the world as one region differs from its refinement"
    );
    // Two overlapping regions: their fill patches sit on one world lattice.
    let step = (p.patch_size - p.patch_size / 4) as i64;
    let mut phases = Vec::new();
    for origin in [[0usize, 32usize], [64, 96]] {
        let side = 160;
        let (c0, c1) = level1_window(origin, side, n / 2);
        let crop = Field::new(
            c1[0] - c0[0],
            c1[1] - c0[1],
            (c0[1]..c1[1])
                .flat_map(|y| {
                    level1.v[y * level1.w + c0[0]..y * level1.w + c1[0]]
                        .iter()
                        .copied()
                })
                .collect(),
        );
        let start = upsample2_region(&crop, c0, origin, side);
        let mut rp = p.clone();
        rp.origin = [origin[0] as i64, origin[1] as i64];
        let r = region(&input, origin, side);
        let out = refine_region(&r, &ex, &rp, &coarse, Some(start), &|_, _| {}, &cancel).unwrap();
        assert!(out.heights.data.iter().all(|v| v.is_finite()));
        let fill = &out.placed[out.stats.patches_feature..];
        assert!(fill.len() > 4, "{} fill patches", fill.len());
        let mods: Vec<[i64; 2]> = fill
            .iter()
            .map(|pl| {
                [
                    (i64::from(pl.p[0]) + rp.origin[0]).rem_euclid(step),
                    (i64::from(pl.p[1]) + rp.origin[1]).rem_euclid(step),
                ]
            })
            .collect();
        assert!(mods.iter().all(|m| *m == mods[0]), "{mods:?}");
        phases.push(mods[0]);
    }
    assert_eq!(
        phases[0], phases[1],
        "the regions' lattices differ in the world"
    );
    // A region's start is the whole world's upsampling, cut.
    let full = upsample2_region(level1, [0, 0], [0, 0], n);
    let (c0, c1) = level1_window([64, 96], 160, n / 2);
    let crop = Field::new(
        c1[0] - c0[0],
        c1[1] - c0[1],
        (c0[1]..c1[1])
            .flat_map(|y| {
                level1.v[y * level1.w + c0[0]..y * level1.w + c1[0]]
                    .iter()
                    .copied()
            })
            .collect(),
    );
    let part = upsample2_region(&crop, c0, [64, 96], 160);
    for y in 0..160 {
        for x in 0..160 {
            assert_eq!(
                part.v[y * 160 + x].to_bits(),
                full.v[(96 + y) * n + 64 + x].to_bits()
            );
        }
    }
}
