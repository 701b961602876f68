//! Selection: culling, view and height dependence, tiling, balance, watertight morph data, mips.

mod common;

use common::{
    CULLED, CoverGrid, EXTENT_M, Lcg, NOTHING, camera, check_watertight, flat_pyramid,
    hills_pyramid, mountain_pyramid, settings,
};
use glam::{Vec3, Vec4Swizzles};
use terrasketch_quadtree::{
    Camera, LodSettings, MinMaxPyramid, Patch, QuadtreeError, Selection, bench_lod,
    max_neighbour_level_diff, select,
};

fn run(pyramid: &MinMaxPyramid, settings: &LodSettings, camera: &Camera, ready: u32) -> Selection {
    let mut selection = Selection::new();
    select(pyramid, settings, camera, ready, &mut selection).unwrap();
    selection
}

fn patch_at(selection: &Selection, x_m: f32, y_m: f32) -> Option<&Patch> {
    selection.patches.iter().find(|p| {
        x_m >= p.origin_m[0]
            && x_m < p.origin_m[0] + p.size_m[0]
            && y_m >= p.origin_m[1]
            && y_m < p.origin_m[1] + p.size_m[1]
    })
}

#[test]
fn a_camera_looking_away_selects_nothing() {
    let settings = settings();
    let pyramid = hills_pyramid();
    // West of the terrain, looking further west.
    let west = camera(
        Vec3::new(-200.0, EXTENT_M / 2.0, 300.0),
        Vec3::new(-5000.0, EXTENT_M / 2.0, 300.0),
    );
    let selection = run(&pyramid, &settings, &west, 0);
    assert!(
        selection.patches.is_empty(),
        "{} patches",
        selection.patches.len()
    );
    // Above the highest point, looking at the sky.
    let up = camera(
        Vec3::new(4000.0, 4000.0, 2000.0),
        Vec3::new(4100.0, 4000.0, 9000.0),
    );
    assert!(run(&pyramid, &settings, &up, 0).patches.is_empty());
    // The same camera turned around sees the terrain.
    let east = camera(
        Vec3::new(-200.0, EXTENT_M / 2.0, 300.0),
        Vec3::new(5000.0, EXTENT_M / 2.0, 0.0),
    );
    assert!(!run(&pyramid, &settings, &east, 0).patches.is_empty());
}

#[test]
fn only_what_is_in_the_frustum_is_selected() {
    let settings = settings();
    let pyramid = flat_pyramid();
    // Low, in the middle, looking north: the southern half is behind the camera.
    let cam = camera(
        Vec3::new(4096.0, 4096.0, 100.0),
        Vec3::new(4096.0, 8000.0, 0.0),
    );
    let selection = run(&pyramid, &settings, &cam, 0);
    assert!(selection.culled_leaves().count() > 0);
    for p in &selection.patches {
        assert!(
            p.origin_m[1] + p.size_m[1] > 4096.0 - 200.0,
            "patch behind the camera: {p:?}"
        );
    }
}

#[test]
fn a_high_top_down_camera_selects_few_coarse_patches_and_a_low_one_many_fine_ones() {
    let settings = settings();
    let pyramid = hills_pyramid();
    let root = settings.levels() - 1;
    let high = camera(
        Vec3::new(4096.0, 4096.0, 60_000.0),
        Vec3::new(4096.0, 4096.0, 0.0),
    );
    let selection = run(&pyramid, &settings, &high, 0);
    assert!(
        !selection.patches.is_empty() && selection.patches.len() <= 16,
        "{} patches",
        selection.patches.len()
    );
    assert!(selection.patches.iter().all(|p| p.level + 2 >= root));

    let low_position = Vec3::new(2000.0, 2000.0, 900.0);
    let low = camera(low_position, Vec3::new(6000.0, 6000.0, 0.0));
    let selection = run(&pyramid, &settings, &low, 0);
    assert!(
        selection.patches.len() > 200,
        "{} patches",
        selection.patches.len()
    );
    // Fine patches near the camera, coarse ones far away.
    let near = patch_at(&selection, 2300.0, 2300.0).expect("ground just ahead is visible");
    let far = patch_at(&selection, 7800.0, 7800.0).expect("far corner is visible");
    assert_eq!(near.level, 0);
    assert!(far.level >= 3, "far patch at level {}", far.level);
}

#[test]
fn patches_and_culled_leaves_tile_the_extent_and_cover_everything_visible() {
    let settings = settings();
    let pyramid = flat_pyramid();
    let cam = camera(
        Vec3::new(1000.0, 1500.0, 250.0),
        Vec3::new(5000.0, 5000.0, 0.0),
    );
    let selection = run(&pyramid, &settings, &cam, 0);
    let cover = CoverGrid::new(&settings, &selection);
    assert!(
        cover.owner.iter().all(|&o| o != NOTHING),
        "a hole in the tiling"
    );
    let area: f32 = selection
        .patches
        .iter()
        .map(|p| p.uv_size * p.uv_size)
        .sum::<f32>()
        + selection.culled_leaves().map(|(_, s)| s * s).sum::<f32>();
    assert!((area - 1.0).abs() < 1e-6, "total area {area}");
    // Every ground point that projects inside the viewport lies in a drawn patch.
    let clip_from_world = cam.clip_from_world();
    let mut rng = Lcg(3);
    let mut visible = 0;
    for _ in 0..20_000 {
        let (u, v) = (rng.range(0.0, 1.0), rng.range(0.0, 1.0));
        let clip = clip_from_world * Vec3::new(u * EXTENT_M, v * EXTENT_M, 0.0).extend(1.0);
        if clip.w <= 0.0 {
            continue;
        }
        let ndc = clip.xyz() / clip.w;
        if ndc.x.abs() < 1.0 && ndc.y.abs() < 1.0 && (0.0..1.0).contains(&ndc.z) {
            visible += 1;
            let owner = cover.owner_at(u, v);
            assert!(
                owner != CULLED && owner != NOTHING,
                "visible point ({u}, {v}) not in a patch"
            );
        }
    }
    assert!(visible > 1000);
}

#[test]
fn balance_and_watertight_morph_hold_for_200_random_cameras() {
    let settings = settings();
    let pyramid = hills_pyramid();
    let mut rng = Lcg(2011);
    let mut selection = Selection::new();
    let (mut seams, mut total_patches) = (0, 0);
    for k in 0..200 {
        let position = Vec3::new(
            rng.range(-0.2, 1.2) * EXTENT_M,
            rng.range(-0.2, 1.2) * EXTENT_M,
            900.0 + rng.range(0.0, 1.0).powi(3) * 20_000.0,
        );
        let (yaw, pitch) = (
            rng.range(0.0, std::f32::consts::TAU),
            rng.range(-89.0, 20.0).to_radians(),
        );
        let dir = Vec3::new(
            yaw.cos() * pitch.cos(),
            yaw.sin() * pitch.cos(),
            pitch.sin(),
        );
        let fov = rng.range(30.0, 100.0).to_radians();
        let cam = Camera::look_at(
            position,
            position + dir,
            fov,
            [rng.range(320.0, 2560.0), rng.range(240.0, 1440.0)],
            0.5,
            1e5,
        );
        let ready = if k % 4 == 3 { rng.next_u32() % 6 } else { 0 };
        select(&pyramid, &settings, &cam, ready, &mut selection).unwrap();
        assert!(
            max_neighbour_level_diff(&selection.patches) <= 1,
            "camera {k}"
        );
        let cover = CoverGrid::new(&settings, &selection);
        seams += check_watertight(&settings, &selection, &cover);
        total_patches += selection.patches.len();
        for p in &selection.patches {
            assert!(p.morph.iter().all(|m| (0.0..=1.0).contains(m)));
        }
    }
    assert!(
        total_patches > 10_000 && seams > 10_000,
        "too easy: {total_patches} patches, {seams} seams"
    );
}

#[test]
fn morph_is_zero_on_the_root_and_mixed_elsewhere() {
    let settings = settings();
    let pyramid = flat_pyramid();
    let far = camera(
        Vec3::new(4096.0, 4096.0, 1e5),
        Vec3::new(4096.0, 4096.0, 0.0),
    );
    let selection = run(&pyramid, &settings, &far, 0);
    assert_eq!(selection.patches.len(), 1);
    assert_eq!(selection.patches[0].level, settings.levels() - 1);
    assert_eq!(selection.patches[0].morph, [0.0; 4]);
    let low = camera(
        Vec3::new(500.0, 500.0, 120.0),
        Vec3::new(8000.0, 8000.0, 0.0),
    );
    let selection = run(&pyramid, &settings, &low, 0);
    let morphing = selection
        .patches
        .iter()
        .filter(|p| p.morph.iter().any(|&m| m > 0.0 && m < 1.0))
        .count();
    assert!(morphing > 0, "no patch is mid-morph");
}

#[test]
fn no_patch_is_finer_than_the_finest_ready_mip_allows() {
    let settings = settings();
    assert_eq!(settings.mip_offset(), 0);
    let pyramid = hills_pyramid();
    let cam = camera(
        Vec3::new(3000.0, 3000.0, 900.0),
        Vec3::new(6000.0, 6000.0, 0.0),
    );
    for ready in 0..=12u32 {
        let selection = run(&pyramid, &settings, &cam, ready);
        let finest = settings.finest_allowed_level(ready);
        assert_eq!(finest, ready.min(settings.levels() - 1));
        let min_level = selection.patches.iter().map(|p| p.level).min().unwrap();
        assert_eq!(
            min_level, finest,
            "ready mip {ready}: the low camera should reach the allowed level"
        );
        for p in &selection.patches {
            assert!(p.level >= finest);
            assert!(p.mip_level >= ready.min(settings.coarsest_mip()));
            assert_eq!(
                p.mip_level,
                (p.level + settings.mip_offset())
                    .max(ready)
                    .min(settings.coarsest_mip())
            );
        }
        assert!(max_neighbour_level_diff(&selection.patches) <= 1);
    }
    // A shallower tree (max_levels) samples coarser mips: level 0 reads mip 2.
    let short = LodSettings {
        max_levels: 6,
        ..settings
    };
    assert_eq!(short.mip_offset(), 2);
    let selection = run(&pyramid, &short, &cam, 0);
    assert!(selection.patches.iter().all(|p| p.mip_level == p.level + 2));
    assert!(selection.patches.iter().any(|p| p.level == 0));
}

#[test]
fn a_mountain_splits_more_than_flat_ground_at_the_same_distance() {
    let settings = settings();
    // Top-down over the centre, 4 km up; a 3 km peak 820 m east of the centre (in view), its
    // mirror point west is flat: same horizontal distance, four times the depth.
    let cam = camera(
        Vec3::new(4096.0, 4096.0, 4000.0),
        Vec3::new(4096.0, 4096.0, 0.0),
    );
    let (east, west) = (
        (0.6 * EXTENT_M, 0.5 * EXTENT_M),
        (0.4 * EXTENT_M, 0.5 * EXTENT_M),
    );
    let level_at = |pyramid: &MinMaxPyramid, (x, y): (f32, f32)| {
        let selection = run(pyramid, &settings, &cam, 0);
        patch_at(&selection, x, y).unwrap().level
    };
    let flat = flat_pyramid();
    assert_eq!(
        level_at(&flat, east),
        level_at(&flat, west),
        "flat terrain must be symmetric"
    );
    let mountain = mountain_pyramid(0.6, 0.5);
    let (over_mountain, over_flat) = (level_at(&mountain, east), level_at(&mountain, west));
    assert!(
        over_mountain + 2 <= over_flat,
        "mountain level {over_mountain}, flat level {over_flat}"
    );
}

#[test]
fn selection_reuses_its_buffers() {
    let settings = settings();
    let pyramid = hills_pyramid();
    let cameras = terrasketch_quadtree::bench_camera_path(settings.extent_m, 30);
    let mut selection = Selection::new();
    for cam in &cameras {
        select(&pyramid, &settings, cam, 0, &mut selection).unwrap();
    }
    let (capacity, pointer) = (selection.patches.capacity(), selection.patches.as_ptr());
    for cam in &cameras {
        select(&pyramid, &settings, cam, 0, &mut selection).unwrap();
        assert_eq!(
            (selection.patches.capacity(), selection.patches.as_ptr()),
            (capacity, pointer)
        );
    }
}

#[test]
fn invalid_settings_and_cameras_are_refused() {
    let pyramid = flat_pyramid();
    let cam = camera(Vec3::new(0.0, 0.0, 100.0), Vec3::new(100.0, 100.0, 0.0));
    let mut selection = Selection::new();
    let base = settings();
    let bad = [
        LodSettings {
            heightmap_side: 1000,
            ..base
        },
        LodSettings {
            leaf_cells: 24,
            ..base
        },
        LodSettings {
            leaf_cells: 8192,
            ..base
        },
        LodSettings {
            extent_m: [0.0, 10.0],
            ..base
        },
        LodSettings {
            pixel_budget: f32::NAN,
            ..base
        },
        LodSettings {
            max_levels: 0,
            ..base
        },
        LodSettings {
            morph_start_ratio: 1.0,
            ..base
        },
    ];
    for settings in bad {
        let err = select(&pyramid, &settings, &cam, 0, &mut selection).unwrap_err();
        assert!(
            matches!(err, QuadtreeError::InvalidSettings { .. }),
            "{settings:?}: {err}"
        );
    }
    let broken = Camera {
        viewport_px: [0.0, 100.0],
        ..cam
    };
    assert!(matches!(
        select(&pyramid, &base, &broken, 0, &mut selection),
        Err(QuadtreeError::InvalidCamera(_))
    ));
}

#[test]
fn bench_reports_consistent_figures() {
    let settings = settings();
    let report = bench_lod(&hills_pyramid(), &settings, 12).unwrap();
    assert_eq!(report.frames, 12);
    assert!(report.patches_median > 0 && report.select_us_median > 0.0);
    assert_eq!(
        report.triangles_median,
        report.patches_median as u64 * 2 * 32 * 32
    );
    assert!(report.max_neighbour_level_diff <= 1);
    let path = terrasketch_quadtree::bench_camera_path(settings.extent_m, 12);
    assert_eq!(
        path,
        terrasketch_quadtree::bench_camera_path(settings.extent_m, 12),
        "path must be deterministic"
    );
    assert!(path.iter().all(|c| c.viewport_px == [1920.0, 1080.0]));
}
