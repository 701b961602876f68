//! terrasketch's realism pass: turns a smooth sketch-solved terrain into a realistic one by borrowing
//! patches of measured terrain (`refine`), with the real digital elevation models (DEMs) it reads
//! into one in-memory form, [`Dem`] (heights in metres, row 0 = north, a cell size in metres), and
//! the metrics that compare terrains.
//!
//! # How it works
//!
//! * [`load_dem`] reads any DEM or heightmap file through the raster crate's one reader
//!   ([`terrasketch_raster::read_raster`]: GeoTIFF, SRTM `.hgt`, ESRI ASCII grid, PNG16 with
//!   stretch chunks, grey and Terrarium PNG, OpenEXR, R16), which picks the format from the
//!   content, refuses hostile headers before allocating, converts geographic cell sizes to
//!   metres, flips south-up rows and fills no-data holes by a multi-resolution pull-push.
//!   [`Dem::filled_nodata`] says how many cells were filled; [`Dem::source`] keeps the file's
//!   format, no-data value and georeference.
//! * [`resample_to_cell_size`] brings exemplars of different sources to the target's cell size:
//!   area averaging along an axis that shrinks, Catmull-Rom bicubic along an axis that grows.
//! * [`load_exemplar_dir`] loads every supported file of a folder tree in name order.
//!
//! The shipped exemplar library is in `synthesis/exemplars/` (see `exemplars/NOTICE.md` for
//! sources and licences); [`shipped_exemplar_dir`] gives its path.

#![warn(missing_docs)]

pub mod features;
mod fft;
pub mod metrics;
pub mod pits;
pub mod protocol;
pub mod refine;
mod resample;
pub mod trace;
mod trace_flow;
mod trace_profile;
mod trace_rough;
#[cfg(test)]
mod trace_tests;

use std::fmt;
use std::path::{Path, PathBuf};

use rayon::prelude::*;

pub use resample::resample_to_cell_size;
pub use terrasketch_raster::{
    HorizontalUnits, MAX_CELLS, MAX_SIDE, METRES_PER_DEGREE_LAT, METRES_PER_DEGREE_LON_AT_EQUATOR,
    RasterError as DemError, ReadOptions as LoadOptions, Source as DemSource,
    SourceFormat as DemFormat, degrees_to_metres, web_mercator_cell_size_m,
};

/// A digital elevation model in memory: heights in metres on a regular grid, row 0 = north,
/// column 0 = west, row-major (`heights_m[row * width + col]`). Contains no holes: no-data cells
/// were filled when it was loaded.
#[derive(Clone)]
pub struct Dem {
    /// Number of columns (west to east).
    pub width: usize,
    /// Number of rows (north to south).
    pub height: usize,
    /// Heights in metres, `width * height` values, all finite.
    pub heights_m: Vec<f32>,
    /// Cell size in metres, `[east-west, north-south]`.
    pub cell_size_m: [f64; 2],
    /// Display name: the file name without its extension.
    pub name: String,
    /// Where the data came from and how it was stored.
    pub source: DemSource,
    /// Number of no-data cells that were filled by the pull-push fill.
    pub filled_nodata: usize,
}

impl Dem {
    /// Lowest and highest height in metres.
    pub fn height_range_m(&self) -> (f32, f32) {
        self.heights_m
            .iter()
            .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &h| {
                (lo.min(h), hi.max(h))
            })
    }

    /// Mean height in metres (computed in `f64`).
    pub fn mean_height_m(&self) -> f64 {
        let sum: f64 = self.heights_m.iter().map(|&h| f64::from(h)).sum();
        sum / self.heights_m.len().max(1) as f64
    }

    /// Height at (`col`, `row`); panics when out of range, like slice indexing.
    pub fn at(&self, col: usize, row: usize) -> f32 {
        assert!(
            col < self.width && row < self.height,
            "({col}, {row}) outside the grid"
        );
        self.heights_m[row * self.width + col]
    }
}

impl fmt::Debug for Dem {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let (lo, hi) = self.height_range_m();
        f.debug_struct("Dem")
            .field("name", &self.name)
            .field("width", &self.width)
            .field("height", &self.height)
            .field("cell_size_m", &self.cell_size_m)
            .field("height_range_m", &(lo, hi))
            .field("filled_nodata", &self.filled_nodata)
            .field("source", &self.source)
            .finish()
    }
}

impl Dem {
    /// The DEM of a raster read by [`terrasketch_raster::read_raster`], named after its file.
    pub fn from_raster(raster: terrasketch_raster::Raster) -> Dem {
        let name = raster
            .source
            .path
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default();
        let filled_nodata = raster.filled_cells();
        Dem {
            width: raster.map.width,
            height: raster.map.height,
            heights_m: raster.map.data,
            cell_size_m: raster.map.cell_size_m,
            name,
            source: raster.source,
            filled_nodata,
        }
    }
}

/// Loads a DEM file with [`terrasketch_raster::read_raster`]: format from the content (or the
/// extension for `.hgt` and `.r16`), no-data holes filled, cell size in metres. See
/// [`LoadOptions`] for what must be supplied for formats that do not carry a cell size (PNG
/// without a sidecar, plain TIFF).
pub fn load_dem(path: &Path, opts: &LoadOptions) -> Result<Dem, DemError> {
    terrasketch_raster::read_raster(path, opts).map(Dem::from_raster)
}

/// Extensions [`load_exemplar_dir`] picks up (compared case-insensitively).
pub const EXEMPLAR_EXTENSIONS: [&str; 6] = ["tif", "tiff", "hgt", "asc", "png", "exr"];

/// Loads every supported file under `dir` (sub-folders included, hidden entries skipped) with
/// default [`LoadOptions`], in path order. Returns the DEMs that loaded and, separately, each file
/// (or folder) that failed with its error; one bad file does not stop the others.
pub fn load_exemplar_dir(dir: &Path) -> (Vec<Dem>, Vec<(PathBuf, DemError)>) {
    let mut files = Vec::new();
    let mut failures = Vec::new();
    collect_files(dir, &mut files, &mut failures);
    files.sort();
    let results: Vec<_> = files
        .par_iter()
        .map(|path| load_dem(path, &LoadOptions::default()))
        .collect();
    let mut dems = Vec::new();
    for (path, result) in files.into_iter().zip(results) {
        match result {
            Ok(dem) => dems.push(dem),
            Err(err) => failures.push((path, err)),
        }
    }
    (dems, failures)
}

fn collect_files(dir: &Path, files: &mut Vec<PathBuf>, failures: &mut Vec<(PathBuf, DemError)>) {
    let entries = match std::fs::read_dir(dir) {
        Ok(entries) => entries,
        Err(err) => return failures.push((dir.to_owned(), io_error(dir, err))),
    };
    for entry in entries {
        let entry = match entry {
            Ok(entry) => entry,
            Err(err) => {
                failures.push((dir.to_owned(), io_error(dir, err)));
                continue;
            }
        };
        let path = entry.path();
        if entry.file_name().to_string_lossy().starts_with('.') {
            continue;
        }
        if path.is_dir() {
            collect_files(&path, files, failures);
        } else if path.extension().and_then(|e| e.to_str()).is_some_and(|e| {
            EXEMPLAR_EXTENSIONS
                .iter()
                .any(|known| known.eq_ignore_ascii_case(e))
        }) {
            files.push(path);
        }
    }
}

fn io_error(path: &Path, source: std::io::Error) -> DemError {
    DemError::Io {
        path: path.to_owned(),
        error: source,
    }
}

/// The exemplar library shipped in this repository (`synthesis/exemplars/`). Only meaningful when
/// running from a source checkout.
pub fn shipped_exemplar_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("exemplars")
}
