//! TIFF: one 32-bit IEEE float sample per pixel, uncompressed strips, GeoTIFF tags.
//!
//! Georeferencing written (GeoTIFF 1.0, raster space to model space):
//! - `ModelPixelScaleTag` (33550) = `[cell_x, cell_y, 0]`;
//! - `ModelTiepointTag` (33922) = `[0, 0, 0, 0, height * cell_y, 0]`: the raster's top-left
//!   corner (row 0 is north) sits at model `x = 0`, `y = extent north`, so model `y` grows
//!   northwards and the map's south-west corner is the origin; a corner-sampled raster
//!   ([`Sampling::Corners`]) ties at `[-cell_x / 2, (height - 1/2) * cell_y]`, so its first
//!   sample lies on the extent's north-west corner;
//! - `GeoKeyDirectoryTag` (34735): projected model, pixel-is-area, linear unit metre.

use std::io::{BufRead, Cursor, Seek, Write};
use std::path::Path;

use tiff::TiffError;
use tiff::decoder::{Decoder, DecodingResult, Limits};
use tiff::encoder::{TiffEncoder, TiffKind, colortype::Gray32Float};
use tiff::tags::Tag;

use crate::checks::{self, MAX_SAMPLE_BYTES, check_payload, check_size};
use crate::{Heightmap, RasterError, Sampling, WriteOptions};

/// GeoKeyDirectoryTag: header (KeyDirectoryVersion 1, KeyRevision 1.0, 3 keys), then
/// `(key id, tag location 0 = value inline, count 1, value)` per key, sorted by key id.
const GEO_KEY_DIRECTORY: [u16; 16] = [
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

/// Encodes `map` (already validated) as a GeoTIFF in memory; the options' sampling and origin
/// place the tie point (corner-sampled rasters put their first sample on the extent's north-west
/// corner).
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
    let [cell_x_m, cell_y_m] = map.cell_size_m;
    // Pixel-is-area: the tie point is the top-left pixel's outer corner. Corner samples sit on
    // the extent's edges, so their pixels reach half a cell past it.
    let [x0_m, y0_m] = options.origin_m;
    let (west_m, north_m) = match options.sampling {
        Sampling::Cells => (x0_m, y0_m + map.height as f64 * cell_y_m),
        Sampling::Corners => (
            x0_m - 0.5 * cell_x_m,
            y0_m + (map.height as f64 - 0.5) * cell_y_m,
        ),
    };

    let mut image = encoder.new_image::<Gray32Float>(width, height)?;
    let directory = image.encoder();
    directory.write_tag(Tag::ModelPixelScaleTag, &[cell_x_m, cell_y_m, 0.0][..])?;
    directory.write_tag(
        Tag::ModelTiepointTag,
        &[0.0, 0.0, 0.0, west_m, north_m, 0.0][..],
    )?;
    directory.write_tag(Tag::GeoKeyDirectoryTag, &GEO_KEY_DIRECTORY[..])?;
    image.write_data(&map.data)
}

/// Decodes the first image of a TIFF file of `file_len` bytes.
pub(crate) fn decode<R: BufRead + Seek>(
    path: &Path,
    reader: R,
    file_len: u64,
) -> Result<Heightmap, RasterError> {
    let to_error = |error| tiff_error(path, error);
    let mut limits = Limits::default();
    limits.decoding_buffer_size = usize::try_from(MAX_SAMPLE_BYTES).unwrap_or(usize::MAX);
    let mut decoder = Decoder::new(reader).map_err(to_error)?.with_limits(limits);

    let (width, height) = decoder.dimensions().map_err(to_error)?;
    check_size(width.into(), height.into())?;
    let width = checks::nonzero_side(path, width.into(), "width")?;
    let height = checks::nonzero_side(path, height.into(), "height")?;

    let bits_per_sample = match decoder.colortype().map_err(to_error)? {
        tiff::ColorType::Gray(bits @ (8 | 16 | 32 | 64)) => u64::from(bits),
        other => {
            return Err(RasterError::decode(
                path,
                format!("expected one greyscale sample per pixel, found {other:?}"),
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
    let raw_bytes = (width * height) as u64 * bits_per_sample / 8;
    check_payload(path, raw_bytes, file_len, max_expansion)?;

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
    let cell_size_m = read_cell_size(path, &mut decoder)?;

    let mut data = match decoder.read_image().map_err(to_error)? {
        DecodingResult::F32(samples) => samples,
        DecodingResult::F64(samples) => samples.into_iter().map(|s| s as f32).collect(),
        DecodingResult::U16(samples) => samples.into_iter().map(f32::from).collect(),
        DecodingResult::I16(samples) => samples.into_iter().map(f32::from).collect(),
        DecodingResult::U8(samples) => samples.into_iter().map(f32::from).collect(),
        _ => {
            return Err(RasterError::decode(
                path,
                "unsupported sample format: expected 32/64-bit float, 16-bit integer or 8-bit \
                 unsigned samples",
            ));
        }
    };
    if data.len() != width * height {
        return Err(RasterError::decode(
            path,
            format!(
                "decoded {} samples for a {width} x {height} image",
                data.len()
            ),
        ));
    }
    apply_orientation(&mut data, width, orientation);
    Ok(Heightmap {
        width,
        height,
        data,
        cell_size_m,
    })
}

/// The cell size from `ModelPixelScaleTag`, or `[1, 1]` when the tag is absent.
fn read_cell_size<R: BufRead + Seek>(
    path: &Path,
    decoder: &mut Decoder<R>,
) -> Result<[f64; 2], RasterError> {
    let Some(value) = decoder
        .find_tag(Tag::ModelPixelScaleTag)
        .map_err(|error| tiff_error(path, error))?
    else {
        return Ok([1.0, 1.0]);
    };
    let scale = value
        .into_f64_vec()
        .map_err(|error| tiff_error(path, error))?;
    match scale.as_slice() {
        [x, y, ..] if x.is_finite() && y.is_finite() && *x > 0.0 && *y > 0.0 => Ok([*x, *y]),
        _ => Err(RasterError::decode(
            path,
            format!("ModelPixelScaleTag {scale:?} is not a positive cell size"),
        )),
    }
}

/// Reorders rows and columns so that row 0 is the top (north) row, left to right, for the
/// mirrored orientations 2 (top-right), 3 (bottom-right) and 4 (bottom-left).
fn apply_orientation(data: &mut [f32], width: usize, orientation: u16) {
    if matches!(orientation, 2 | 3) {
        for row in data.chunks_exact_mut(width) {
            row.reverse();
        }
    }
    if matches!(orientation, 3 | 4) {
        let height = data.len() / width;
        for top in 0..height / 2 {
            let bottom = height - 1 - top;
            let (upper, lower) = data.split_at_mut(bottom * width);
            upper[top * width..(top + 1) * width].swap_with_slice(&mut lower[..width]);
        }
    }
}

/// Converts a `tiff` error into ours; running out of bytes means truncation.
fn tiff_error(path: &Path, error: TiffError) -> RasterError {
    match error {
        TiffError::IoError(source) => RasterError::from_read(path, source),
        TiffError::LimitsExceeded => {
            RasterError::decode(path, "the image exceeds the decoder's memory limits")
        }
        other => RasterError::decode(path, format!("TIFF: {other}")),
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
