//! PNG: 16-bit greyscale codes of a [`Stretch`], which is stored with the cell size in `tEXt`
//! chunks so that the file reads back in metres. Reads grey PNGs from elsewhere as levels
//! (`offset + k * level`) and Terrarium RGB tiles (`h = R * 256 + G + B / 256 - 32768`); PNG
//! carries no georeference, so the cell size comes from the chunk, a sidecar `NAME.json`
//! (`{"cell_size_m": 61.76}`) or the caller.

use std::io::{BufRead, Seek};
use std::path::Path;

use png::{BitDepth, ColorType, DecodingError, EncodingError};

use crate::checks::{self, check_payload, check_size};
use crate::source::{RawGrid, ReadOptions, Source, SourceFormat};
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
/// Largest sidecar `NAME.json` read.
const SIDECAR_MAX_BYTES: usize = 1 << 20;

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

/// Decodes a PNG of `file_len` bytes: grey (8 or 16 bit; palette and sub-byte grey expanded to
/// 8 bit) in metres when it carries the stretch chunks, else `offset + k * level` from the
/// options; RGB(A) as Terrarium when asked or named so. The cell size comes from the cell-size
/// chunk, else a sidecar `NAME.json` (`{"cell_size_m": 61.76}`), else `None`.
pub(crate) fn decode<R: BufRead + Seek>(
    path: &Path,
    reader: R,
    file_len: u64,
    options: &ReadOptions,
) -> Result<RawGrid, RasterError> {
    let to_error = |error| png_error(path, error);
    let limits = png::Limits {
        bytes: DECODER_LIMIT_BYTES,
    };
    let mut decoder = png::Decoder::new_with_limits(reader, limits);
    decoder.set_transformations(png::Transformations::EXPAND);

    // Only the IHDR chunk so far: check it before the decoder sizes any buffer.
    let header = decoder.read_header_info().map_err(to_error)?;
    let (width, height) = (u64::from(header.width), u64::from(header.height));
    let bits_per_pixel = header.color_type.samples() as u64 * header.bit_depth as u64;
    check_size(width, height)?;
    let width = checks::nonzero_side(path, width, "width")?;
    let height = checks::nonzero_side(path, height, "height")?;
    let filtered_bytes = ((width as u64 * bits_per_pixel).div_ceil(8) + 1) * height as u64;
    check_payload(path, filtered_bytes, file_len, MAX_DEFLATE_EXPANSION)?;

    let mut reader = decoder.read_info().map_err(to_error)?;
    let buffer_len = reader
        .output_buffer_size()
        .filter(|&len| len as u64 <= checks::MAX_SAMPLE_BYTES)
        .ok_or_else(|| RasterError::decode(path, "the decoded image does not fit in memory"))?;
    let mut buffer = vec![0; buffer_len];
    let frame = reader.next_frame(&mut buffer).map_err(to_error)?;
    // Reads up to IEND: catches truncation after the image data and picks up text chunks
    // placed after it.
    reader.finish().map_err(to_error)?;
    let bytes = &buffer[..frame.buffer_size()];
    let channels = frame.color_type.samples();
    let bytes_per_sample = match frame.bit_depth {
        BitDepth::Eight => 1,
        BitDepth::Sixteen => 2,
        other => {
            return Err(RasterError::decode(
                path,
                format!("{other:?}-bit samples are not supported"),
            ));
        }
    };
    let cells = width * height;
    if bytes.len() < cells * channels * bytes_per_sample {
        return Err(RasterError::decode(
            path,
            "the decoded image is smaller than its header says",
        ));
    }
    let pixels = Pixels {
        bytes,
        channels,
        bytes_per_sample,
    };
    let info = reader.info();
    let text = |keyword: &str| {
        info.uncompressed_latin1_text
            .iter()
            .find(|chunk| chunk.keyword == keyword)
            .map(|chunk| chunk.text.as_str())
    };
    let stretch = read_stretch(path, text(MIN_KEY), text(MAX_KEY))?;
    let cell_size_m = match text(CELL_SIZE_KEY) {
        Some(cell_size) => Some(checks::parse_cell_size(path, cell_size)?),
        None => sidecar_cell_size(path)?.map(|cell| [cell, cell]),
    };
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().to_lowercase())
        .unwrap_or_default();
    let terrarium = options.terrarium || name.contains("terrarium");
    let (format, sample_type, data) = match frame.color_type {
        ColorType::Rgb | ColorType::Rgba if terrarium => {
            if bytes_per_sample != 1 {
                return Err(RasterError::decode(
                    path,
                    "Terrarium PNG with 16-bit samples is not supported",
                ));
            }
            (SourceFormat::TerrariumPng, "rgb8", pixels.terrarium(cells))
        }
        ColorType::Rgb | ColorType::Rgba => {
            return Err(RasterError::decode(
                path,
                "an RGB PNG is read as heights only as Terrarium: put \"terrarium\" in its \
                 name (or set ReadOptions::terrarium)",
            ));
        }
        ColorType::Grayscale | ColorType::GrayscaleAlpha => {
            let sample_type = if bytes_per_sample == 2 {
                "uint16"
            } else {
                "uint8"
            };
            let data = pixels.grey(cells, stretch, options);
            (SourceFormat::GreyPng, sample_type, data)
        }
        ColorType::Indexed => {
            return Err(RasterError::decode(path, "palette PNG is not supported"));
        }
    };
    let mut source = Source::new(path.to_owned(), format, sample_type);
    if let Some(cell) = cell_size_m {
        source.native_cell_size = cell;
    }
    Ok(RawGrid {
        width,
        height,
        heights_m: data,
        cell_size_m,
        source,
    })
}

/// A decoded frame's samples.
struct Pixels<'a> {
    bytes: &'a [u8],
    channels: usize,
    bytes_per_sample: usize,
}

impl Pixels<'_> {
    /// Sample `c` of pixel `i`, as an integer of the image's bit depth.
    fn sample(&self, i: usize, c: usize) -> u32 {
        let at = (i * self.channels + c) * self.bytes_per_sample;
        match self.bytes_per_sample {
            1 => u32::from(self.bytes[at]),
            _ => u32::from(u16::from_be_bytes([self.bytes[at], self.bytes[at + 1]])),
        }
    }

    /// Terrarium heights of 8-bit RGB(A) pixels.
    fn terrarium(&self, cells: usize) -> Vec<f32> {
        (0..cells)
            .map(|i| {
                let [r, g, b] = [0, 1, 2].map(|c| self.sample(i, c) as f32);
                r * 256.0 + g + b / 256.0 - 32768.0
            })
            .collect()
    }

    /// Grey heights: codes of the stretch when there is one (255 * 257 = 65535: the 8-bit range
    /// covers the same stretch), else `offset + k * level`.
    fn grey(&self, cells: usize, stretch: Option<Stretch>, options: &ReadOptions) -> Vec<f32> {
        match stretch {
            Some(stretch) => {
                let full = if self.bytes_per_sample == 2 { 1 } else { 257 };
                (0..cells)
                    .map(|i| stretch.metres_from_code((self.sample(i, 0) * full) as u16))
                    .collect()
            }
            None => {
                let k = options.png_metres_per_level as f32;
                let offset = options.png_offset_m as f32;
                (0..cells)
                    .map(|i| offset + k * self.sample(i, 0) as f32)
                    .collect()
            }
        }
    }
}

/// The cell size from `NAME.json` beside `path`, if that file exists.
fn sidecar_cell_size(path: &Path) -> Result<Option<f64>, RasterError> {
    let sidecar = path.with_extension("json");
    let text = match std::fs::read(&sidecar) {
        Ok(bytes) if bytes.len() > SIDECAR_MAX_BYTES => {
            return Err(RasterError::decode(
                &sidecar,
                "the sidecar is over 1 MiB: not a cell-size file",
            ));
        }
        Ok(bytes) => bytes,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(e) => return Err(RasterError::io(&sidecar, e)),
    };
    let value: serde_json::Value = serde_json::from_slice(&text)
        .map_err(|e| RasterError::decode(&sidecar, format!("sidecar JSON: {e}")))?;
    match value.get("cell_size_m").and_then(serde_json::Value::as_f64) {
        Some(cell) if cell.is_finite() && cell > 0.0 => Ok(Some(cell)),
        _ => Err(RasterError::decode(
            &sidecar,
            "the sidecar has no positive number \"cell_size_m\"",
        )),
    }
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
        other => RasterError::decode(path, other.to_string()),
    }
}
