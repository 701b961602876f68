//! Atomic saving: the target is the old file or the complete new one, never anything else.

use std::fs;
use std::path::PathBuf;

use terrasketch_sketch::{
    SketchError, benchmark_sketch, example_sketch, load_sketch, save_sketch_atomic,
};

/// A fresh empty directory for one test, removed when dropped.
struct TempDir(PathBuf);

impl TempDir {
    fn new(name: &str) -> TempDir {
        let dir =
            std::env::temp_dir().join(format!("terrasketch-sketch-{name}-{}", std::process::id()));
        let _ = fs::remove_dir_all(&dir);
        fs::create_dir_all(&dir).unwrap();
        TempDir(dir)
    }

    fn entries(&self) -> Vec<String> {
        let mut names: Vec<String> = fs::read_dir(&self.0)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        names
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = fs::remove_dir_all(&self.0);
    }
}

#[test]
fn save_then_load_gives_the_same_sketch() {
    let dir = TempDir::new("save-load");
    let path = dir.0.join("scene.json");
    save_sketch_atomic(&example_sketch(), &path).unwrap();
    let loaded = load_sketch(&path).unwrap();
    assert_eq!(loaded.sketch, example_sketch());
    assert_eq!(loaded.warnings, vec![]);
    assert_eq!(dir.entries(), vec!["scene.json"]);
}

#[test]
fn saving_over_an_existing_file_replaces_it() {
    let dir = TempDir::new("replace");
    let path = dir.0.join("scene.json");
    fs::write(
        &path,
        "old contents that are much longer than nothing at all",
    )
    .unwrap();
    save_sketch_atomic(&benchmark_sketch(), &path).unwrap();
    assert_eq!(load_sketch(&path).unwrap().sketch, benchmark_sketch());
    save_sketch_atomic(&example_sketch(), &path).unwrap();
    assert_eq!(load_sketch(&path).unwrap().sketch, example_sketch());
    // No temporary file left behind.
    assert_eq!(dir.entries(), vec!["scene.json"]);
}

#[test]
fn saving_into_a_missing_directory_fails_and_creates_nothing() {
    let dir = TempDir::new("missing-dir");
    let path = dir.0.join("not-here").join("scene.json");
    let err = save_sketch_atomic(&example_sketch(), &path).unwrap_err();
    assert!(
        matches!(err, SketchError::Io { path: ref p, .. } if *p == path),
        "{err:?}"
    );
    assert!(err.to_string().contains("not-here"), "{err}");
    assert_eq!(dir.entries(), Vec::<String>::new());
}

#[test]
fn failed_rename_keeps_the_old_target_and_removes_the_temp_file() {
    // The target is a non-empty directory: the temporary file is written, the rename fails.
    let dir = TempDir::new("failed-rename");
    let target = dir.0.join("scene.json");
    fs::create_dir(&target).unwrap();
    fs::write(target.join("keep.txt"), "kept").unwrap();
    let err = save_sketch_atomic(&example_sketch(), &target).unwrap_err();
    assert!(matches!(err, SketchError::Io { .. }), "{err:?}");
    assert_eq!(dir.entries(), vec!["scene.json"]);
    assert_eq!(fs::read_to_string(target.join("keep.txt")).unwrap(), "kept");
}

#[test]
fn path_without_a_file_name_is_an_io_error() {
    let err = save_sketch_atomic(&example_sketch(), std::path::Path::new("/")).unwrap_err();
    assert!(matches!(err, SketchError::Io { .. }), "{err:?}");
}

#[cfg(unix)]
#[test]
fn replaced_file_keeps_its_permissions() {
    use std::os::unix::fs::PermissionsExt;
    let dir = TempDir::new("permissions");
    let path = dir.0.join("scene.json");
    fs::write(&path, "old").unwrap();
    fs::set_permissions(&path, fs::Permissions::from_mode(0o640)).unwrap();
    save_sketch_atomic(&example_sketch(), &path).unwrap();
    assert_eq!(
        fs::metadata(&path).unwrap().permissions().mode() & 0o777,
        0o640
    );
}
