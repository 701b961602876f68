//! TIFF / GeoTIFF: reads one grey band of any integer or float sample type, striped or tiled,
//! with whatever compression and predictor the `tiff` crate decodes; writes one 32-bit float
//! sample per pixel, uncompressed strips.
//!
//! Georeference read: `ModelPixelScaleTag` (33550) + `ModelTiepointTag` (33922), or
//! `ModelTransformationTag` (34264); `GeoKeyDirectoryTag` (34735) with its double (34736) and
//! ASCII (34737) parameters says geographic or projected; `GDAL_NODATA` (42113) gives the no-data
//! value. All of it is kept in [`Georef`] and written back by [`encode`] when the options carry
//! it. Without any CRS key, a pixel scale above 0.01 is taken as metres and a smaller one as
//! degrees (with a warning).
//!
//! Without a georeference to keep, the local metric frame is written:
//! - `ModelPixelScaleTag` = `[cell_x, cell_y, 0]`;
//! - `ModelTiepointTag` = `[0, 0, 0, x0, y0 + height * cell_y, 0]`: the raster's top-left corner
//!   (row 0 is north) sits at the origin's `x`, the extent's north edge, so model `y` grows
//!   northwards and the south-west corner is the origin (`[0, 0]` unless a tile's); a
//!   corner-sampled raster ([`Sampling::Corners`]) ties half a cell further out, so its first
//!   sample lies on the extent's north-west corner;
//! - `GeoKeyDirectoryTag`: projected model, pixel-is-area, linear unit metre, no CRS code.

use std::io::{BufRead, Cursor, Seek, Write};
use std::path::Path;

use tiff::TiffError;
use tiff::decoder::{ChunkType, Decoder, DecodingResult, Limits};
use tiff::encoder::{TiffEncoder, TiffKind, colortype::Gray32Float};
use tiff::tags::Tag;

use crate::checks::{self, MAX_SAMPLE_BYTES, check_payload, check_size};
use crate::georef::{self, Georef, Transform};
use crate::source::{HorizontalUnits, RawGrid, Source, SourceFormat, degrees_to_metres};
use crate::{Heightmap, RasterError, Sampling, WriteOptions};

/// The local metric frame's GeoKeyDirectoryTag: header (KeyDirectoryVersion 1, KeyRevision
/// 1.0, 3 keys), then `(key id, tag location 0 = value inline, count 1, value)` per key.
const LOCAL_GEO_KEYS: [u16; 16] = [
    1, 1, 0, 3, //
    1024, 0, 1, 1, // GTModelTypeGeoKey = ModelTypeProjected
    1025, 0, 1, 1, // GTRasterTypeGeoKey = RasterPixelIsArea
    3076, 0, 1, 9001, // ProjLinearUnitsGeoKey = Linear_Meter
];

/// Above this many bytes of samples the file is written as BigTIFF (classic TIFF offsets are
/// 32-bit; the margin covers the header and the directory).
const CLASSIC_TIFF_MAX_DATA_BYTES: u64 = u32::MAX as u64 - (16 << 20);

/// Bound on how many times a TIFF codec can expand its input (LZW stays below ~2,600:1, Deflate
/// below ~1,032:1). Used only to refuse absurd headers before allocating.
const MAX_COMPRESSION_EXPANSION: u64 = 4096;

/// TIFF `Compression` value for uncompressed data.
const COMPRESSION_NONE: u16 = 1;

/// Decoder buffer limit while tags are read: the crate sizes ASCII tag values (such as
/// GDAL_NODATA) by it, so a corrupt count cannot reserve GiBs.
const TAG_BUFFER_BYTES: usize = 1 << 20;

/// Most numbers accepted in one georeference tag (tie points, GeoKeys).
const MAX_GEO_VALUES: usize = 1 << 16;

/// Encodes `map` (already validated) as a GeoTIFF in memory: with the options' georeference and
/// no-data value when given, else in the local metric frame placed by the options' sampling and
/// origin.
pub(crate) fn encode(map: &Heightmap, options: &WriteOptions) -> Result<Vec<u8>, RasterError> {
    let data_bytes = map.data.len() as u64 * 4;
    let mut bytes = Cursor::new(Vec::with_capacity(map.data.len() * 4 + 4096));
    let written = if data_bytes > CLASSIC_TIFF_MAX_DATA_BYTES {
        TiffEncoder::new_big(&mut bytes).and_then(|encoder| write_image(encoder, map, options))
    } else {
        TiffEncoder::new(&mut bytes).and_then(|encoder| write_image(encoder, map, options))
    };
    written.map_err(|error| RasterError::encode(format!("TIFF: {error}")))?;
    Ok(bytes.into_inner())
}

/// Writes the one image directory with its GeoTIFF tags, for classic TIFF or BigTIFF.
fn write_image<W: Write + Seek, K: TiffKind>(
    mut encoder: TiffEncoder<W, K>,
    map: &Heightmap,
    options: &WriteOptions,
) -> Result<(), TiffError> {
    // `check_writable` bounded the sides by MAX_SIDE, so they fit in u32.
    let width = u32::try_from(map.width)?;
    let height = u32::try_from(map.height)?;
    let mut image = encoder.new_image::<Gray32Float>(width, height)?;
    let directory = image.encoder();
    match options.georef {
        Some(geo) => {
            match &geo.transform {
                Transform::ScaleTiepoints { scale, tiepoints } => {
                    directory.write_tag(Tag::ModelPixelScaleTag, &scale[..])?;
                    let flat: Vec<f64> = tiepoints.iter().flatten().copied().collect();
                    directory.write_tag(Tag::ModelTiepointTag, &flat[..])?;
                }
                Transform::Matrix(m) => directory.write_tag(Tag::ModelTransformationTag, &m[..])?,
            }
            if !geo.geo_keys.is_empty() {
                directory.write_tag(Tag::GeoKeyDirectoryTag, &geo.geo_keys[..])?;
            }
            if !geo.geo_doubles.is_empty() {
                directory.write_tag(Tag::GeoDoubleParamsTag, &geo.geo_doubles[..])?;
            }
            if !geo.geo_ascii.is_empty() {
                directory.write_tag(Tag::GeoAsciiParamsTag, geo.geo_ascii.as_str())?;
            }
        }
        None => {
            let [cell_x_m, cell_y_m] = map.cell_size_m;
            // Pixel-is-area: the tie point is the top-left pixel's outer corner. Corner samples
            // sit on the extent's edges, so their pixels reach half a cell past it.
            let [x0_m, y0_m] = options.origin_m;
            let (west_m, north_m) = match options.sampling {
                Sampling::Cells => (x0_m, y0_m + map.height as f64 * cell_y_m),
                Sampling::Corners => (
                    x0_m - 0.5 * cell_x_m,
                    y0_m + (map.height as f64 - 0.5) * cell_y_m,
                ),
            };
            directory.write_tag(Tag::ModelPixelScaleTag, &[cell_x_m, cell_y_m, 0.0][..])?;
            directory.write_tag(
                Tag::ModelTiepointTag,
                &[0.0, 0.0, 0.0, west_m, north_m, 0.0][..],
            )?;
            directory.write_tag(Tag::GeoKeyDirectoryTag, &LOCAL_GEO_KEYS[..])?;
        }
    }
    if let Some(nodata) = options.nodata {
        directory.write_tag(Tag::GdalNodata, nodata.to_string().as_str())?;
    }
    image.write_data(&map.data)
}

/// Decodes the first image of a TIFF file of `file_len` bytes into a north-up grid with NaN
/// holes; the cell size in metres comes from the georeference (`None` without one).
pub(crate) fn decode<R: BufRead + Seek>(
    path: &Path,
    reader: R,
    file_len: u64,
) -> Result<RawGrid, RasterError> {
    let to_error = |error| tiff_error(path, error);
    let mut decoder = Decoder::new(reader)
        .map_err(to_error)?
        .with_limits(limits(TAG_BUFFER_BYTES));
    let (width, height) = decoder.dimensions().map_err(to_error)?;
    check_size(width.into(), height.into())?;
    let width = checks::nonzero_side(path, width.into(), "width")?;
    let height = checks::nonzero_side(path, height.into(), "height")?;

    let bits = match decoder.colortype().map_err(to_error)? {
        tiff::ColorType::Gray(bits) => u64::from(bits),
        other => {
            return Err(RasterError::decode(
                path,
                format!("{other:?} image: expected one grey band"),
            ));
        }
    };
    let compression = decoder
        .find_tag_unsigned::<u16>(Tag::Compression)
        .map_err(to_error)?
        .unwrap_or(COMPRESSION_NONE);
    let max_expansion = if compression == COMPRESSION_NONE {
        1
    } else {
        MAX_COMPRESSION_EXPANSION
    };
    let raw_bytes = (width * height) as u64 * bits.div_ceil(8);
    check_payload(path, raw_bytes, file_len, max_expansion)?;
    let predictor = decoder
        .find_tag_unsigned::<u16>(Tag::Predictor)
        .map_err(to_error)?
        .unwrap_or(1);
    let orientation = decoder
        .find_tag_unsigned::<u16>(Tag::Orientation)
        .map_err(to_error)?
        .unwrap_or(1);
    if !(1..=4).contains(&orientation) {
        return Err(RasterError::decode(
            path,
            format!("TIFF orientation {orientation} (transposed) is not supported"),
        ));
    }
    let format = SourceFormat::GeoTiff {
        compression: compression_name(compression),
        tiled: decoder.get_chunk_type() == ChunkType::Tile,
        predictor: predictor > 1,
    };
    let tags = read_tags(path, &mut decoder)?;

    // The image itself: at most the checked grid size of 8-byte samples.
    let image_bytes = usize::try_from(raw_bytes.min(2 * MAX_SAMPLE_BYTES)).unwrap_or(usize::MAX);
    let mut decoder = decoder.with_limits(limits(image_bytes.max(TAG_BUFFER_BYTES)));
    let (sample_type, mut heights) = samples(path, decoder.read_image().map_err(to_error)?)?;
    if heights.len() != width * height {
        return Err(RasterError::decode(
            path,
            format!(
                "decoded {} samples for a {width} x {height} image",
                heights.len()
            ),
        ));
    }
    apply_orientation(&mut heights, width, orientation);
    crate::fill::mark_holes(&mut heights, tags.nodata);
    let mut source = Source::new(path.to_owned(), format, sample_type);
    source.nodata = tags.nodata;
    source.warnings = tags.warnings;
    // GeoTIFF raster space is the image as stored: a mirrored orientation mirrors the
    // transform with the samples.
    let georef = tags.georef.map(|mut geo| {
        if matches!(orientation, 2 | 3) {
            geo = geo.remapped([width as f64, -1.0], [0.0, 1.0]);
        }
        if matches!(orientation, 3 | 4) {
            geo = geo.remapped([0.0, 1.0], [height as f64, -1.0]);
        }
        geo
    });
    let cell_size_m = match georef {
        Some(geo) => Some(place(
            path,
            geo,
            &mut heights,
            [width, height],
            &mut source,
        )?),
        None => None,
    };
    Ok(RawGrid {
        width,
        height,
        heights_m: heights,
        cell_size_m,
        source,
    })
}

/// The decoder's limits with `decoding_buffer_bytes` for pixel and tag buffers.
fn limits(decoding_buffer_bytes: usize) -> Limits {
    let mut limits = Limits::default();
    limits.decoding_buffer_size = decoding_buffer_bytes;
    limits.ifd_value_size = TAG_BUFFER_BYTES;
    limits
}

/// Samples of any type as `f32`, with the type's name.
fn samples(path: &Path, decoded: DecodingResult) -> Result<(&'static str, Vec<f32>), RasterError> {
    Ok(match decoded {
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
            return Err(RasterError::decode(
                path,
                "64-bit integer samples are not supported",
            ));
        }
    })
}

/// The georeference and no-data tags.
struct Tags {
    georef: Option<Georef>,
    nodata: Option<f64>,
    warnings: Vec<String>,
}

/// Reads the georeference tags verbatim. A file with neither a pixel scale nor a transformation
/// has no georeference (the caller supplies the cell size).
fn read_tags<R: BufRead + Seek>(
    path: &Path,
    decoder: &mut Decoder<R>,
) -> Result<Tags, RasterError> {
    let to_error = |error| tiff_error(path, error);
    let mut f64s = |tag: Tag| -> Result<Option<Vec<f64>>, RasterError> {
        let values = decoder
            .find_tag(tag)
            .map_err(to_error)?
            .map(|v| v.into_f64_vec())
            .transpose()
            .map_err(to_error)?;
        match values {
            Some(v) if v.len() > MAX_GEO_VALUES || v.iter().any(|x| !x.is_finite()) => Err(
                RasterError::decode(path, format!("{tag:?} holds absurd or non-finite values")),
            ),
            other => Ok(other),
        }
    };
    let pixel_scale = f64s(Tag::ModelPixelScaleTag)?;
    let tiepoints = f64s(Tag::ModelTiepointTag)?;
    let matrix = f64s(Tag::ModelTransformationTag)?;
    let geo_doubles = f64s(Tag::GeoDoubleParamsTag)?.unwrap_or_default();
    let mut warnings = Vec::new();
    let transform = match (pixel_scale, tiepoints, matrix) {
        (Some(s), tie, _) if s.len() >= 2 => {
            let mut tiepoints: Vec<[f64; 6]> = tie
                .unwrap_or_default()
                .chunks_exact(6)
                .map(|t| [t[0], t[1], t[2], t[3], t[4], t[5]])
                .collect();
            if tiepoints.is_empty() {
                warnings.push("no tiepoint: the raster's corner is taken as (0, 0)".into());
                tiepoints.push([0.0; 6]);
            }
            Some(Transform::ScaleTiepoints {
                scale: [s[0], s[1], s.get(2).copied().unwrap_or(0.0)],
                tiepoints,
            })
        }
        (_, _, Some(m)) if m.len() == 16 => {
            let mut matrix = [0.0; 16];
            matrix.copy_from_slice(&m);
            Some(Transform::Matrix(matrix))
        }
        _ => None,
    };
    let geo_keys = match decoder
        .find_tag(Tag::GeoKeyDirectoryTag)
        .map_err(to_error)?
    {
        Some(v) => v.into_u16_vec().map_err(to_error)?,
        None => Vec::new(),
    };
    let geo_ascii = match decoder.find_tag(Tag::GeoAsciiParamsTag).map_err(to_error)? {
        Some(v) => v.into_string().map_err(to_error)?,
        None => String::new(),
    };
    let nodata = match decoder.find_tag(Tag::GdalNodata).map_err(to_error)? {
        Some(v) => {
            let text = v.into_string().map_err(to_error)?;
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
    let georef = transform.map(|transform| Georef {
        transform,
        geo_keys,
        geo_doubles,
        geo_ascii: geo_ascii.trim_end_matches('\0').to_owned(),
    });
    Ok(Tags {
        georef,
        nodata,
        warnings,
    })
}

/// Brings a georeferenced grid north-up and west-to-east (flipping the transform with it),
/// records its units and returns its cell size in metres.
fn place(
    path: &Path,
    geo: Georef,
    heights: &mut [f32],
    [width, height]: [usize; 2],
    source: &mut Source,
) -> Result<[f64; 2], RasterError> {
    let (sx, sy) = match &geo.transform {
        Transform::ScaleTiepoints { scale, .. } => (scale[0], scale[1]),
        Transform::Matrix(m) => {
            if m[1] != 0.0 || m[4] != 0.0 {
                source
                    .warnings
                    .push("rotated ModelTransformation: rotation ignored".into());
            }
            (m[0], -m[5])
        }
    };
    if sx == 0.0 || sy == 0.0 || !sx.is_finite() || !sy.is_finite() {
        return Err(RasterError::decode(
            path,
            format!("pixel scale ({sx}, {sy})"),
        ));
    }
    let vertical = unit_metres(geo.key(georef::KEY_VERTICAL_UNITS), &mut source.warnings);
    if vertical != 1.0 {
        heights.iter_mut().for_each(|h| *h *= vertical as f32);
    }
    // GeoTIFF convention: model y = tie_y - (row - tie_row) * scale_y, so a positive scale_y means
    // row 0 is north. A negative one means the rows are stored south-up.
    let mut geo = geo;
    if sy < 0.0 {
        flip_rows(heights, width);
        geo = geo.remapped([0.0, 1.0], [height as f64, -1.0]);
        source.rows_flipped = true;
    }
    if sx < 0.0 {
        heights.chunks_exact_mut(width).for_each(<[f32]>::reverse);
        geo = geo.remapped([width as f64, -1.0], [0.0, 1.0]);
        source
            .warnings
            .push("negative x pixel scale: columns were mirrored to run west to east".into());
    }
    let native = [sx.abs(), sy.abs()];
    let geographic = match geo.key(georef::KEY_MODEL_TYPE) {
        Some(georef::MODEL_TYPE_GEOGRAPHIC) => true,
        Some(georef::MODEL_TYPE_PROJECTED) => false,
        _ if geo.key(georef::KEY_PROJECTED_CS_TYPE).is_some() => false,
        _ if geo.key(georef::KEY_GEOGRAPHIC_TYPE).is_some() => true,
        _ if native[0] > 0.01 => false,
        _ => {
            source.warnings.push(format!(
                "no CRS keys and a pixel scale of {}: assumed degrees",
                native[0]
            ));
            true
        }
    };
    source.native_cell_size = native;
    let cell_size_m = if geographic {
        // Latitude of the grid's middle (model y of the centre in pixel-is-area or -point
        // raster coordinates).
        let mid = if geo.pixel_is_point() {
            (height as f64 - 1.0) / 2.0
        } else {
            height as f64 / 2.0
        };
        let lat = geo.model_xy(0.0, mid)[1];
        if !(-90.0..=90.0).contains(&lat) {
            return Err(RasterError::decode(
                path,
                format!("centre latitude {lat} is not on Earth"),
            ));
        }
        source.horizontal_units = HorizontalUnits::Degrees;
        source.centre_lat_deg = Some(lat);
        degrees_to_metres(native, lat)
    } else {
        let k = unit_metres(geo.key(georef::KEY_PROJ_LINEAR_UNITS), &mut source.warnings);
        [native[0] * k, native[1] * k]
    };
    source.georef = Some(geo);
    Ok(cell_size_m)
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

/// Reorders rows and columns so that row 0 is the top row, left to right, for the mirrored
/// orientations 2 (top-right), 3 (bottom-right) and 4 (bottom-left).
fn apply_orientation(data: &mut [f32], width: usize, orientation: u16) {
    if matches!(orientation, 2 | 3) {
        for row in data.chunks_exact_mut(width) {
            row.reverse();
        }
    }
    if matches!(orientation, 3 | 4) {
        flip_rows(data, width);
    }
}

/// Converts a `tiff` error into ours; running out of bytes means truncation.
fn tiff_error(path: &Path, error: TiffError) -> RasterError {
    match error {
        TiffError::IoError(source) => RasterError::from_read(path, source),
        TiffError::LimitsExceeded => {
            RasterError::decode(path, "a TIFF structure exceeds the decoder's memory limits")
        }
        other => RasterError::decode(path, other.to_string()),
    }
}

#[cfg(test)]
mod tests {
    use super::apply_orientation;

    #[test]
    fn orientations_bring_the_north_west_corner_to_index_zero() {
        // 3 x 2 raster stored in each orientation; after correction it reads 1..=6.
        let cases: [(u16, [f32; 6]); 4] = [
            (1, [1.0, 2.0, 3.0, 4.0, 5.0, 6.0]),
            (2, [3.0, 2.0, 1.0, 6.0, 5.0, 4.0]),
            (3, [6.0, 5.0, 4.0, 3.0, 2.0, 1.0]),
            (4, [4.0, 5.0, 6.0, 1.0, 2.0, 3.0]),
        ];
        for (orientation, stored) in cases {
            let mut data = stored;
            apply_orientation(&mut data, 3, orientation);
            assert_eq!(
                data,
                [1.0, 2.0, 3.0, 4.0, 5.0, 6.0],
                "orientation {orientation}"
            );
        }
    }
}
