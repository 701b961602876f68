//! PNG: 16-bit greyscale codes of a [`Stretch`], which is stored with the cell size in `tEXt`
//! chunks so that the file reads back in metres.

use std::io::{BufRead, Seek};
use std::path::Path;

use png::{BitDepth, ColorType, DecodingError, EncodingError};

use crate::checks::{self, check_payload, check_size};
use crate::{Heightmap, RasterError, Stretch};

/// `tEXt` keyword of the height in metres of code 0.
pub(crate) const MIN_KEY: &str = "terrasketch:min_m";
/// `tEXt` keyword of the height in metres of code 65535.
pub(crate) const MAX_KEY: &str = "terrasketch:max_m";
/// `tEXt` keyword of the cell size, `"x y"` in metres.
pub(crate) const CELL_SIZE_KEY: &str = "terrasketch:cell_size_m";

/// Memory the PNG decoder may use besides the image (row buffers, text chunks).
const DECODER_LIMIT_BYTES: usize = 64 << 20;
/// Deflate expands its input at most 1,032 times.
const MAX_DEFLATE_EXPANSION: u64 = 1032;

/// Encodes `map` (already validated) as 16-bit greyscale codes of `stretch`.
pub(crate) fn encode(map: &Heightmap, stretch: Stretch) -> Result<Vec<u8>, RasterError> {
    let to_error = |error: EncodingError| RasterError::encode(format!("PNG: {error}"));
    // `check_writable` bounded the sides by MAX_SIDE, so they fit in u32.
    let width = u32::try_from(map.width).map_err(|_| RasterError::encode("width exceeds u32"))?;
    let height =
        u32::try_from(map.height).map_err(|_| RasterError::encode("height exceeds u32"))?;

    let mut samples = Vec::with_capacity(map.data.len() * 2);
    for &height_m in &map.data {
        samples.extend_from_slice(&stretch.code_from_metres(height_m).to_be_bytes());
    }

    let mut bytes = Vec::new();
    let mut encoder = png::Encoder::new(&mut bytes, width, height);
    encoder.set_color(ColorType::Grayscale);
    encoder.set_depth(BitDepth::Sixteen);
    let texts = [
        (MIN_KEY, stretch.min_m.to_string()),
        (MAX_KEY, stretch.max_m.to_string()),
        (CELL_SIZE_KEY, checks::cell_size_text(map.cell_size_m)),
    ];
    for (keyword, text) in texts {
        encoder
            .add_text_chunk(keyword.to_string(), text)
            .map_err(to_error)?;
    }
    let mut writer = encoder.write_header().map_err(to_error)?;
    writer.write_image_data(&samples).map_err(to_error)?;
    writer.finish().map_err(to_error)?;
    Ok(bytes)
}

/// Encodes `pixels` (`width x height`, already checked) as an 8-bit greyscale PNG.
pub(crate) fn encode_grey8(
    width: usize,
    height: usize,
    pixels: &[u8],
) -> Result<Vec<u8>, RasterError> {
    let to_error = |error: EncodingError| RasterError::encode(format!("PNG: {error}"));
    let width = u32::try_from(width).map_err(|_| RasterError::encode("width exceeds u32"))?;
    let height = u32::try_from(height).map_err(|_| RasterError::encode("height exceeds u32"))?;
    let mut bytes = Vec::new();
    let mut encoder = png::Encoder::new(&mut bytes, width, height);
    encoder.set_color(ColorType::Grayscale);
    encoder.set_depth(BitDepth::Eight);
    let mut writer = encoder.write_header().map_err(to_error)?;
    writer.write_image_data(pixels).map_err(to_error)?;
    writer.finish().map_err(to_error)?;
    Ok(bytes)
}

/// Decodes an 8- or 16-bit greyscale PNG of `file_len` bytes: in metres when it carries the
/// stretch chunks, else as raw code values.
pub(crate) fn decode<R: BufRead + Seek>(
    path: &Path,
    reader: R,
    file_len: u64,
) -> Result<Heightmap, RasterError> {
    let to_error = |error| png_error(path, error);
    let limits = png::Limits {
        bytes: DECODER_LIMIT_BYTES,
    };
    let mut decoder = png::Decoder::new_with_limits(reader, limits);
    decoder.set_transformations(png::Transformations::IDENTITY);

    // Only the IHDR chunk so far: check it before the decoder sizes any buffer.
    let header = decoder.read_header_info().map_err(to_error)?;
    let (width, height) = (u64::from(header.width), u64::from(header.height));
    let (color_type, bit_depth) = (header.color_type, header.bit_depth);
    check_size(width, height)?;
    let width = checks::nonzero_side(path, width, "width")?;
    let height = checks::nonzero_side(path, height, "height")?;
    let bytes_per_sample = match (color_type, bit_depth) {
        (ColorType::Grayscale, BitDepth::Sixteen) => 2,
        (ColorType::Grayscale, BitDepth::Eight) => 1,
        _ => {
            return Err(RasterError::decode(
                path,
                format!(
                    "expected 8- or 16-bit greyscale, found {color_type:?} with {bit_depth:?} \
                     bits per sample"
                ),
            ));
        }
    };
    let filtered_bytes = (width as u64 * bytes_per_sample + 1) * height as u64;
    check_payload(path, filtered_bytes, file_len, MAX_DEFLATE_EXPANSION)?;

    let mut reader = decoder.read_info().map_err(to_error)?;
    let buffer_len = reader
        .output_buffer_size()
        .ok_or_else(|| RasterError::decode(path, "the image does not fit in memory"))?;
    let mut buffer = vec![0; buffer_len];
    reader.next_frame(&mut buffer).map_err(to_error)?;
    // Reads up to IEND: catches truncation after the image data and picks up text chunks
    // placed after it.
    reader.finish().map_err(to_error)?;

    let info = reader.info();
    let text = |keyword: &str| {
        info.uncompressed_latin1_text
            .iter()
            .find(|chunk| chunk.keyword == keyword)
            .map(|chunk| chunk.text.as_str())
    };
    let stretch = read_stretch(path, text(MIN_KEY), text(MAX_KEY))?;
    let cell_size_m = match text(CELL_SIZE_KEY) {
        Some(cell_size) => checks::parse_cell_size(path, cell_size)?,
        None => [1.0, 1.0],
    };

    let cells = width * height;
    let data: Vec<f32> = if bytes_per_sample == 2 {
        let codes = buffer[..cells * 2]
            .chunks_exact(2)
            .map(|pair| u16::from_be_bytes([pair[0], pair[1]]));
        match stretch {
            Some(stretch) => codes.map(|code| stretch.metres_from_code(code)).collect(),
            None => codes.map(f32::from).collect(),
        }
    } else {
        let codes = buffer[..cells].iter().copied();
        match stretch {
            // 255 * 257 = 65535: the 8-bit range covers the same stretch.
            Some(stretch) => codes
                .map(|code| stretch.metres_from_code(u16::from(code) * 257))
                .collect(),
            None => codes.map(f32::from).collect(),
        }
    };
    Ok(Heightmap {
        width,
        height,
        data,
        cell_size_m,
    })
}

/// The stretch from its two text chunks: both or neither must be present.
fn read_stretch(
    path: &Path,
    min_text: Option<&str>,
    max_text: Option<&str>,
) -> Result<Option<Stretch>, RasterError> {
    let (min_text, max_text) = match (min_text, max_text) {
        (None, None) => return Ok(None),
        (Some(min_text), Some(max_text)) => (min_text, max_text),
        _ => {
            return Err(RasterError::decode(
                path,
                format!("only one of the {MIN_KEY} and {MAX_KEY} text chunks is present"),
            ));
        }
    };
    let stretch = match (min_text.trim().parse(), max_text.trim().parse()) {
        (Ok(min_m), Ok(max_m)) => Some(Stretch { min_m, max_m }),
        _ => None,
    };
    match stretch {
        Some(stretch) if stretch.is_valid() => Ok(Some(stretch)),
        _ => Err(RasterError::decode(
            path,
            format!(
                "invalid stretch {MIN_KEY}={min_text:?}, {MAX_KEY}={max_text:?}: expected finite \
                 numbers with min <= max"
            ),
        )),
    }
}

/// Converts a `png` error into ours; running out of bytes means truncation.
fn png_error(path: &Path, error: DecodingError) -> RasterError {
    match error {
        DecodingError::IoError(source) => RasterError::from_read(path, source),
        DecodingError::LimitsExceeded => {
            RasterError::decode(path, "the image exceeds the decoder's memory limits")
        }
        other => RasterError::decode(path, format!("PNG: {other}")),
    }
}
