//! Writes replace the target whole or not at all, leave no temporary files, and report the
//! target path on I/O errors. Non-finite data is refused before anything is written.

mod common;

use std::fs;

use common::{ScratchDir, constant, ramp_sine};
use terrasketch_raster::{RasterError, encode_heightmap, read_heightmap, write_heightmap};

const NAMES: [&str; 4] = ["map.exr", "map.tif", "map.png", "map.r16"];

#[test]
fn missing_directory_is_an_io_error_naming_the_path_and_creates_nothing() {
    let dir = ScratchDir::new("missing-dir");
    let map = ramp_sine(37, 23);
    for name in NAMES {
        let path = dir.join("not/there").join(name);
        let error = write_heightmap(&path, &map).unwrap_err();
        assert!(
            matches!(&error, RasterError::Io { path: p, .. } if *p == path),
            "{error}"
        );
        assert!(
            error.to_string().contains(&*path.to_string_lossy()),
            "{error}"
        );
    }
    assert!(
        dir.entries().is_empty(),
        "nothing created: {:?}",
        dir.entries()
    );
}

#[test]
fn overwrite_replaces_the_target_whole_and_leaves_no_temporary_file() {
    let dir = ScratchDir::new("overwrite");
    let big = ramp_sine(64, 48);
    let small = ramp_sine(37, 23);
    for name in NAMES {
        let path = dir.join(name);
        write_heightmap(&path, &big).unwrap();
        let info = write_heightmap(&path, &small).unwrap();
        let (expected, _) = encode_heightmap(info.format, &small).unwrap();
        assert_eq!(
            fs::read(&path).unwrap(),
            expected,
            "{name}: exactly the new file, no tail"
        );
        if name != "map.r16" {
            let back = read_heightmap(&path).unwrap();
            assert_eq!((back.width, back.height), (37, 23), "{name}");
        }
    }
    assert_eq!(dir.entries(), ["map.exr", "map.png", "map.r16", "map.tif"]);
}

#[test]
fn overwrite_swaps_in_a_new_file_instead_of_writing_in_place() {
    let dir = ScratchDir::new("new-inode");
    let first = ramp_sine(37, 23);
    let second = constant(37, 23, -5.0);
    for name in NAMES {
        let path = dir.join(name);
        write_heightmap(&path, &first).unwrap();
        let old_bytes = fs::read(&path).unwrap();
        // A second name for the old file: an in-place write would change it too.
        let old_link = dir.join(&format!("old-{name}"));
        fs::hard_link(&path, &old_link).unwrap();
        write_heightmap(&path, &second).unwrap();
        assert_eq!(
            fs::read(&old_link).unwrap(),
            old_bytes,
            "{name}: old file intact"
        );
        assert_ne!(
            fs::read(&path).unwrap(),
            old_bytes,
            "{name}: target replaced"
        );
    }
}

#[test]
fn non_finite_data_is_refused_naming_the_first_bad_sample() {
    let dir = ScratchDir::new("non-finite");
    for (bad_value, label) in [
        (f32::NAN, "NaN"),
        (f32::INFINITY, "+inf"),
        (f32::NEG_INFINITY, "-inf"),
    ] {
        let mut map = ramp_sine(37, 23);
        map.data[5 * 37 + 9] = bad_value;
        map.data[20 * 37] = f32::NAN;
        for name in NAMES {
            let path = dir.join(name);
            let error = write_heightmap(&path, &map).unwrap_err();
            assert!(
                matches!(error, RasterError::NonFinite { index } if index == 5 * 37 + 9),
                "{name} {label}: {error}"
            );
            assert!(
                error.to_string().contains(&(5 * 37 + 9).to_string()),
                "{error}"
            );
            assert!(!path.exists(), "{name} {label}: nothing written");
        }
    }
    assert!(dir.entries().is_empty(), "{:?}", dir.entries());
}

#[test]
fn a_failed_write_leaves_the_existing_target_untouched() {
    let dir = ScratchDir::new("failed-overwrite");
    let good = ramp_sine(37, 23);
    let mut bad = constant(37, 23, 1.0);
    bad.data[100] = f32::NAN;
    for name in NAMES {
        let path = dir.join(name);
        write_heightmap(&path, &good).unwrap();
        let before = fs::read(&path).unwrap();
        assert!(write_heightmap(&path, &bad).is_err(), "{name}");
        assert_eq!(fs::read(&path).unwrap(), before, "{name}: target untouched");
    }
    assert_eq!(dir.entries(), ["map.exr", "map.png", "map.r16", "map.tif"]);
}

#[test]
fn a_failed_rename_removes_the_temporary_file() {
    let dir = ScratchDir::new("rename-fails");
    // The target is a non-empty directory: the temporary file is written, the rename fails.
    let path = dir.join("occupied.tif");
    fs::create_dir(&path).unwrap();
    fs::write(path.join("keep"), b"x").unwrap();
    let error = write_heightmap(&path, &ramp_sine(37, 23)).unwrap_err();
    assert!(
        matches!(&error, RasterError::Io { path: p, .. } if *p == path),
        "{error}"
    );
    assert_eq!(dir.entries(), ["occupied.tif"], "temporary file removed");
    assert_eq!(fs::read(path.join("keep")).unwrap(), b"x");
}

#[cfg(unix)]
#[test]
fn unwritable_directory_is_an_io_error() {
    use std::os::unix::fs::PermissionsExt;

    let dir = ScratchDir::new("read-only");
    let locked = dir.join("locked");
    fs::create_dir(&locked).unwrap();
    fs::set_permissions(&locked, fs::Permissions::from_mode(0o555)).unwrap();
    // Privileged users (root in containers) may write anyway; then there is nothing to test.
    let probe = locked.join("probe");
    let enforced = fs::write(&probe, b"").is_err();
    let _ = fs::remove_file(&probe);
    if enforced {
        let path = locked.join("map.png");
        let error = write_heightmap(&path, &ramp_sine(8, 8)).unwrap_err();
        assert!(
            matches!(&error, RasterError::Io { path: p, .. } if *p == path),
            "{error}"
        );
        assert!(
            fs::read_dir(&locked).unwrap().next().is_none(),
            "nothing created"
        );
    }
    fs::set_permissions(&locked, fs::Permissions::from_mode(0o755)).unwrap();
}

#[test]
fn concurrent_writes_to_one_directory_do_not_collide() {
    let dir = ScratchDir::new("concurrent");
    std::thread::scope(|scope| {
        for thread in 0..4 {
            let dir = &dir;
            scope.spawn(move || {
                for round in 0..5 {
                    let map = constant(9, 7, (thread * 10 + round) as f32);
                    write_heightmap(&dir.join("shared.tif"), &map).unwrap();
                    write_heightmap(&dir.join(&format!("own-{thread}.exr")), &map).unwrap();
                }
            });
        }
    });
    let shared = read_heightmap(&dir.join("shared.tif")).unwrap();
    let value = shared.data[0];
    assert!(
        shared.data.iter().all(|&h| h == value),
        "one whole write won"
    );
    assert_eq!(
        dir.entries(),
        [
            "own-0.exr",
            "own-1.exr",
            "own-2.exr",
            "own-3.exr",
            "shared.tif"
        ]
    );
}
