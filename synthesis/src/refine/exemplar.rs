//! Exemplars prepared for one target cell size: resampled (and cropped), with their ridge and
//! valley networks extracted once and cached on disk.

use std::io::Write;
use std::path::{Path, PathBuf};

use rayon::prelude::*;

use super::RefineError;
use super::field::{Field, downsample};
use crate::features::{FeatureKind, FeatureParams, extract_features, feature_cache_key};
use crate::{Dem, resample_to_cell_size};

/// Largest side of a prepared exemplar, in target cells: larger DEMs are cropped around their
/// centre before resampling, so that a coarse DEM brought to a fine target stays in memory and
/// matching time stays bounded.
pub const MAX_EXEMPLAR_SIDE: usize = 1024;
/// Largest side of an exemplar's coarser pyramid levels (in that level's cells): the coarse
/// levels of the synthesis are at most half the target's side, so this still offers several
/// times the level's area while bounding the per-level setup.
pub const MAX_COARSE_EXEMPLAR_SIDE: usize = 512;
/// Coarser levels prepared per exemplar (cell sizes 2, 4, ... 2^this times the target's).
pub const PYRAMID_LEVELS: usize = 4;
/// Features are extracted on a grid this many times coarser than the target cells (both target
/// and exemplars), so ridges are found at the scale patches are placed at.
pub const FEATURE_FACTOR: usize = 4;
/// Version of the cache file layout and of the extraction recipe (part of the key).
const CACHE_VERSION: &[u8; 8] = b"TSFEAT02";

/// One polyline of a feature network, in the prepared exemplar's (or target's) cells.
#[derive(Clone, Debug, PartialEq)]
pub struct FeatureLine {
    /// Ridge or valley.
    pub kind: FeatureKind,
    /// Points `[x = column, y = row]` in full-resolution cells.
    pub points: Vec<[f32; 2]>,
}

/// An exemplar ready for matching.
#[derive(Clone, Debug)]
pub struct PreparedExemplar {
    /// The DEM's name.
    pub name: String,
    /// The file it came from.
    pub path: PathBuf,
    /// Heights at the target cell size (row 0 = north).
    pub heights: Field,
    /// Square cell size in metres (the target's).
    pub cell_size_m: f64,
    /// The source DEM's own (smaller) cell side in metres: the finest scale its heights measure.
    pub native_cell_m: f64,
    /// Ridge and valley polylines.
    pub features: Vec<FeatureLine>,
    /// Heights at `2^j` times the target cell size (`levels[j - 1]`, `j` = 1 ..=
    /// [`PYRAMID_LEVELS`]), each resampled from the source DEM and cropped around its centre to
    /// at most [`MAX_COARSE_EXEMPLAR_SIDE`] cells, so coarse levels see more of the DEM than
    /// the fine crop holds.
    pub levels: Vec<Field>,
    /// Slope histogram of `heights` (1-degree bins, fractions).
    pub slope_histogram: Vec<f64>,
    /// Pits deeper than [`super::PIT_MIN_DEPTH_M`] in `heights` (cached with the features).
    pub pits_deep: usize,
    /// Whether the features were read from the cache (true) or extracted now.
    pub features_from_cache: bool,
    /// A cache problem that did not stop the preparation (unreadable, corrupt, not writable).
    pub cache_warning: Option<String>,
    /// Problems of the exemplar itself for this target: brought more than
    /// [`MAX_UPSAMPLING`] times finer (its detail at the target's scale is invented by
    /// interpolation), or flat (it gives no detail).
    pub warnings: Vec<String>,
}

impl PreparedExemplar {
    /// The exemplar's name, paths, statistics and warnings, without its height fields and
    /// feature network (for the coarse levels, which bring their own heights).
    pub(super) fn clone_meta(&self) -> PreparedExemplar {
        PreparedExemplar {
            name: self.name.clone(),
            path: self.path.clone(),
            heights: Field::new(0, 0, Vec::new()),
            cell_size_m: self.cell_size_m,
            native_cell_m: self.native_cell_m,
            features: Vec::new(),
            levels: Vec::new(),
            slope_histogram: self.slope_histogram.clone(),
            pits_deep: self.pits_deep,
            features_from_cache: self.features_from_cache,
            cache_warning: self.cache_warning.clone(),
            warnings: self.warnings.clone(),
        }
    }
}

/// Exemplars resampled to cells more than this many times finer than their own get a warning.
pub const MAX_UPSAMPLING: f64 = 4.0;
/// Exemplars whose height range is under this (metres) are flat and get a warning.
const FLAT_RELIEF_M: f32 = 1.0;

/// The warnings of [`PreparedExemplar::warnings`].
fn exemplar_warnings(dem: &Dem, heights: &Field, cell_size_m: f64) -> Vec<String> {
    let mut out = Vec::new();
    let native = dem.cell_size_m[0].min(dem.cell_size_m[1]);
    if native > MAX_UPSAMPLING * cell_size_m {
        out.push(format!(
            "exemplar {} has {native:.1} m cells, {:.1} times coarser than the target's \
             {cell_size_m:.1} m: its detail at this scale is interpolated, not measured",
            dem.name,
            native / cell_size_m
        ));
    }
    let (lo, hi) = heights
        .v
        .iter()
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), &v| {
            (a.min(v), b.max(v))
        });
    if hi - lo < FLAT_RELIEF_M {
        out.push(format!(
            "exemplar {} is flat ({:.2} m of relief): it adds no detail",
            dem.name,
            (hi - lo).max(0.0)
        ));
    }
    out
}

/// Ridge and valley polylines of a heightmap at the feature scale, in full-resolution cells.
pub fn extract_lines(heights: &Field, cell_size_m: f64) -> Vec<FeatureLine> {
    let coarse = downsample(heights, FEATURE_FACTOR);
    let cell = cell_size_m * FEATURE_FACTOR as f64;
    let params = FeatureParams::default();
    let f = FEATURE_FACTOR as f32;
    [FeatureKind::Ridge, FeatureKind::Valley]
        .par_iter()
        .map(|&kind| {
            let net = extract_features(&coarse.v, coarse.w, coarse.h, [cell; 2], kind, &params);
            net.polylines
                .into_iter()
                .map(|pl| FeatureLine {
                    kind,
                    points: pl
                        .into_iter()
                        .map(|[x, y]| [(x + 0.5) * f - 0.5, (y + 0.5) * f - 0.5])
                        .collect(),
                })
                .collect::<Vec<_>>()
        })
        .collect::<Vec<_>>()
        .into_iter()
        .flatten()
        .collect()
}

/// Crops `dem` around its centre so that, resampled to `cell_size_m`, it has at most
/// [`MAX_EXEMPLAR_SIDE`] cells a side.
fn crop_for(dem: &Dem, cell_size_m: f64, max_side: usize) -> Dem {
    let keep = |n: usize, c: f64| -> usize {
        let max_src = (max_side as f64 * cell_size_m / c).floor() as usize;
        n.min(max_src.max(8))
    };
    let (w, h) = (
        keep(dem.width, dem.cell_size_m[0]),
        keep(dem.height, dem.cell_size_m[1]),
    );
    if w == dem.width && h == dem.height {
        return dem.clone();
    }
    let (x0, y0) = ((dem.width - w) / 2, (dem.height - h) / 2);
    let mut heights_m = Vec::with_capacity(w * h);
    for y in y0..y0 + h {
        heights_m.extend_from_slice(&dem.heights_m[y * dem.width + x0..y * dem.width + x0 + w]);
    }
    Dem {
        width: w,
        height: h,
        heights_m,
        ..dem.clone()
    }
}

/// Resamples each DEM to `cell_size_m` (cropping large ones, see [`MAX_EXEMPLAR_SIDE`]) and
/// extracts its ridge/valley network, or reads it from `cache_dir` when a valid cache file for
/// the same heights, cell size and extraction parameters exists. Cache files are written
/// atomically (temporary file + rename); a corrupt one is recomputed and replaced.
pub fn prepare_exemplars(
    dems: &[Dem],
    cell_size_m: f64,
    cache_dir: Option<&Path>,
    progress: &(dyn Fn(f32, &str) + Sync),
) -> Result<Vec<PreparedExemplar>, RefineError> {
    if !(cell_size_m.is_finite() && cell_size_m > 0.0) {
        return Err(RefineError::BadInput(format!(
            "cell size {cell_size_m} m is not positive"
        )));
    }
    if dems.is_empty() {
        return Err(RefineError::NoExemplars);
    }
    let mut out = Vec::with_capacity(dems.len());
    for (i, dem) in dems.iter().enumerate() {
        progress(
            i as f32 / dems.len() as f32,
            &format!("preparing exemplar {}", dem.name),
        );
        let cropped = crop_for(dem, cell_size_m, MAX_EXEMPLAR_SIDE);
        let r = resample_to_cell_size(&cropped, cell_size_m)?;
        let levels = (1..=PYRAMID_LEVELS)
            .into_par_iter()
            .map(|j| {
                let c = cell_size_m * (1u64 << j) as f64;
                let r = resample_to_cell_size(&crop_for(dem, c, MAX_COARSE_EXEMPLAR_SIDE), c)?;
                Ok(Field::new(r.width, r.height, r.heights_m))
            })
            .collect::<Result<Vec<Field>, crate::DemError>>()?;
        let heights = Field::new(r.width, r.height, r.heights_m);
        let key = cache_key(dem, &heights, cell_size_m);
        let mut warning = None;
        let cached = cache_dir.and_then(|d| match read_cache(&d.join(&key)) {
            Ok(lines) => lines,
            Err(e) => {
                warning = Some(e);
                None
            }
        });
        let from_cache = cached.is_some();
        let (features, pits_deep) = match cached {
            Some(c) => c,
            None => {
                let (lines, pits) = rayon::join(
                    || extract_lines(&heights, cell_size_m),
                    || {
                        crate::pits::count_pits(
                            &heights.v,
                            heights.w,
                            heights.h,
                            None,
                            super::PIT_MIN_DEPTH_M,
                        )
                    },
                );
                if let Some(d) = cache_dir
                    && let Err(e) = write_cache(d, &key, &lines, pits)
                {
                    warning = Some(format!(
                        "cannot write feature cache in {}: {e}",
                        d.display()
                    ));
                }
                (lines, pits)
            }
        };
        let slope_histogram = super::slope_hist(&heights.v, heights.w, heights.h, cell_size_m);
        let warnings = exemplar_warnings(dem, &heights, cell_size_m);
        out.push(PreparedExemplar {
            warnings,
            slope_histogram,
            name: dem.name.clone(),
            path: dem.source.path.clone(),
            heights,
            cell_size_m,
            native_cell_m: dem.cell_size_m[0].min(dem.cell_size_m[1]),
            features,
            levels,
            pits_deep,
            features_from_cache: from_cache,
            cache_warning: warning,
        });
    }
    progress(1.0, "exemplars ready");
    Ok(out)
}

/// File name of the cache entry: the crate's feature key over the prepared heights, plus the
/// layout version and the feature factor.
fn cache_key(dem: &Dem, heights: &Field, cell_size_m: f64) -> String {
    let prepared = Dem {
        width: heights.w,
        height: heights.h,
        heights_m: heights.v.clone(),
        cell_size_m: [cell_size_m; 2],
        ..dem.clone()
    };
    let key = feature_cache_key(&prepared, &FeatureParams::default());
    format!("{key}-f{FEATURE_FACTOR}-v2.tsfeat")
}

fn fnv(bytes: &[u8]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for &b in bytes {
        h ^= u64::from(b);
        h = h.wrapping_mul(0x0100_0000_01b3);
    }
    h
}

fn encode(lines: &[FeatureLine], pits: usize) -> Vec<u8> {
    let mut b = CACHE_VERSION.to_vec();
    b.extend_from_slice(&(pits as u64).to_le_bytes());
    b.extend_from_slice(&(lines.len() as u64).to_le_bytes());
    for l in lines {
        b.push(u8::from(l.kind == FeatureKind::Valley));
        b.extend_from_slice(&(l.points.len() as u64).to_le_bytes());
        for p in &l.points {
            b.extend_from_slice(&p[0].to_le_bytes());
            b.extend_from_slice(&p[1].to_le_bytes());
        }
    }
    let sum = fnv(&b);
    b.extend_from_slice(&sum.to_le_bytes());
    b
}

/// Reads a cache file: `Ok(None)` if absent, `Err` (a message) if present but unusable.
fn read_cache(path: &Path) -> Result<Option<(Vec<FeatureLine>, usize)>, String> {
    let bytes = match std::fs::read(path) {
        Ok(b) => b,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(e) => return Err(format!("cannot read {}: {e}", path.display())),
    };
    decode(&bytes)
        .map(Some)
        .ok_or_else(|| format!("{} is corrupt; features re-extracted", path.display()))
}

fn decode(bytes: &[u8]) -> Option<(Vec<FeatureLine>, usize)> {
    let body_len = bytes.len().checked_sub(8)?;
    let (body, sum) = bytes.split_at(body_len);
    if fnv(body) != u64::from_le_bytes(sum.try_into().ok()?) || !body.starts_with(CACHE_VERSION) {
        return None;
    }
    let mut at = CACHE_VERSION.len();
    let mut take = |n: usize| -> Option<&[u8]> {
        let s = body.get(at..at.checked_add(n)?)?;
        at += n;
        Some(s)
    };
    let pits = u64::from_le_bytes(take(8)?.try_into().ok()?) as usize;
    let count = u64::from_le_bytes(take(8)?.try_into().ok()?) as usize;
    let mut lines = Vec::with_capacity(count.min(body.len() / 9));
    for _ in 0..count {
        let kind = match take(1)?[0] {
            0 => FeatureKind::Ridge,
            1 => FeatureKind::Valley,
            _ => return None,
        };
        let n = u64::from_le_bytes(take(8)?.try_into().ok()?) as usize;
        let raw = take(n.checked_mul(8)?)?;
        let points = raw
            .chunks_exact(8)
            .map(|c| {
                [
                    f32::from_le_bytes([c[0], c[1], c[2], c[3]]),
                    f32::from_le_bytes([c[4], c[5], c[6], c[7]]),
                ]
            })
            .collect::<Vec<_>>();
        if points.iter().flatten().any(|v| !v.is_finite()) {
            return None;
        }
        lines.push(FeatureLine { kind, points });
    }
    (at == body.len()).then_some((lines, pits))
}

fn write_cache(dir: &Path, key: &str, lines: &[FeatureLine], pits: usize) -> std::io::Result<()> {
    std::fs::create_dir_all(dir)?;
    let tmp = dir.join(format!(".{key}.{}.tmp", std::process::id()));
    let result = (|| {
        let mut f = std::fs::File::create(&tmp)?;
        f.write_all(&encode(lines, pits))?;
        f.sync_all()?;
        std::fs::rename(&tmp, dir.join(key))
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cache_round_trip_and_corruption() {
        let lines = vec![
            FeatureLine {
                kind: FeatureKind::Ridge,
                points: vec![[1.0, 2.0], [3.5, 4.0]],
            },
            FeatureLine {
                kind: FeatureKind::Valley,
                points: vec![[0.0, 0.0]],
            },
        ];
        let bytes = encode(&lines, 7);
        assert_eq!(decode(&bytes), Some((lines, 7)));
        for i in [0, 9, bytes.len() / 2, bytes.len() - 1] {
            let mut bad = bytes.clone();
            bad[i] ^= 0x40;
            assert_eq!(decode(&bad), None, "flip at {i}");
        }
        assert_eq!(decode(&bytes[..bytes.len() - 3]), None);
        assert_eq!(decode(&[]), None);
    }
}
