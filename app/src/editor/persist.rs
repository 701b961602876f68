//! Refined terrains that survive save and reopen.
//!
//! Saving a sketch whose refined layer is shown writes the layer's heights beside it
//! (`NAME.refined.exr`, f32, north-up, written atomically first) and then the sketch with a
//! `refined` record: seed, solve size, exemplar names, parameters, the sketch's digest and the
//! heights' digest. Reopening loads the heights when the file's size and digest match the record
//! and the record's sketch digest matches the sketch; otherwise the layer is recomputed in the
//! background from the record (the same inputs give the same bits, see [`super::refine`]).

use std::path::{Path, PathBuf};

use terrasketch_multigrid::Grid;
use terrasketch_raster::{Heightmap, read_heightmap, write_heightmap};
use terrasketch_sketch::{RefinedRecord, Sketch, heights_digest, sketch_digest};
use terrasketch_synthesis::pits::PitMode;
use terrasketch_synthesis::refine::{MAX_FINE_DETAIL, RefineParams};

use crate::refine::flip_rows;

/// What made a refined layer: enough to make it again.
#[derive(Debug, Clone, PartialEq)]
pub struct Provenance {
    /// Exemplar names, in the order used.
    pub exemplars: Vec<String>,
    /// The parameters (seed included).
    pub params: RefineParams,
}

/// The heights file saved beside `sketch_path`: `NAME.refined.exr` for `NAME.json`.
pub fn heights_path(sketch_path: &Path) -> PathBuf {
    let stem = sketch_path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "sketch".into());
    sketch_path.with_file_name(format!("{stem}.refined.exr"))
}

/// A parameter's name, bounds and whether it is a whole number.
struct Spec {
    name: &'static str,
    lo: f64,
    hi: f64,
    whole: bool,
}

const fn spec(name: &'static str, lo: f64, hi: f64, whole: bool) -> Spec {
    Spec {
        name,
        lo,
        hi,
        whole,
    }
}

/// Every parameter a record may hold, with bounds that keep a recomputation affordable.
const SPECS: [Spec; 23] = [
    spec("patch_size", 16.0, 256.0, true),
    spec("lowpass_cells", 0.0, 4096.0, true),
    spec("pit_mode", 0.0, 3.0, true),
    spec("pit_max_depth_m", 0.0, 100_000.0, false),
    spec("pit_max_length", 0.0, 1e9, true),
    spec("sites_per_exemplar", 1.0, 100_000.0, true),
    spec("feature_sites_per_exemplar", 0.0, 100_000.0, true),
    spec("overlap_candidates", 1.0, 1000.0, true),
    spec("graphcut_candidates", 1.0, 100.0, true),
    spec("jitter", 0.0, 1.0, false),
    spec("low_weight", 0.0, 1.0, false),
    spec("constraint_weight", 0.0, 1.0, false),
    spec("levels", 1.0, 8.0, true),
    spec("level_band_cells", 1.0, 1024.0, true),
    spec("guide_weight", 0.0, 100.0, false),
    spec("weights.feature_profile", 0.0, 1000.0, false),
    spec("weights.feature_angle", 0.0, 1000.0, false),
    spec("weights.noise", 0.0, 1000.0, false),
    spec("weights.shape", 0.0, 1000.0, false),
    spec("weights.overlap", 0.0, 1000.0, false),
    spec("weights.relief", 0.0, 1000.0, false),
    spec("weights.reuse", 0.0, 1000.0, false),
    spec("fine_detail", 0.0, MAX_FINE_DETAIL as f64, false),
];

/// Parameters as the record stores them (the seed is stored on its own).
pub fn params_to_record(p: &RefineParams) -> Vec<(String, f64)> {
    let (mode, depth, length) = match p.pit_mode {
        PitMode::Breach => (0.0, 0.0, 0.0),
        PitMode::Fill { epsilon: false } => (1.0, 0.0, 0.0),
        PitMode::Fill { epsilon: true } => (2.0, 0.0, 0.0),
        PitMode::Hybrid {
            max_depth_m,
            max_length,
        } => (3.0, f64::from(max_depth_m), max_length as f64),
    };
    let w = &p.weights;
    let mut v: Vec<(String, f64)> = [
        ("patch_size", p.patch_size as f64),
        ("lowpass_cells", p.lowpass_cells as f64),
        ("pit_mode", mode),
        ("pit_max_depth_m", depth),
        ("pit_max_length", length),
        ("sites_per_exemplar", p.sites_per_exemplar as f64),
        (
            "feature_sites_per_exemplar",
            p.feature_sites_per_exemplar as f64,
        ),
        ("overlap_candidates", p.overlap_candidates as f64),
        ("graphcut_candidates", p.graphcut_candidates as f64),
        ("jitter", f64::from(p.jitter)),
        ("low_weight", f64::from(p.low_weight)),
        ("constraint_weight", f64::from(p.constraint_weight)),
        ("levels", p.levels as f64),
        ("level_band_cells", p.level_band_cells as f64),
        ("guide_weight", f64::from(p.guide_weight)),
        ("weights.feature_profile", f64::from(w.feature_profile)),
        ("weights.feature_angle", f64::from(w.feature_angle)),
        ("weights.noise", f64::from(w.noise)),
        ("weights.shape", f64::from(w.shape)),
        ("weights.overlap", f64::from(w.overlap)),
        ("weights.relief", f64::from(w.relief)),
        ("weights.reuse", f64::from(w.reuse)),
        ("fine_detail", f64::from(p.fine_detail)),
    ]
    .into_iter()
    .map(|(k, x)| (k.to_string(), x))
    .collect();
    v.sort_by(|a, b| a.0.cmp(&b.0));
    v
}

/// Parameters from a record: absent names keep their defaults; an unknown name or a value out
/// of bounds is refused with a message naming it.
pub fn params_from_record(seed: u64, stored: &[(String, f64)]) -> Result<RefineParams, String> {
    let mut p = RefineParams {
        seed,
        ..RefineParams::default()
    };
    let (mut mode, mut depth, mut length) = (0.0, 0.0, 0.0);
    for (name, x) in stored {
        let x = *x;
        let bounds = SPECS
            .iter()
            .find(|s| s.name == name)
            .map(|s| (s.lo, s.hi, s.whole));
        let Some((lo, hi, whole)) = bounds else {
            return Err(format!("refined.params: unknown parameter {name:?}"));
        };
        if !(lo..=hi).contains(&x) || (whole && x.fract() != 0.0) {
            let kind = if whole { "a whole number" } else { "a number" };
            return Err(format!(
                "refined.params.{name} must be {kind} from {lo} to {hi}, got {x}"
            ));
        }
        let (u, f) = (x as usize, x as f32);
        match name.as_str() {
            "patch_size" => p.patch_size = u,
            "lowpass_cells" => p.lowpass_cells = u,
            "pit_mode" => mode = x,
            "pit_max_depth_m" => depth = x,
            "pit_max_length" => length = x,
            "sites_per_exemplar" => p.sites_per_exemplar = u,
            "feature_sites_per_exemplar" => p.feature_sites_per_exemplar = u,
            "overlap_candidates" => p.overlap_candidates = u,
            "graphcut_candidates" => p.graphcut_candidates = u,
            "jitter" => p.jitter = f,
            "low_weight" => p.low_weight = f,
            "constraint_weight" => p.constraint_weight = f,
            "levels" => p.levels = u,
            "level_band_cells" => p.level_band_cells = u,
            "guide_weight" => p.guide_weight = f,
            "weights.feature_profile" => p.weights.feature_profile = f,
            "weights.feature_angle" => p.weights.feature_angle = f,
            "weights.noise" => p.weights.noise = f,
            "weights.shape" => p.weights.shape = f,
            "weights.overlap" => p.weights.overlap = f,
            "weights.reuse" => p.weights.reuse = f,
            "fine_detail" => p.fine_detail = f,
            _ => p.weights.relief = f,
        }
    }
    // Records written before the reuse cost existed name no weight for it: theirs was 0, and
    // with 0 they are recomputed as they were made.
    if !stored.iter().any(|(k, _)| k == "weights.reuse") {
        p.weights.reuse = 0.0;
    }
    // Likewise for the detail in the octaves finer than the exemplars, which came later still.
    if !stored.iter().any(|(k, _)| k == "fine_detail") {
        p.fine_detail = 0.0;
    }
    if stored.iter().any(|(k, _)| k == "pit_mode") {
        p.pit_mode = match mode as u8 {
            0 => PitMode::Breach,
            1 => PitMode::Fill { epsilon: false },
            2 => PitMode::Fill { epsilon: true },
            _ => PitMode::Hybrid {
                max_depth_m: depth as f32,
                max_length: length as usize,
            },
        };
    }
    Ok(p)
}

/// The record of a layer made by `made` for `sketch` at solve size `n`; `heights` is the
/// digest of the saved heights file, if one was written.
pub fn record(
    made: &Provenance,
    sketch: &Sketch,
    n: usize,
    heights: Option<String>,
) -> RefinedRecord {
    RefinedRecord {
        seed: made.params.seed,
        size: n,
        exemplars: made.exemplars.clone(),
        params: params_to_record(&made.params),
        sketch_digest: sketch_digest(sketch),
        heights_digest: heights,
    }
}

/// Writes level-0 heights (`grid.n`^2, row 0 = south) to `path` atomically as north-up f32 EXR;
/// returns the digest of what was written.
pub fn write_heights(path: &Path, grid: &Grid, h0: &[f32]) -> Result<String, String> {
    let n = grid.n;
    let map = Heightmap {
        width: n,
        height: n,
        data: flip_rows(h0, n),
        cell_size_m: grid.cell_size_m(),
    };
    let digest = heights_digest(&map.data);
    write_heightmap(path, &map)
        .map(|_| digest)
        .map_err(|e| format!("cannot write the refined heights {}: {e}", path.display()))
}

/// Reads the heights file saved for `record` and checks it: the record's sketch digest must be
/// `sketch`'s, its size the grid's, and the file's size and digest the record's. Returns level-0
/// heights (row 0 = south) or why the file cannot be used.
pub fn load_heights(
    path: &Path,
    record: &RefinedRecord,
    sketch: &Sketch,
    grid: &Grid,
) -> Result<Vec<f32>, String> {
    if record.sketch_digest != sketch_digest(sketch) {
        return Err("the sketch changed since it was refined".into());
    }
    if record.size != grid.n {
        return Err(format!(
            "it was refined at size {}, the editor runs at {}",
            record.size, grid.n
        ));
    }
    let Some(want) = &record.heights_digest else {
        return Err("no heights file was saved".into());
    };
    // A file far larger than an n x n f32 raster is refused before it is read.
    let max_bytes = 4 * (grid.n as u64).pow(2) + (1 << 20);
    match std::fs::metadata(path) {
        Ok(m) if m.is_file() && m.len() <= max_bytes => {}
        Ok(m) if m.is_file() => {
            return Err(format!(
                "{} is {} bytes, more than an {} x {} raster",
                file_name(path),
                m.len(),
                grid.n,
                grid.n
            ));
        }
        _ => return Err(format!("{} is missing", file_name(path))),
    }
    let map = read_heightmap(path).map_err(|e| format!("{}: {e}", file_name(path)))?;
    if (map.width, map.height) != (grid.n, grid.n) {
        return Err(format!(
            "{} is {} x {}, not {} x {}",
            file_name(path),
            map.width,
            map.height,
            grid.n,
            grid.n
        ));
    }
    if &heights_digest(&map.data) != want {
        return Err(format!(
            "{} does not match the record (stale)",
            file_name(path)
        ));
    }
    Ok(flip_rows(&map.data, grid.n))
}

fn file_name(path: &Path) -> String {
    path.file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| path.display().to_string())
}

#[cfg(test)]
mod tests {
    use super::*;
    use terrasketch_sketch::example_sketch;

    #[test]
    fn params_round_trip_through_the_record() {
        let p = RefineParams {
            seed: 7,
            pit_mode: PitMode::Hybrid {
                max_depth_m: 5.0,
                max_length: 40,
            },
            ..RefineParams::default()
        };
        let back = params_from_record(7, &params_to_record(&p)).unwrap();
        assert_eq!(format!("{back:?}"), format!("{p:?}"));
        // A record naming no parameter: the defaults, but no reuse cost and no fine detail,
        // which records made before them did not have.
        let mut old = RefineParams {
            seed: 3,
            fine_detail: 0.0,
            ..RefineParams::default()
        };
        old.weights.reuse = 0.0;
        assert_eq!(
            format!("{:?}", params_from_record(3, &[]).unwrap()),
            format!("{old:?}")
        );
        let with = params_from_record(3, &[("fine_detail".into(), 0.75)]).unwrap();
        assert_eq!(with.fine_detail, 0.75);
        for bad in [
            ("patch_size", 1e12),
            ("levels", 2.5),
            ("colour", 1.0),
            ("fine_detail", 5.0),
        ] {
            let e = params_from_record(1, &[(bad.0.to_string(), bad.1)]).unwrap_err();
            assert!(e.contains(bad.0), "{e}");
        }
    }

    #[test]
    fn heights_files_are_checked_against_the_record() {
        let dir = tempfile::tempdir().unwrap();
        let sketch = example_sketch();
        let g = Grid::new(64, sketch.extent_m).unwrap();
        let h0: Vec<f32> = (0..64 * 64).map(|i| (i % 61) as f32 * 1.5).collect();
        let path = heights_path(&dir.path().join("a.json"));
        assert_eq!(path.file_name().unwrap(), "a.refined.exr");
        let digest = write_heights(&path, &g, &h0).unwrap();
        let made = Provenance {
            exemplars: vec!["x".into()],
            params: RefineParams::default(),
        };
        let rec = record(&made, &sketch, 64, Some(digest));
        assert_eq!(load_heights(&path, &rec, &sketch, &g).unwrap(), h0);
        // Another sketch, another size, another file, no file: refused with the reason.
        let mut other = sketch.clone();
        other.seed += 1;
        assert!(
            load_heights(&path, &rec, &other, &g)
                .unwrap_err()
                .contains("changed")
        );
        let g128 = Grid::new(128, sketch.extent_m).unwrap();
        assert!(
            load_heights(&path, &rec, &sketch, &g128)
                .unwrap_err()
                .contains("size")
        );
        let mut h1 = h0.clone();
        h1[5] += 1.0;
        write_heights(&path, &g, &h1).unwrap();
        assert!(
            load_heights(&path, &rec, &sketch, &g)
                .unwrap_err()
                .contains("stale")
        );
        // Garbage and oversized files: refused with the file's name.
        std::fs::write(&path, b"v/1\x01 not an exr").unwrap();
        let e = load_heights(&path, &rec, &sketch, &g).unwrap_err();
        assert!(e.contains("a.refined.exr"), "{e}");
        std::fs::write(&path, vec![0u8; 4 * 64 * 64 + (1 << 20) + 1]).unwrap();
        let e = load_heights(&path, &rec, &sketch, &g).unwrap_err();
        assert!(e.contains("bytes"), "{e}");
        std::fs::remove_file(&path).unwrap();
        assert!(
            load_heights(&path, &rec, &sketch, &g)
                .unwrap_err()
                .contains("missing")
        );
    }
}
