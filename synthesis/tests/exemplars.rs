//! The shipped exemplar library: every file loads with the size, cell size and height range of
//! `exemplars/NOTICE.md`; damaged copies give errors, not panics; resampling keeps the mean.

mod common;

use common::{ScratchDir, exemplar};
use terrasketch_synthesis::{
    DemError, DemFormat, HorizontalUnits, LoadOptions, MAX_CELLS, load_dem, load_exemplar_dir,
    resample_to_cell_size, shipped_exemplar_dir, web_mercator_cell_size_m,
};

/// Metres of one 3 arc-second step east-west at `lat_deg` and north-south.
fn srtm3_cell_m(lat_deg: f64) -> [f64; 2] {
    let deg = 3.0 / 3600.0;
    [
        deg * lat_deg.to_radians().cos() * 111_320.0,
        deg * 110_574.0,
    ]
}

struct Expected {
    file: &'static str,
    size: (usize, usize),
    cell_m: [f64; 2],
    range_m: (f32, f32),
    nodata: Option<f64>,
}

fn expected() -> Vec<Expected> {
    vec![
        Expected {
            file: "sierra_nevada_north_srtm3.tif",
            size: (2043, 1024),
            cell_m: [74.0, 93.0], // the README's rounded values
            range_m: (89.0, 4205.0),
            nodata: Some(0.0),
        },
        Expected {
            file: "grand_canyon_terrarium_z11.png",
            size: (256, 256),
            // Tile z11 y=803 is centred on 36.10 N: 40075016.686 * cos(36.10) / 2^11 / 256.
            cell_m: [61.76, 61.76],
            range_m: (715.0, 2489.0),
            nodata: None,
        },
        Expected {
            file: "jacksboro_fault_srtm3.tif",
            size: (403, 344),
            cell_m: srtm3_cell_m(36.59), // centre of 36.446..36.733 N
            range_m: (236.0, 1076.0),
            nodata: None,
        },
        Expected {
            file: "zurich_dhm25.tif",
            size: (399, 366),
            cell_m: [25.0, 25.0],
            range_m: (393.0, 870.0),
            nodata: Some(-9999.0),
        },
        Expected {
            file: "kossou_plains_srtm3.tif",
            size: (1201, 1201),
            cell_m: srtm3_cell_m(7.5), // 7..8 N
            range_m: (145.0, 546.0),
            nodata: Some(-32767.0),
        },
    ]
}

#[test]
fn every_shipped_file_has_the_documented_size_cell_and_range() {
    for e in expected() {
        let dem = load_dem(&exemplar(e.file), &LoadOptions::default())
            .unwrap_or_else(|err| panic!("{}: {err}", e.file));
        assert_eq!((dem.width, dem.height), e.size, "{}", e.file);
        assert_eq!(dem.heights_m.len(), e.size.0 * e.size.1);
        for axis in 0..2 {
            let rel = (dem.cell_size_m[axis] / e.cell_m[axis] - 1.0).abs();
            assert!(
                rel < 0.02,
                "{}: cell {:?} vs {:?}",
                e.file,
                dem.cell_size_m,
                e.cell_m
            );
        }
        let (lo, hi) = dem.height_range_m();
        assert!(
            (lo - e.range_m.0).abs() <= 3.0,
            "{}: min {lo} vs {}",
            e.file,
            e.range_m.0
        );
        assert!(
            (hi - e.range_m.1).abs() <= 3.0,
            "{}: max {hi} vs {}",
            e.file,
            e.range_m.1
        );
        assert!(dem.heights_m.iter().all(|h| h.is_finite()), "{}", e.file);
        assert_eq!(dem.source.nodata, e.nodata, "{}", e.file);
        if let Some(nodata) = e.nodata {
            assert!(
                dem.heights_m.iter().all(|&h| f64::from(h) != nodata),
                "{}",
                e.file
            );
        }
        assert!(
            !dem.source.rows_flipped,
            "{}: all shipped files are stored north-up",
            e.file
        );
        assert!(
            dem.source.warnings.is_empty(),
            "{}: {:?}",
            e.file,
            dem.source.warnings
        );
        assert_eq!(dem.name, e.file.rsplit_once('.').unwrap().0);
    }
}

#[test]
fn format_details_are_reported() {
    let load = |f: &str| load_dem(&exemplar(f), &LoadOptions::default()).unwrap();
    let sierra = load("sierra_nevada_north_srtm3.tif");
    assert_eq!(
        sierra.source.format,
        DemFormat::GeoTiff {
            compression: "LZW",
            tiled: true,
            predictor: false
        }
    );
    assert_eq!(sierra.source.horizontal_units, HorizontalUnits::Degrees);
    let lat = sierra.source.centre_lat_deg.unwrap();
    assert!((lat - 37.665).abs() < 0.01, "{lat}");
    let jacksboro = load("jacksboro_fault_srtm3.tif");
    assert_eq!(
        jacksboro.source.format,
        DemFormat::GeoTiff {
            compression: "deflate",
            tiled: false,
            predictor: false
        }
    );
    // Zurich has no CRS keys; a 25-unit pixel scale is read as metres (projected, Swiss LV03).
    let zurich = load("zurich_dhm25.tif");
    assert_eq!(zurich.source.horizontal_units, HorizontalUnits::Metres);
    assert_eq!(zurich.cell_size_m, [25.0, 25.0]);
    // Kossou is PixelIsPoint with its tiepoint on the 8 N, 6 W cell centre: centre at 7.5 N.
    let kossou = load("kossou_plains_srtm3.tif");
    assert!((kossou.source.centre_lat_deg.unwrap() - 7.5).abs() < 1e-9);
    let canyon = load("grand_canyon_terrarium_z11.png");
    assert_eq!(canyon.source.format, DemFormat::TerrariumPng);
}

#[test]
fn grand_canyon_sidecar_matches_the_tile_geometry() {
    let dem = load_dem(
        &exemplar("grand_canyon_terrarium_z11.png"),
        &LoadOptions::default(),
    )
    .unwrap();
    let true_cell = web_mercator_cell_size_m(11, 803);
    assert!(
        (dem.cell_size_m[0] - true_cell).abs() < 0.01,
        "{:?} vs {true_cell}",
        dem.cell_size_m
    );
}

#[test]
fn the_shipped_folder_loads_in_name_order() {
    let (dems, failures) = load_exemplar_dir(&shipped_exemplar_dir());
    assert!(failures.is_empty(), "{failures:?}");
    let names: Vec<&str> = dems.iter().map(|d| d.name.as_str()).collect();
    assert_eq!(
        names,
        [
            "grand_canyon_terrarium_z11",
            "jacksboro_fault_srtm3",
            "kossou_plains_srtm3",
            "sierra_nevada_north_srtm3",
            "zurich_dhm25"
        ]
    );
}

#[test]
fn truncated_copies_are_errors() {
    let scratch = ScratchDir::new("truncated");
    // The PNG's cell size is given so that the error can only come from the damaged data.
    let opts = LoadOptions {
        cell_size_m: Some(60.0),
        ..LoadOptions::default()
    };
    for e in expected() {
        let bytes = std::fs::read(exemplar(e.file)).unwrap();
        let path = scratch.path(e.file);
        std::fs::write(&path, &bytes[..bytes.len() * 6 / 10]).unwrap();
        match load_dem(&path, &opts) {
            Err(DemError::Decode { .. }) => {}
            other => panic!("{}: expected Malformed, got {other:?}", e.file),
        }
    }
}

/// Cuts and corrupts the shipped files at many places: every outcome must be a value, never a
/// panic (a panic fails the test).
#[test]
fn damaged_copies_never_panic() {
    let scratch = ScratchDir::new("damaged");
    let opts = LoadOptions {
        cell_size_m: Some(60.0),
        ..LoadOptions::default()
    };
    let mut seed = 0x9e37_79b9_7f4a_7c15u64;
    let mut next = move || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        seed
    };
    let (mut errors, mut loaded) = (0, 0);
    for e in expected() {
        let bytes = std::fs::read(exemplar(e.file)).unwrap();
        let path = scratch.path(e.file);
        for k in 1..12 {
            std::fs::write(&path, &bytes[..bytes.len() * k / 12]).unwrap();
            assert!(load_dem(&path, &opts).is_err(), "{} cut to {k}/12", e.file);
            errors += 1;
        }
        for _ in 0..12 {
            let mut damaged = bytes.clone();
            // Hit the header and structures (first 4 KiB) more often than the bulk.
            for _ in 0..8 {
                let span = if next() % 2 == 0 {
                    4096.min(damaged.len())
                } else {
                    damaged.len()
                };
                let at = (next() as usize) % span;
                damaged[at] = next() as u8;
            }
            std::fs::write(&path, &damaged).unwrap();
            match load_dem(&path, &opts) {
                Ok(dem) => {
                    assert!(dem.heights_m.iter().all(|h| h.is_finite()));
                    loaded += 1;
                }
                Err(_) => errors += 1,
            }
        }
    }
    assert!(errors > 0 && errors + loaded == 5 * 23);
}

#[test]
fn doubling_the_cell_size_halves_the_grid_and_keeps_the_mean() {
    for file in [
        "zurich_dhm25.tif",
        "kossou_plains_srtm3.tif",
        "grand_canyon_terrarium_z11.png",
    ] {
        let dem = load_dem(&exemplar(file), &LoadOptions::default()).unwrap();
        let coarse = resample_to_cell_size(&dem, 2.0 * dem.cell_size_m[0]).unwrap();
        let halves = |n: usize, m: usize| (m as f64 - n as f64 / 2.0).abs() <= 0.5;
        assert!(
            halves(dem.width, coarse.width),
            "{file}: {} -> {}",
            dem.width,
            coarse.width
        );
        // Kossou's cells are not square (92.0 x 92.1 m): its rows shrink by 2 * 92.0 / 92.1.
        let expected_rows = dem.height as f64 * dem.cell_size_m[1] / coarse.cell_size_m[1];
        assert!(
            (coarse.height as f64 - expected_rows).abs() <= 0.5,
            "{file}: rows {}",
            coarse.height
        );
        let (before, after) = (dem.mean_height_m(), coarse.mean_height_m());
        assert!(
            (after / before - 1.0).abs() < 0.01,
            "{file}: mean {before} -> {after}"
        );
        assert_eq!(coarse.cell_size_m, [2.0 * dem.cell_size_m[0]; 2]);
    }
}

#[test]
fn sierra_to_square_cells_and_upsampling() {
    let sierra = load_dem(
        &exemplar("sierra_nevada_north_srtm3.tif"),
        &LoadOptions::default(),
    )
    .unwrap();
    // 73.4 x 92.1 m to 90 m: x shrinks (area average), y grows slightly (bicubic).
    let square = resample_to_cell_size(&sierra, 90.0).unwrap();
    assert_eq!(
        square.width,
        (2043.0 * sierra.cell_size_m[0] / 90.0_f64).round() as usize
    );
    assert_eq!(
        square.height,
        (1024.0 * sierra.cell_size_m[1] / 90.0_f64).round() as usize
    );
    assert!((square.mean_height_m() / sierra.mean_height_m() - 1.0).abs() < 0.01);
    let zurich = load_dem(&exemplar("zurich_dhm25.tif"), &LoadOptions::default()).unwrap();
    let fine = resample_to_cell_size(&zurich, 12.5).unwrap();
    assert_eq!((fine.width, fine.height), (798, 732));
    assert!((fine.mean_height_m() / zurich.mean_height_m() - 1.0).abs() < 0.01);
    let (lo, hi) = fine.height_range_m();
    assert!(lo > 393.0 - 5.0 && hi < 870.0 + 5.0, "{lo}..{hi}");
}

#[test]
fn resampling_refuses_huge_or_invalid_targets() {
    let zurich = load_dem(&exemplar("zurich_dhm25.tif"), &LoadOptions::default()).unwrap();
    let started = std::time::Instant::now();
    match resample_to_cell_size(&zurich, 0.001) {
        Err(DemError::TooLarge { width, height, .. }) => {
            assert!(width as u128 * height as u128 > MAX_CELLS as u128)
        }
        other => panic!("expected TooLarge, got {other:?}"),
    }
    assert!(started.elapsed().as_secs_f64() < 1.0);
    for bad in [0.0, -5.0, f64::NAN, f64::INFINITY] {
        assert!(matches!(
            resample_to_cell_size(&zurich, bad),
            Err(DemError::InvalidCellSize { .. })
        ));
    }
}
