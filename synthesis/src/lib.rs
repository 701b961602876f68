//! terrasketch's realism pass: turns a smooth sketch-solved terrain into a realistic one by borrowing
//! patches of measured terrain (`refine`), with the real digital elevation models (DEMs) it reads
//! into one in-memory form, [`Dem`] (heights in metres, row 0 = north, a cell size in metres), and
//! the metrics that compare terrains.
//!
//! # How it works
//!
//! * [`load_dem`] picks a reader from the file's first bytes (TIFF and PNG signatures, an ESRI
//!   ASCII header) and falls back to the extension (`.hgt` has no signature). Readers:
//!   GeoTIFF (`geotiff.rs`, via the `tiff` crate), SRTM `.hgt` (`hgt.rs`), ESRI ASCII grid
//!   (`asc.rs`), 16-bit grey and Terrarium RGB PNG (`png_dem.rs`, via the `png` crate).
//! * Each reader checks the grid size against [`MAX_SIDE`] and [`MAX_CELLS`] before it allocates the
//!   grid, so a hostile header cannot make us reserve gigabytes; truncated or corrupt files give a
//!   [`DemError`], never a panic.
//! * Horizontal units: a geographic grid (degrees) is converted to metres at the grid's centre
//!   latitude ([`degrees_to_metres`]). Rows stored south-up are flipped to north-up.
//! * No-data cells (the file's no-data value, SRTM voids, non-finite values) are filled by a
//!   multi-resolution pull-push (`fill.rs`): a pyramid of averages of valid cells is built, then
//!   pushed back down with bilinear interpolation, so holes get smooth values that blend into their
//!   rims. [`Dem::filled_nodata`] says how many cells were filled.
//! * [`resample_to_cell_size`] brings exemplars of different sources to the target's cell size:
//!   area averaging along an axis that shrinks, Catmull-Rom bicubic along an axis that grows.
//! * [`load_exemplar_dir`] loads every supported file of a folder tree in name order.
//!
//! The shipped exemplar library is in `synthesis/exemplars/` (see `exemplars/NOTICE.md` for
//! sources and licences); [`shipped_exemplar_dir`] gives its path.

#![warn(missing_docs)]

mod asc;
pub mod features;
mod fft;
mod fill;
mod geotiff;
mod hgt;
pub mod metrics;
pub mod pits;
mod png_dem;
pub mod protocol;
pub mod refine;
mod resample;
pub mod trace;
mod trace_flow;
mod trace_profile;
#[cfg(test)]
mod trace_tests;

use std::fmt;
use std::io::Read;
use std::path::{Path, PathBuf};

use rayon::prelude::*;

pub use png_dem::web_mercator_cell_size_m;
pub use resample::resample_to_cell_size;

/// Largest accepted grid side, in cells. Larger headers are refused before anything is allocated.
pub const MAX_SIDE: usize = 65_536;
/// Largest accepted number of cells (2^28: 1 GiB of `f32`). Larger grids are refused before
/// anything is allocated.
pub const MAX_CELLS: usize = 1 << 28;
/// Metres per degree of latitude used to convert geographic grids (the equatorial value).
pub const METRES_PER_DEGREE_LAT: f64 = 110_574.0;
/// Metres per degree of longitude at the equator; multiplied by cos(latitude) elsewhere.
pub const METRES_PER_DEGREE_LON_AT_EQUATOR: f64 = 111_320.0;

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

/// The file format a [`Dem`] was read from.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum DemFormat {
    /// GeoTIFF, striped or tiled.
    GeoTiff {
        /// Compression as named in the TIFF specification ("none", "LZW", "deflate", ...).
        compression: &'static str,
        /// Whether the image is stored in tiles (else in strips).
        tiled: bool,
        /// Whether a horizontal differencing predictor was undone.
        predictor: bool,
    },
    /// SRTM `.hgt`: raw big-endian `i16`, 1201 or 3601 cells square.
    SrtmHgt,
    /// ESRI ASCII grid (`.asc`).
    EsriAsciiGrid,
    /// Grey PNG (8 or 16 bit) whose values are heights, with a cell size given separately.
    GreyPng,
    /// Terrarium RGB PNG: `h = R * 256 + G + B / 256 - 32768`.
    TerrariumPng,
}

/// Horizontal units of a grid's georeference.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum HorizontalUnits {
    /// Metres (projected coordinates).
    #[default]
    Metres,
    /// Degrees of longitude and latitude (geographic coordinates).
    Degrees,
}

/// Where a [`Dem`] came from and how the file described it.
#[derive(Clone, Debug, PartialEq)]
pub struct DemSource {
    /// The file that was read.
    pub path: PathBuf,
    /// Its format.
    pub format: DemFormat,
    /// How one sample is stored, e.g. "int16", "float32", "rgb8".
    pub sample_type: &'static str,
    /// Units of the file's own cell size.
    pub horizontal_units: HorizontalUnits,
    /// The file's own cell size `[x, y]` in `horizontal_units` (before conversion to metres).
    pub native_cell_size: [f64; 2],
    /// Latitude of the grid's centre in degrees, when the file gives it.
    pub centre_lat_deg: Option<f64>,
    /// The no-data value the file declared (or the format implies), if any.
    pub nodata: Option<f64>,
    /// True if the file stored rows south-up and they were flipped to north-up.
    pub rows_flipped: bool,
    /// Guesses made while reading, for the application to show (e.g. "no CRS, assumed degrees").
    pub warnings: Vec<String>,
}

/// Options for [`load_dem`]. `LoadOptions::default()` suits every self-describing file.
#[derive(Clone, Debug)]
pub struct LoadOptions {
    /// Square cell size in metres. Required where the file gives none: PNGs without a sidecar
    /// `NAME.json`, TIFFs without georeference tags, `.hgt` files not named after their corner.
    /// When set it overrides the cell size of every format.
    pub cell_size_m: Option<f64>,
    /// Decode an RGB PNG as Terrarium even if its name does not contain "terrarium".
    pub terrarium: bool,
    /// Units of an ESRI ASCII grid's `cellsize` (the format does not say).
    pub asc_units: HorizontalUnits,
    /// Metres per grey level of a grey PNG: `h = png_offset_m + png_metres_per_level * value`.
    pub png_metres_per_level: f64,
    /// Height in metres of grey level 0 of a grey PNG.
    pub png_offset_m: f64,
}

impl Default for LoadOptions {
    fn default() -> Self {
        Self {
            cell_size_m: None,
            terrarium: false,
            asc_units: HorizontalUnits::Metres,
            png_metres_per_level: 1.0,
            png_offset_m: 0.0,
        }
    }
}

/// Everything that can go wrong while loading or resampling a DEM.
#[derive(Debug, thiserror::Error)]
pub enum DemError {
    /// The file could not be opened or read.
    #[error("cannot read {path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The operating system's error.
        source: std::io::Error,
    },
    /// Neither the content nor the extension names a supported format.
    #[error("{path}: not a supported DEM file (.tif, .tiff, .hgt, .asc, .png)")]
    UnknownFormat {
        /// The file.
        path: PathBuf,
    },
    /// The file is truncated, corrupt or inconsistent.
    #[error("{path}: malformed file: {reason}")]
    Malformed {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
    /// The file is valid but uses something this crate does not read (e.g. an RGB TIFF).
    #[error("{path}: unsupported: {reason}")]
    Unsupported {
        /// The file.
        path: PathBuf,
        /// What is not supported.
        reason: String,
    },
    /// The grid is larger than [`MAX_SIDE`] or [`MAX_CELLS`]; refused before allocation.
    #[error(
        "{what}: {width}x{height} cells is over the limit ({MAX_SIDE} a side, {MAX_CELLS} cells)"
    )]
    TooLarge {
        /// The file, or what was being made.
        what: String,
        /// Requested columns.
        width: u64,
        /// Requested rows.
        height: u64,
    },
    /// The format carries no cell size and none was given.
    #[error(
        "{path}: the file gives no cell size: set LoadOptions::cell_size_m, or for a PNG add a sidecar {} with {{\"cell_size_m\": ...}}",
        path.with_extension("json").display()
    )]
    MissingCellSize {
        /// The file.
        path: PathBuf,
    },
    /// Every cell is no-data, so there is nothing to fill holes from.
    #[error("{path}: every cell is no-data")]
    AllNoData {
        /// The file.
        path: PathBuf,
    },
    /// A cell size is zero, negative or not finite.
    #[error("invalid cell size {cell_size_m:?} m")]
    InvalidCellSize {
        /// The offending cell size in metres.
        cell_size_m: [f64; 2],
    },
}

impl DemError {
    pub(crate) fn malformed(path: &Path, reason: impl Into<String>) -> Self {
        Self::Malformed {
            path: path.to_owned(),
            reason: reason.into(),
        }
    }

    pub(crate) fn unsupported(path: &Path, reason: impl Into<String>) -> Self {
        Self::Unsupported {
            path: path.to_owned(),
            reason: reason.into(),
        }
    }

    pub(crate) fn io(path: &Path, source: std::io::Error) -> Self {
        if source.kind() == std::io::ErrorKind::UnexpectedEof {
            return Self::malformed(path, "file is truncated");
        }
        Self::Io {
            path: path.to_owned(),
            source,
        }
    }
}

/// Refuses grids over [`MAX_SIDE`] / [`MAX_CELLS`] (and empty ones) before anything is allocated.
pub(crate) fn check_grid_size(what: &Path, width: u64, height: u64) -> Result<(), DemError> {
    check_grid_size_named(&what.display().to_string(), width, height)?;
    if width == 0 || height == 0 {
        return Err(DemError::malformed(
            what,
            format!("empty grid {width}x{height}"),
        ));
    }
    Ok(())
}

pub(crate) fn check_grid_size_named(what: &str, width: u64, height: u64) -> Result<(), DemError> {
    let cells = u128::from(width) * u128::from(height);
    if width > MAX_SIDE as u64 || height > MAX_SIDE as u64 || cells > MAX_CELLS as u128 {
        return Err(DemError::TooLarge {
            what: what.to_owned(),
            width,
            height,
        });
    }
    Ok(())
}

/// Converts a cell size in degrees `[lon, lat]` to metres at latitude `lat_deg`:
/// x = lon * cos(lat) * 111 320 m, y = lat * 110 574 m.
pub fn degrees_to_metres(cell_deg: [f64; 2], lat_deg: f64) -> [f64; 2] {
    [
        cell_deg[0] * lat_deg.to_radians().cos() * METRES_PER_DEGREE_LON_AT_EQUATOR,
        cell_deg[1] * METRES_PER_DEGREE_LAT,
    ]
}

/// What a reader hands back: raw heights with holes, before filling.
pub(crate) struct RawGrid {
    pub width: usize,
    pub height: usize,
    /// Row 0 = north. Holes are NaN.
    pub heights_m: Vec<f32>,
    pub cell_size_m: [f64; 2],
    pub source: DemSource,
}

/// Loads a DEM file, fills its no-data holes and converts its cell size to metres.
///
/// The format is recognised from the content (TIFF, PNG, ESRI ASCII header) and, for `.hgt`,
/// from the extension. See [`LoadOptions`] for what must be supplied for formats that do not carry
/// a cell size (PNG).
pub fn load_dem(path: &Path, opts: &LoadOptions) -> Result<Dem, DemError> {
    let mut magic = [0u8; 8];
    let magic_len = {
        let mut file = std::fs::File::open(path).map_err(|e| DemError::io(path, e))?;
        read_up_to(&mut file, &mut magic).map_err(|e| DemError::io(path, e))?
    };
    let magic = &magic[..magic_len];
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .unwrap_or_default();
    let raw = if magic.starts_with(b"II*\0") || magic.starts_with(b"MM\0*") {
        geotiff::read(path, opts.cell_size_m.is_some())?
    } else if magic.starts_with(b"\x89PNG\r\n\x1a\n") {
        png_dem::read(path, opts)?
    } else if asc::looks_like_header(magic) {
        asc::read(path, opts)?
    } else if ext == "hgt" {
        hgt::read(path, opts.cell_size_m.is_some())?
    } else if matches!(ext.as_str(), "tif" | "tiff" | "png" | "asc") {
        return Err(DemError::malformed(
            path,
            format!("content is not a .{ext} file"),
        ));
    } else {
        return Err(DemError::UnknownFormat {
            path: path.to_owned(),
        });
    };
    finish(path, raw, opts)
}

fn read_up_to(reader: &mut impl Read, buf: &mut [u8]) -> std::io::Result<usize> {
    let mut filled = 0;
    while filled < buf.len() {
        match reader.read(&mut buf[filled..])? {
            0 => break,
            n => filled += n,
        }
    }
    Ok(filled)
}

/// Applies the cell-size override, fills holes and names the result.
fn finish(path: &Path, mut raw: RawGrid, opts: &LoadOptions) -> Result<Dem, DemError> {
    if let Some(cell) = opts.cell_size_m {
        raw.cell_size_m = [cell, cell];
    }
    let cell = raw.cell_size_m;
    if !cell.iter().all(|c| c.is_finite() && *c > 0.0) {
        return Err(DemError::InvalidCellSize { cell_size_m: cell });
    }
    let filled_nodata =
        fill::fill_holes(raw.width, raw.height, &mut raw.heights_m).ok_or_else(|| {
            DemError::AllNoData {
                path: path.to_owned(),
            }
        })?;
    let name = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    Ok(Dem {
        width: raw.width,
        height: raw.height,
        heights_m: raw.heights_m,
        cell_size_m: cell,
        name,
        source: raw.source,
        filled_nodata,
    })
}

/// Extensions [`load_exemplar_dir`] picks up (compared case-insensitively).
pub const EXEMPLAR_EXTENSIONS: [&str; 5] = ["tif", "tiff", "hgt", "asc", "png"];

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
        Err(err) => return failures.push((dir.to_owned(), DemError::io(dir, err))),
    };
    for entry in entries {
        let entry = match entry {
            Ok(entry) => entry,
            Err(err) => {
                failures.push((dir.to_owned(), DemError::io(dir, err)));
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

/// The exemplar library shipped in this repository (`synthesis/exemplars/`). Only meaningful when
/// running from a source checkout.
pub fn shipped_exemplar_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("exemplars")
}
