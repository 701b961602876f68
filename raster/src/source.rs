//! What a read gives besides the heights: the file's format, units, no-data value and
//! georeference ([`Source`]), and the options for formats that do not describe themselves.

use std::path::PathBuf;

use crate::{Georef, Heightmap};

/// Metres per degree of latitude used to convert geographic grids (the equatorial value).
pub const METRES_PER_DEGREE_LAT: f64 = 110_574.0;
/// Metres per degree of longitude at the equator; multiplied by cos(latitude) elsewhere.
pub const METRES_PER_DEGREE_LON_AT_EQUATOR: f64 = 111_320.0;
/// Equatorial circumference used by web-map (EPSG:3857) tiles, in metres.
const WEB_MERCATOR_CIRCUMFERENCE_M: f64 = 40_075_016.686;
/// Pixels per side of a web-map tile.
const WEB_TILE_PIXELS: f64 = 256.0;

/// Converts a cell size in degrees `[lon, lat]` to metres at latitude `lat_deg`:
/// x = lon * cos(lat) * 111 320 m, y = lat * 110 574 m.
pub fn degrees_to_metres(cell_deg: [f64; 2], lat_deg: f64) -> [f64; 2] {
    [
        cell_deg[0] * lat_deg.to_radians().cos() * METRES_PER_DEGREE_LON_AT_EQUATOR,
        cell_deg[1] * METRES_PER_DEGREE_LAT,
    ]
}

/// Ground size in metres of one pixel of a 256-pixel web-map tile at `zoom`, row `tile_y`, taken
/// at the latitude of the tile's centre: `40 075 016.686 m * cos(lat) / 2^zoom / 256`. The same in
/// x and y (Mercator is conformal).
pub fn web_mercator_cell_size_m(zoom: u32, tile_y: u32) -> f64 {
    let tiles = 2f64.powi(zoom as i32);
    let y = (f64::from(tile_y) + 0.5) / tiles;
    let lat = (std::f64::consts::PI * (1.0 - 2.0 * y)).sinh().atan();
    WEB_MERCATOR_CIRCUMFERENCE_M * lat.cos() / tiles / WEB_TILE_PIXELS
}

/// The file format a raster was read as.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum SourceFormat {
    /// TIFF / GeoTIFF, striped or tiled.
    GeoTiff {
        /// Compression as named in the TIFF specification ("none", "LZW", "deflate", ...).
        compression: &'static str,
        /// Whether the image is stored in tiles (else in strips).
        tiled: bool,
        /// Whether a horizontal differencing predictor was undone.
        predictor: bool,
    },
    /// OpenEXR.
    Exr,
    /// Grey PNG (8 or 16 bit): metres through terrasketch's stretch chunks, else levels.
    GreyPng,
    /// Terrarium RGB PNG: `h = R * 256 + G + B / 256 - 32768`.
    TerrariumPng,
    /// SRTM `.hgt`: raw big-endian `i16`, 1201 or 3601 cells square.
    SrtmHgt,
    /// ESRI ASCII grid (`.asc`).
    EsriAsciiGrid,
    /// Raw little-endian 16-bit codes.
    R16,
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

/// Where a raster came from and how the file described it.
#[derive(Clone, Debug, PartialEq)]
pub struct Source {
    /// The file that was read.
    pub path: PathBuf,
    /// Its format.
    pub format: SourceFormat,
    /// How one sample is stored, e.g. "int16", "float32", "rgb8".
    pub sample_type: &'static str,
    /// Units of the file's own cell size.
    pub horizontal_units: HorizontalUnits,
    /// The file's own cell size `[x, y]` in `horizontal_units` (before conversion to metres).
    pub native_cell_size: [f64; 2],
    /// Latitude of the grid's centre in degrees, when the file gives it.
    pub centre_lat_deg: Option<f64>,
    /// The no-data value the file declared (or the format implies), if any, in file units.
    pub nodata: Option<f64>,
    /// True if the file stored rows south-up and they were flipped to north-up.
    pub rows_flipped: bool,
    /// GeoTIFF georeference (CRS and transform), describing the north-up raster as held.
    pub georef: Option<Georef>,
    /// Guesses made while reading, for the application to show (e.g. "no CRS, assumed degrees").
    pub warnings: Vec<String>,
}

impl Source {
    /// A source record for `path` in `format` with metric units and nothing else known.
    pub(crate) fn new(path: PathBuf, format: SourceFormat, sample_type: &'static str) -> Source {
        Source {
            path,
            format,
            sample_type,
            horizontal_units: HorizontalUnits::Metres,
            native_cell_size: [1.0, 1.0],
            centre_lat_deg: None,
            nodata: None,
            rows_flipped: false,
            georef: None,
            warnings: Vec::new(),
        }
    }
}

impl SourceFormat {
    /// The format's name for messages ("GeoTIFF", "PNG", ...).
    pub fn name(&self) -> &'static str {
        match self {
            SourceFormat::GeoTiff { .. } => "GeoTIFF",
            SourceFormat::Exr => "OpenEXR",
            SourceFormat::GreyPng => "PNG",
            SourceFormat::TerrariumPng => "Terrarium PNG",
            SourceFormat::SrtmHgt => "SRTM .hgt",
            SourceFormat::EsriAsciiGrid => "ESRI ASCII grid",
            SourceFormat::R16 => "R16",
        }
    }
}

/// Options for [`crate::read_raster`]. The default suits every self-describing file.
#[derive(Clone, Debug)]
pub struct ReadOptions {
    /// Square cell size in metres, overriding what the file says. Required where the file gives
    /// none (PNGs without a sidecar `NAME.json` or stretch chunks, TIFFs without georeference,
    /// `.hgt` files not named after their corner) unless `unit_cells_when_absent` is set.
    pub cell_size_m: Option<f64>,
    /// When the file gives no cell size and none is set, use 1 m (with a warning) instead of
    /// failing with [`crate::RasterError::MissingCellSize`].
    pub unit_cells_when_absent: bool,
    /// Decode an RGB PNG as Terrarium even if its name does not contain "terrarium".
    pub terrarium: bool,
    /// Units of an ESRI ASCII grid's `cellsize` (the format does not say).
    pub asc_units: HorizontalUnits,
    /// Metres per grey level of a grey PNG without stretch chunks:
    /// `h = png_offset_m + png_metres_per_level * value`.
    pub png_metres_per_level: f64,
    /// Height in metres of grey level 0 of a grey PNG without stretch chunks.
    pub png_offset_m: f64,
}

impl Default for ReadOptions {
    fn default() -> Self {
        Self {
            cell_size_m: None,
            unit_cells_when_absent: false,
            terrarium: false,
            asc_units: HorizontalUnits::Metres,
            png_metres_per_level: 1.0,
            png_offset_m: 0.0,
        }
    }
}

/// A raster read from a file: heights in metres and cell size (the [`Heightmap`]), where they
/// came from with the no-data value and georeference ([`Source`]), and which cells were no-data
/// (filled by a smooth pull-push interpolation so that every height is finite).
#[derive(Clone, Debug, PartialEq)]
pub struct Raster {
    /// North-up heights in metres, every one finite, and the cell size in metres.
    pub map: Heightmap,
    /// Format, units, no-data value, georeference and warnings.
    pub source: Source,
    /// `true` at cells that were no-data in the file (row-major); empty when there were none.
    pub nodata_mask: Vec<bool>,
}

impl Raster {
    /// How many cells were no-data (and were filled).
    pub fn filled_cells(&self) -> usize {
        self.nodata_mask.iter().filter(|&&hole| hole).count()
    }
}

/// What a format reader hands back: heights with NaN holes, the cell size in metres (`None` when
/// the file gives none) and the source record.
pub(crate) struct RawGrid {
    pub width: usize,
    pub height: usize,
    /// Row 0 = north. Holes are NaN.
    pub heights_m: Vec<f32>,
    pub cell_size_m: Option<[f64; 2]>,
    pub source: Source,
}

#[cfg(test)]
mod tests {
    use super::web_mercator_cell_size_m;

    #[test]
    fn web_mercator_cell_sizes() {
        // The zoom-0 tile is centred on the equator.
        assert!((web_mercator_cell_size_m(0, 0) - 156_543.034).abs() < 0.01);
        // Grand Canyon tile z11/385/803: centre latitude 36.10 N.
        let cell = web_mercator_cell_size_m(11, 803);
        assert!((cell - 61.76).abs() < 0.01, "{cell}");
    }
}
