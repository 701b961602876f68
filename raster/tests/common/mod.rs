//! Helpers shared by the integration tests: scratch directories, test maps, tolerances.

#![allow(dead_code)] // Each test binary uses a different subset.

use std::fs;
use std::path::{Path, PathBuf};

use terrasketch_raster::Heightmap;

/// A scratch directory under Cargo's per-target temporary directory, removed on drop.
pub struct ScratchDir(PathBuf);

impl ScratchDir {
    /// A fresh, empty directory unique to `name` and this process.
    pub fn new(name: &str) -> ScratchDir {
        let path = Path::new(env!("CARGO_TARGET_TMPDIR"))
            .join(format!("raster-{name}-{}", std::process::id()));
        let _ = fs::remove_dir_all(&path);
        fs::create_dir_all(&path).expect("create scratch directory");
        ScratchDir(path)
    }

    /// `name` inside the directory.
    pub fn join(&self, name: &str) -> PathBuf {
        self.0.join(name)
    }

    /// The directory itself.
    pub fn path(&self) -> &Path {
        &self.0
    }

    /// Names of the entries in the directory, sorted (temporary files would show up here).
    pub fn entries(&self) -> Vec<String> {
        let mut names: Vec<String> = fs::read_dir(&self.0)
            .expect("list scratch directory")
            .map(|entry| {
                entry
                    .expect("entry")
                    .file_name()
                    .to_string_lossy()
                    .into_owned()
            })
            .collect();
        names.sort();
        names
    }
}

impl Drop for ScratchDir {
    fn drop(&mut self) {
        let _ = fs::remove_dir_all(&self.0);
    }
}

/// A non-square map whose rows all differ: a tilted ramp plus a sine bump, cells 2.5 m x 4 m.
pub fn ramp_sine(width: usize, height: usize) -> Heightmap {
    let mut data = Vec::with_capacity(width * height);
    for row in 0..height {
        for column in 0..width {
            let (x, y) = (column as f32, row as f32);
            data.push(120.0 + 3.5 * x - 2.25 * y + 40.0 * (0.37 * x).sin() * (0.21 * y).cos());
        }
    }
    Heightmap {
        width,
        height,
        data,
        cell_size_m: [2.5, 4.0],
    }
}

/// A constant map.
pub fn constant(width: usize, height: usize, height_m: f32) -> Heightmap {
    Heightmap {
        width,
        height,
        data: vec![height_m; width * height],
        cell_size_m: [1.0, 1.0],
    }
}

/// Asserts `actual` equals `expected` within the quantisation bound of a 16-bit stretch over
/// `expected`'s range: half a step plus `f32` rounding of the value.
pub fn assert_within_quantisation(expected: &Heightmap, actual: &Heightmap) {
    assert_eq!(
        (actual.width, actual.height),
        (expected.width, expected.height)
    );
    let min_m = expected.data.iter().copied().fold(f32::INFINITY, f32::min);
    let max_m = expected
        .data
        .iter()
        .copied()
        .fold(f32::NEG_INFINITY, f32::max);
    let half_step_m = (max_m - min_m) / 65535.0 / 2.0;
    for (index, (&want, &got)) in expected.data.iter().zip(&actual.data).enumerate() {
        let bound_m = half_step_m + want.abs().max(got.abs()) * f32::EPSILON;
        assert!(
            (want - got).abs() <= bound_m,
            "sample {index}: wrote {want}, read {got}, bound {bound_m}"
        );
    }
}

/// CRC-32 (ISO-HDLC, as used by PNG chunks), for crafting PNG files.
pub fn crc32(bytes: &[u8]) -> u32 {
    let mut crc = !0u32;
    for &byte in bytes {
        crc ^= u32::from(byte);
        for _ in 0..8 {
            let mask = (crc & 1).wrapping_neg();
            crc = (crc >> 1) ^ (0xEDB8_8320 & mask);
        }
    }
    !crc
}
