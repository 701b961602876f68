//! GeoTIFF reader: one grey band of any integer or float sample type, striped or tiled, with
//! whatever compression and predictor the `tiff` crate decodes (none, LZW, deflate, PackBits;
//! horizontal and float predictors).
//!
//! Georeference: `ModelPixelScaleTag` (33550) + `ModelTiepointTag` (33922), or
//! `ModelTransformationTag` (34264); `GeoKeyDirectoryTag` (34735) says geographic or projected;
//! `GDAL_NODATA` (42113) gives the no-data value. Without any CRS key, a pixel scale above 0.01 is
//! taken as metres and a smaller one as degrees (with a warning in [`DemSource::warnings`]).

use std::fs::File;
use std::io::BufReader;
use std::path::Path;

use tiff::decoder::{Decoder, DecodingResult, Limits};
use tiff::tags::Tag;
use tiff::{ColorType, TiffError};

use crate::fill::mark_holes;
use crate::{
    DemError, DemFormat, DemSource, HorizontalUnits, RawGrid, check_grid_size, degrees_to_metres,
};

const TAG_MODEL_TRANSFORMATION: u16 = 34264;
const KEY_MODEL_TYPE: u16 = 1024;
const KEY_RASTER_TYPE: u16 = 1025;
const KEY_GEOGRAPHIC_TYPE: u16 = 2048;
const KEY_PROJECTED_CS_TYPE: u16 = 3072;
const KEY_PROJ_LINEAR_UNITS: u16 = 3076;
const KEY_VERTICAL_UNITS: u16 = 4099;
const MODEL_TYPE_PROJECTED: u16 = 1;
const MODEL_TYPE_GEOGRAPHIC: u16 = 2;
const RASTER_PIXEL_IS_POINT: u16 = 2;
/// Decoder buffer limit while tags are read.
const TAG_BUFFER_BYTES: usize = 1 << 20;

fn limits(decoding_buffer_bytes: usize) -> Limits {
    let mut limits = Limits::default();
    limits.decoding_buffer_size = decoding_buffer_bytes;
    limits.ifd_value_size = TAG_BUFFER_BYTES;
    limits
}

/// Reads a GeoTIFF into a north-up grid with NaN holes and a cell size in metres. A plain TIFF
/// without georeference needs `LoadOptions::cell_size_m` (`cell_size_given`).
pub(crate) fn read(path: &Path, cell_size_given: bool) -> Result<RawGrid, DemError> {
    let file = File::open(path).map_err(|e| DemError::io(path, e))?;
    let tiff_err = |e: TiffError| tiff_error(path, e);
    let mut decoder = Decoder::new(BufReader::new(file)).map_err(tiff_err)?;
    let (width, height) = decoder.dimensions().map_err(tiff_err)?;
    check_grid_size(path, width.into(), height.into())?;
    // While tags are read, keep every buffer small: the crate sizes ASCII tag values (such as
    // GDAL_NODATA) by `decoding_buffer_size`, so a corrupt count could otherwise reserve GiBs.
    let mut decoder = decoder.with_limits(limits(TAG_BUFFER_BYTES));
    let bits = match decoder.colortype().map_err(tiff_err)? {
        ColorType::Gray(bits) => bits,
        other => {
            return Err(DemError::unsupported(
                path,
                format!("{other:?} image, expected one band"),
            ));
        }
    };
    let compression = match decoder.find_tag_unsigned::<u16>(Tag::Compression) {
        Ok(c) => compression_name(c.unwrap_or(1)),
        Err(e) => return Err(tiff_err(e)),
    };
    let predictor = decoder
        .find_tag_unsigned::<u16>(Tag::Predictor)
        .map_err(tiff_err)?;
    let tiled = decoder.get_chunk_type() == tiff::decoder::ChunkType::Tile;
    let geo = read_georeference(&mut decoder).map_err(tiff_err)?;
    if !geo.georeferenced && !cell_size_given {
        return Err(DemError::MissingCellSize {
            path: path.to_owned(),
        });
    }

    // The image itself: exactly the checked grid size (at most MAX_CELLS 8-byte samples).
    let image_bytes = width as usize * height as usize * usize::from(bits).div_ceil(8);
    let mut decoder = decoder.with_limits(limits(image_bytes.max(TAG_BUFFER_BYTES)));
    let (sample_type, mut heights) = match decoder.read_image().map_err(tiff_err)? {
        DecodingResult::I16(v) => ("int16", v.into_iter().map(f32::from).collect()),
        DecodingResult::U16(v) => ("uint16", v.into_iter().map(f32::from).collect()),
        DecodingResult::F32(v) => ("float32", v),
        DecodingResult::I8(v) => ("int8", v.into_iter().map(f32::from).collect()),
        DecodingResult::U8(v) => ("uint8", v.into_iter().map(f32::from).collect()),
        DecodingResult::I32(v) => ("int32", v.into_iter().map(|h| h as f32).collect()),
        DecodingResult::U32(v) => ("uint32", v.into_iter().map(|h| h as f32).collect()),
        DecodingResult::F64(v) => ("float64", v.into_iter().map(|h| h as f32).collect()),
        DecodingResult::F16(v) => ("float16", v.into_iter().map(f32::from).collect()),
        DecodingResult::I64(_) | DecodingResult::U64(_) => {
            return Err(DemError::unsupported(path, "64-bit integer samples"));
        }
    };
    let (width, height) = (width as usize, height as usize);
    if heights.len() != width * height {
        return Err(DemError::malformed(
            path,
            "decoded sample count does not match the size",
        ));
    }
    mark_holes(&mut heights, geo.nodata);
    if geo.vertical_metres_per_unit != 1.0 {
        let k = geo.vertical_metres_per_unit as f32;
        heights.iter_mut().for_each(|h| *h *= k);
    }

    let mut warnings = geo.warnings;
    let [sx, sy] = geo.scale;
    if sx == 0.0 || sy == 0.0 || !sx.is_finite() || !sy.is_finite() {
        return Err(DemError::malformed(
            path,
            format!("pixel scale ({sx}, {sy})"),
        ));
    }
    // GeoTIFF convention: model y = tie_y - (row - tie_row) * scale_y, so a positive scale_y means
    // row 0 is north. A negative one means the rows are stored south-up.
    let rows_flipped = sy < 0.0;
    if rows_flipped {
        flip_rows(&mut heights, width);
    }
    if sx < 0.0 {
        flip_columns(&mut heights, width);
        warnings.push("negative x pixel scale: columns were mirrored to run west to east".into());
    }
    let native = [sx.abs(), sy.abs()];
    let (units, centre_lat_deg, cell_size_m) = if geo.geographic {
        // Raster row of the grid's middle, in the tiepoint's raster space (corner- or
        // centre-based depending on the raster type).
        let mid_row = if geo.pixel_is_point {
            (height as f64 - 1.0) / 2.0
        } else {
            height as f64 / 2.0
        };
        let lat = geo.tie_model[1] - (mid_row - geo.tie_raster[1]) * sy;
        if !(-90.0..=90.0).contains(&lat) {
            return Err(DemError::malformed(
                path,
                format!("centre latitude {lat} is not on Earth"),
            ));
        }
        (
            HorizontalUnits::Degrees,
            Some(lat),
            degrees_to_metres(native, lat),
        )
    } else {
        let k = geo.linear_metres_per_unit;
        (
            HorizontalUnits::Metres,
            None,
            [native[0] * k, native[1] * k],
        )
    };
    let source = DemSource {
        path: path.to_owned(),
        format: DemFormat::GeoTiff {
            compression,
            tiled,
            predictor: predictor.unwrap_or(1) > 1,
        },
        sample_type,
        horizontal_units: units,
        native_cell_size: native,
        centre_lat_deg,
        nodata: geo.nodata,
        rows_flipped,
        warnings,
    };
    Ok(RawGrid {
        width,
        height,
        heights_m: heights,
        cell_size_m,
        source,
    })
}

fn tiff_error(path: &Path, err: TiffError) -> DemError {
    match err {
        TiffError::IoError(e) => DemError::io(path, e),
        TiffError::UnsupportedError(e) => DemError::unsupported(path, e.to_string()),
        TiffError::LimitsExceeded => {
            DemError::malformed(path, "a TIFF structure exceeds the limits")
        }
        other => DemError::malformed(path, other.to_string()),
    }
}

fn compression_name(code: u16) -> &'static str {
    match code {
        1 => "none",
        5 => "LZW",
        8 | 32946 => "deflate",
        32773 => "PackBits",
        _ => "other",
    }
}

fn flip_rows(heights: &mut [f32], width: usize) {
    let rows = heights.len() / width;
    for r in 0..rows / 2 {
        let (top, bottom) = heights.split_at_mut((rows - 1 - r) * width);
        top[r * width..(r + 1) * width].swap_with_slice(&mut bottom[..width]);
    }
}

fn flip_columns(heights: &mut [f32], width: usize) {
    heights.chunks_exact_mut(width).for_each(<[f32]>::reverse);
}

/// What the GeoTIFF tags say about the grid.
struct Georeference {
    /// False if the file has neither a pixel scale nor a transformation.
    georeferenced: bool,
    /// Pixel scale (x, y) in model units; y positive for north-up.
    scale: [f64; 2],
    /// Tiepoint raster (i, j) and model (x, y).
    tie_raster: [f64; 2],
    tie_model: [f64; 2],
    geographic: bool,
    pixel_is_point: bool,
    linear_metres_per_unit: f64,
    vertical_metres_per_unit: f64,
    nodata: Option<f64>,
    warnings: Vec<String>,
}

fn read_georeference<R: std::io::Read + std::io::Seek>(
    decoder: &mut Decoder<R>,
) -> Result<Georeference, TiffError> {
    let f64s = |d: &mut Decoder<R>, tag: Tag| -> Result<Option<Vec<f64>>, TiffError> {
        d.find_tag(tag)?.map(|v| v.into_f64_vec()).transpose()
    };
    let mut warnings = Vec::new();
    let mut georeferenced = true;
    let pixel_scale = f64s(decoder, Tag::ModelPixelScaleTag)?;
    let tiepoint = f64s(decoder, Tag::ModelTiepointTag)?;
    let transform = f64s(decoder, Tag::Unknown(TAG_MODEL_TRANSFORMATION))?;
    let (scale, tie_raster, tie_model) = match (pixel_scale, tiepoint, transform) {
        (Some(s), Some(t), _) if s.len() >= 2 && t.len() >= 6 => {
            ([s[0], s[1]], [t[0], t[1]], [t[3], t[4]])
        }
        (_, _, Some(m)) if m.len() >= 16 => {
            if m[1] != 0.0 || m[4] != 0.0 {
                warnings.push("rotated ModelTransformation: rotation ignored".into());
            }
            ([m[0], -m[5]], [0.0, 0.0], [m[3], m[7]])
        }
        (Some(s), _, _) if s.len() >= 2 => {
            warnings.push("no tiepoint: latitude unknown, assumed 0".into());
            ([s[0], s[1]], [0.0, 0.0], [0.0, 0.0])
        }
        _ => {
            georeferenced = false; // the caller supplies the cell size
            ([1.0, 1.0], [0.0, 0.0], [0.0, 0.0])
        }
    };

    let keys = match decoder.find_tag(Tag::GeoKeyDirectoryTag)? {
        Some(v) => v.into_u16_vec()?,
        None => Vec::new(),
    };
    let key = |id: u16| -> Option<u16> {
        // Header of 4 shorts, then (key, location, count, value); location 0 = value inline.
        keys.get(4..)?
            .chunks_exact(4)
            .find(|k| k[0] == id && k[1] == 0)
            .map(|k| k[3])
    };
    let geographic = match key(KEY_MODEL_TYPE) {
        Some(MODEL_TYPE_GEOGRAPHIC) => true,
        Some(MODEL_TYPE_PROJECTED) => false,
        _ if key(KEY_PROJECTED_CS_TYPE).is_some() => false,
        _ if key(KEY_GEOGRAPHIC_TYPE).is_some() => true,
        _ if scale[0].abs() > 0.01 => false,
        _ => {
            warnings.push(format!(
                "no CRS keys and a pixel scale of {}: assumed degrees",
                scale[0].abs()
            ));
            true
        }
    };
    let nodata = match decoder.find_tag(Tag::GdalNodata)? {
        Some(v) => {
            let text = v.into_string()?;
            let text = text.trim_matches(|c: char| c == '\0' || c.is_whitespace());
            match text.parse::<f64>() {
                Ok(v) => Some(v),
                Err(_) => {
                    warnings.push(format!("unreadable GDAL_NODATA {text:?} ignored"));
                    None
                }
            }
        }
        None => None,
    };
    Ok(Georeference {
        georeferenced,
        scale,
        tie_raster,
        tie_model,
        geographic,
        pixel_is_point: key(KEY_RASTER_TYPE) == Some(RASTER_PIXEL_IS_POINT),
        linear_metres_per_unit: unit_metres(key(KEY_PROJ_LINEAR_UNITS), &mut warnings),
        vertical_metres_per_unit: unit_metres(key(KEY_VERTICAL_UNITS), &mut warnings),
        nodata,
        warnings,
    })
}

/// Metres per unit for an EPSG linear unit code (absent = metres).
fn unit_metres(code: Option<u16>, warnings: &mut Vec<String>) -> f64 {
    match code {
        None | Some(9001) | Some(32767) => 1.0,
        Some(9002) => 0.3048,
        Some(9003) => 1200.0 / 3937.0,
        Some(other) => {
            warnings.push(format!("unknown linear unit code {other}: assumed metres"));
            1.0
        }
    }
}
