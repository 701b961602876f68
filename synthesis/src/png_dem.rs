//! PNG readers: grey (8 or 16 bit) heights and Terrarium RGB tiles.
//!
//! PNG carries no georeference, so the cell size comes from `LoadOptions::cell_size_m` or from a
//! sidecar `NAME.json` next to the image, `{"cell_size_m": 61.76}` (other keys are ignored).
//! An RGB(A) PNG is decoded as Terrarium (`h = R * 256 + G + B / 256 - 32768`) when
//! `LoadOptions::terrarium` is set or the file name contains "terrarium".

use std::fs::File;
use std::io::BufReader;
use std::path::Path;

use png::{BitDepth, ColorType, Transformations};

use crate::{
    DemError, DemFormat, DemSource, HorizontalUnits, LoadOptions, RawGrid, check_grid_size,
};

/// Equatorial circumference used by web-map (EPSG:3857) tiles, in metres.
const WEB_MERCATOR_CIRCUMFERENCE_M: f64 = 40_075_016.686;
/// Pixels per side of a web-map tile.
const WEB_TILE_PIXELS: f64 = 256.0;

/// Ground size in metres of one pixel of a 256-pixel web-map tile at `zoom`, row `tile_y`, taken
/// at the latitude of the tile's centre: `40 075 016.686 m * cos(lat) / 2^zoom / 256`. The same in
/// x and y (Mercator is conformal).
pub fn web_mercator_cell_size_m(zoom: u32, tile_y: u32) -> f64 {
    let tiles = 2f64.powi(zoom as i32);
    let y = (f64::from(tile_y) + 0.5) / tiles;
    let lat = (std::f64::consts::PI * (1.0 - 2.0 * y)).sinh().atan();
    WEB_MERCATOR_CIRCUMFERENCE_M * lat.cos() / tiles / WEB_TILE_PIXELS
}

/// Reads a grey or Terrarium PNG.
pub(crate) fn read(path: &Path, opts: &LoadOptions) -> Result<RawGrid, DemError> {
    let png_err = |e: png::DecodingError| match e {
        png::DecodingError::IoError(e) => DemError::io(path, e),
        other => DemError::malformed(path, other.to_string()),
    };
    let file = File::open(path).map_err(|e| DemError::io(path, e))?;
    let mut decoder = png::Decoder::new(BufReader::new(file));
    // Palette and sub-byte grey to 8 bit; 16-bit samples stay 16 bit.
    decoder.set_transformations(Transformations::EXPAND);
    let header = decoder.read_header_info().map_err(png_err)?;
    let (width, height) = (header.width as usize, header.height as usize);
    check_grid_size(path, width as u64, height as u64)?;

    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().to_lowercase())
        .unwrap_or_default();
    let terrarium = opts.terrarium || name.contains("terrarium");
    let cell = match opts.cell_size_m {
        Some(cell) => cell,
        None => sidecar_cell_size(path)?.ok_or_else(|| DemError::MissingCellSize {
            path: path.to_owned(),
        })?,
    };

    let mut reader = decoder.read_info().map_err(png_err)?;
    let len = reader
        .output_buffer_size()
        .ok_or_else(|| DemError::malformed(path, "image too large"))?;
    let mut buf = vec![0u8; len];
    let frame = reader.next_frame(&mut buf).map_err(png_err)?;
    let bytes = &buf[..frame.buffer_size()];
    let channels = frame.color_type.samples();
    let bytes_per_sample = match frame.bit_depth {
        BitDepth::Eight => 1,
        BitDepth::Sixteen => 2,
        other => return Err(DemError::unsupported(path, format!("{other:?} samples"))),
    };
    // Sample `c` of pixel `i`, as an integer of the image's bit depth.
    let sample = |i: usize, c: usize| -> u32 {
        let at = (i * channels + c) * bytes_per_sample;
        match bytes_per_sample {
            1 => u32::from(bytes[at]),
            _ => u32::from(u16::from_be_bytes([bytes[at], bytes[at + 1]])),
        }
    };
    if bytes.len() < width * height * channels * bytes_per_sample {
        return Err(DemError::malformed(
            path,
            "decoded image is smaller than its header says",
        ));
    }
    let (format, sample_type, heights): (_, _, Vec<f32>) = match frame.color_type {
        ColorType::Rgb | ColorType::Rgba if terrarium => {
            if bytes_per_sample != 1 {
                return Err(DemError::unsupported(
                    path,
                    "Terrarium PNG with 16-bit samples",
                ));
            }
            let h = (0..width * height)
                .map(|i| {
                    let (r, g, b) = (
                        sample(i, 0) as f32,
                        sample(i, 1) as f32,
                        sample(i, 2) as f32,
                    );
                    r * 256.0 + g + b / 256.0 - 32768.0
                })
                .collect();
            (DemFormat::TerrariumPng, "rgb8", h)
        }
        ColorType::Rgb | ColorType::Rgba => {
            return Err(DemError::unsupported(
                path,
                "RGB PNG: set LoadOptions::terrarium (or put \"terrarium\" in the name) to decode it as Terrarium",
            ));
        }
        ColorType::Grayscale | ColorType::GrayscaleAlpha => {
            let (k, offset) = (opts.png_metres_per_level as f32, opts.png_offset_m as f32);
            let h = (0..width * height)
                .map(|i| offset + k * sample(i, 0) as f32)
                .collect();
            let sample_type = if bytes_per_sample == 2 {
                "uint16"
            } else {
                "uint8"
            };
            (DemFormat::GreyPng, sample_type, h)
        }
        ColorType::Indexed => return Err(DemError::unsupported(path, "palette PNG")),
    };
    let source = DemSource {
        path: path.to_owned(),
        format,
        sample_type,
        horizontal_units: HorizontalUnits::Metres,
        native_cell_size: [cell, cell],
        centre_lat_deg: None,
        nodata: None,
        rows_flipped: false,
        warnings: Vec::new(),
    };
    Ok(RawGrid {
        width,
        height,
        heights_m: heights,
        cell_size_m: [cell, cell],
        source,
    })
}

/// The cell size from `NAME.json` beside `path`, if that file exists.
fn sidecar_cell_size(path: &Path) -> Result<Option<f64>, DemError> {
    let sidecar = path.with_extension("json");
    let text = match std::fs::read_to_string(&sidecar) {
        Ok(text) => text,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(e) => return Err(DemError::io(&sidecar, e)),
    };
    let value: serde_json::Value =
        serde_json::from_str(&text).map_err(|e| DemError::malformed(&sidecar, e.to_string()))?;
    match value.get("cell_size_m").and_then(serde_json::Value::as_f64) {
        Some(cell) => Ok(Some(cell)),
        None => Err(DemError::malformed(&sidecar, "no number \"cell_size_m\"")),
    }
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
