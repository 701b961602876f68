//! Reading and writing heightmap rasters: OpenEXR, GeoTIFF, 16-bit PNG and raw R16.
//!
//! # How it works
//!
//! A [`Heightmap`] is a north-up, row-major grid of `f32` heights in metres plus the cell size.
//! The path's extension picks the [`Format`]. Float formats (EXR, TIFF) round-trip exactly;
//! 16-bit formats (PNG, R16) store codes of a [`Stretch`] over the data's `[min, max]`.
//!
//! - **Writing** validates first (shape, size limits, finite samples, cell size), encodes into
//!   memory ([`encode_heightmap`], usable from any thread), then replaces the target
//!   atomically: temporary file `.NAME.tmp-PID-N` next to it, fsync, rename. A failed write
//!   leaves the target untouched and no temporary file behind.
//! - **Reading** treats the file as hostile: header dimensions are checked against
//!   [`MAX_SIDE`], a 4 GiB sample budget and the file's length before any pixel buffer exists;
//!   the decoders' own limits are set; truncation and corruption are errors, never panics or
//!   silently zeroed pixels. The decoded map must then pass [`check_bounds`] (heights within
//!   +-100 km, cells from 1 cm, extent up to 40,000 km).
//!
//! | Format | Extension | Samples | Metadata |
//! |---|---|---|---|
//! | [`Format::Exr`] | `.exr` | `f32`, channel `Y` (reads `height`, `Y` or a lone channel; any compression) | cell size in a text attribute |
//! | [`Format::Tiff`] | `.tif`, `.tiff` | `f32` (reads `f32`/`f64`/`u16`/`i16`/`u8`) | GeoTIFF pixel scale, tie point, keys |
//! | [`Format::Png16`] | `.png` | 16-bit grey codes | stretch and cell size in `tEXt` chunks |
//! | [`Format::R16`] | `.r16` | 16-bit little-endian codes | none: the caller keeps the stretch |

mod asc_file;
mod atomic;
mod checks;
mod error;
mod exr_file;
mod fill;
mod format;
mod georef;
mod hgt_file;
mod png_file;
mod r16_file;
mod read;
mod resample;
mod source;
mod stretch;
mod tiff_file;

use std::fs::File;
use std::io::BufReader;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::Path;

pub use checks::{
    MAX_ABS_HEIGHT_M, MAX_CELLS, MAX_EXTENT_M, MAX_SIDE, MIN_CELL_SIZE_M, check_bounds,
};
pub use error::RasterError;
pub use format::Format;
pub use georef::{Georef, Transform};
pub use read::read_raster;
pub use resample::{Sampling, resample_cells};
pub use source::{
    HorizontalUnits, METRES_PER_DEGREE_LAT, METRES_PER_DEGREE_LON_AT_EQUATOR, Raster, ReadOptions,
    Source, SourceFormat, degrees_to_metres, web_mercator_cell_size_m,
};
pub use stretch::Stretch;

/// A heightmap in metres: row 0 is the NORTH edge (north-up), rows are stored one after the
/// other (row-major), `width` columns by `height` rows.
#[derive(Debug, Clone, PartialEq)]
pub struct Heightmap {
    /// Number of columns (west to east).
    pub width: usize,
    /// Number of rows (north to south).
    pub height: usize,
    /// Heights in metres, `data[row * width + column]`; `width * height` samples.
    pub data: Vec<f32>,
    /// Size of one cell in metres, `[east-west, north-south]`.
    pub cell_size_m: [f64; 2],
}

/// What [`write_heightmap`] wrote.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WriteInfo {
    /// The format chosen from the extension.
    pub format: Format,
    /// The stretch of 16-bit formats (PNG, R16), `None` for float formats. R16 files do not
    /// store it, so the caller must keep it (the CLI prints it).
    pub stretch: Option<Stretch>,
}

/// Writes `map` to `path` atomically in the format its extension names.
///
/// Fails without touching the target on an unsupported extension, a bad shape, an oversized
/// map, a non-finite sample ([`RasterError::NonFinite`] names the first), an unusable cell size,
/// or any I/O error ([`RasterError::Io`] with `path`, e.g. a missing directory).
pub fn write_heightmap(path: &Path, map: &Heightmap) -> Result<WriteInfo, RasterError> {
    write_heightmap_with(path, map, &WriteOptions::default())
}

/// How [`write_heightmap_with`] writes: where the samples sit, which 16-bit stretch to use, and
/// the georeference and no-data value a GeoTIFF keeps.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct WriteOptions<'a> {
    /// Sample placement: [`Sampling::Cells`] (the default) or [`Sampling::Corners`]; GeoTIFF's
    /// tie point follows it, the other formats do not record it.
    pub sampling: Sampling,
    /// The stretch of 16-bit formats; `None` covers the map's own `[min, max]`. Tiles of one
    /// world pass the world's stretch so that equal heights get equal codes.
    pub stretch: Option<Stretch>,
    /// Model position, metres, of the raster's south-west corner (cell-centred: the outer corner
    /// of its south-west cell; corner-sampled: its south-west sample); GeoTIFF's tie point
    /// follows it, so a tile of a world keeps its place. `[0, 0]` by default.
    pub origin_m: [f64; 2],
    /// A GeoTIFF's georeference (CRS and transform) for the map as given, written verbatim in
    /// place of the local metric frame (sampling and origin are then unused); other formats
    /// cannot store it and ignore it.
    pub georef: Option<&'a Georef>,
    /// A GeoTIFF's `GDAL_NODATA` value (other formats ignore it); samples equal to it are
    /// no-data to GIS readers.
    pub nodata: Option<f64>,
}

/// [`write_heightmap`] with [`WriteOptions`].
pub fn write_heightmap_with(
    path: &Path,
    map: &Heightmap,
    options: &WriteOptions,
) -> Result<WriteInfo, RasterError> {
    let format = Format::from_path(path)?;
    let (bytes, stretch) = encode_heightmap_with(format, map, options)?;
    atomic::write_atomically(path, &bytes)?;
    Ok(WriteInfo { format, stretch })
}

/// Encodes `map` as the bytes of a `format` file, in memory (no file system access), and
/// returns the stretch used by 16-bit formats. Validates the map like [`write_heightmap`].
pub fn encode_heightmap(
    format: Format,
    map: &Heightmap,
) -> Result<(Vec<u8>, Option<Stretch>), RasterError> {
    encode_heightmap_with(format, map, &WriteOptions::default())
}

/// [`encode_heightmap`] with [`WriteOptions`]; a given stretch must be finite with
/// `min_m <= max_m` (heights outside it get the end codes).
pub fn encode_heightmap_with(
    format: Format,
    map: &Heightmap,
    options: &WriteOptions,
) -> Result<(Vec<u8>, Option<Stretch>), RasterError> {
    checks::check_writable(map)?;
    let stretch = match options.stretch {
        Some(s) if !s.is_valid() => {
            return Err(RasterError::encode(format!(
                "stretch {} .. {} m is not a finite increasing range",
                s.min_m, s.max_m
            )));
        }
        Some(s) => s,
        None => Stretch::covering(&map.data),
    };
    if let Some(nodata) = options.nodata.filter(|v| !v.is_finite()) {
        return Err(RasterError::encode(format!(
            "no-data value {nodata} is not finite"
        )));
    }
    match format {
        Format::Exr => Ok((exr_file::encode(map)?, None)),
        Format::Tiff => Ok((tiff_file::encode(map, options)?, None)),
        Format::Png16 => Ok((png_file::encode(map, stretch)?, Some(stretch))),
        Format::R16 => Ok((r16_file::encode(map, stretch), Some(stretch))),
    }
}

/// Replaces the file at `path` with `bytes` atomically (temporary file in the same folder,
/// fsync, rename), for the side files of an export (manifests, meshes, masks).
pub fn write_file_atomically(path: &Path, bytes: &[u8]) -> Result<(), RasterError> {
    atomic::write_atomically(path, bytes)
}

/// Writes an 8-bit greyscale PNG of `width x height` bytes (row-major, north-up) atomically, for
/// pictures such as a hillshade.
pub fn write_grey8_png(
    path: &Path,
    width: usize,
    height: usize,
    pixels: &[u8],
) -> Result<(), RasterError> {
    checks::check_size(width as u64, height as u64)?;
    if width == 0 || height == 0 || width.checked_mul(height) != Some(pixels.len()) {
        return Err(RasterError::BadShape {
            width,
            height,
            len: pixels.len(),
        });
    }
    let bytes = png_file::encode_grey8(width, height, pixels)?;
    atomic::write_atomically(path, &bytes)
}

/// Reads the heightmap at `path` with [`read_raster`] and keeps the heights and cell size. A
/// file that gives no cell size reads with 1 m cells, as terrasketch's own headerless outputs
/// do.
///
/// - EXR and TIFF give heights as stored (GeoTIFF in metres, any CRS; no-data cells filled).
/// - PNG gives metres when the `terrasketch:*` text chunks are present, else raw code values
///   (`0..=65535` for 16-bit files).
/// - R16 has no header: the file must be a square of `sqrt(bytes / 2)` per side and gives raw
///   code values; use [`read_r16`] for other shapes or to apply a stretch.
/// - SRTM `.hgt` and ESRI ASCII grids read as in [`read_raster`].
///
/// Every map read is checked by [`check_bounds`]: heights finite and within +-100 km, cells of
/// 1 cm or more, an extent of at most 40,000 km ([`RasterError::OutOfBounds`] names the field).
pub fn read_heightmap(path: &Path) -> Result<Heightmap, RasterError> {
    let options = ReadOptions {
        unit_cells_when_absent: true,
        ..ReadOptions::default()
    };
    Ok(read_raster(path, &options)?.map)
}

/// Reads a headerless R16 file of `width x height` codes (exactly `width * height * 2` bytes),
/// in metres when `stretch` is given, else as raw code values. The cell size is `[1, 1]`.
pub fn read_r16(
    path: &Path,
    width: usize,
    height: usize,
    stretch: Option<Stretch>,
) -> Result<Heightmap, RasterError> {
    checks::check_size(width as u64, height as u64)?;
    let (reader, file_len) = open(path)?;
    decode_guarded(path, || {
        let map = r16_file::decode(path, reader, file_len, [width, height], stretch)?;
        check_bounds(path, &map)?;
        Ok(map)
    })
    .map_err(|e| e.read_as(path, "R16"))
}

/// Opens `path` for buffered reading and returns its length.
fn open(path: &Path) -> Result<(BufReader<File>, u64), RasterError> {
    let file = File::open(path).map_err(|source| RasterError::io(path, source))?;
    let file_len = file
        .metadata()
        .map_err(|source| RasterError::io(path, source))?
        .len();
    Ok((BufReader::new(file), file_len))
}

/// Runs a decoder, turning a panic inside a third-party decoder on malformed input into a
/// [`RasterError::Decode`] so a bad file cannot take the editor down.
pub(crate) fn decode_guarded<T>(
    path: &Path,
    decode: impl FnOnce() -> Result<T, RasterError>,
) -> Result<T, RasterError> {
    // Unwind safety: the closure owns the reader and builds a fresh map; nothing it touched
    // outlives a panic.
    catch_unwind(AssertUnwindSafe(decode)).unwrap_or_else(|_| {
        Err(RasterError::decode(
            path,
            "the decoder failed on malformed data (internal panic)",
        ))
    })
}
