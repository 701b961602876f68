//! R16: raw little-endian `u16` codes, row-major, row 0 first, no header. The dimensions and
//! the stretch travel outside the file.

use std::io::Read;
use std::path::Path;

use crate::checks::{self, check_size};
use crate::{Heightmap, RasterError, Stretch};

/// Encodes `map` (already validated) as little-endian codes of `stretch`.
pub(crate) fn encode(map: &Heightmap, stretch: Stretch) -> Vec<u8> {
    let mut bytes = Vec::with_capacity(map.data.len() * 2);
    for &height_m in &map.data {
        bytes.extend_from_slice(&stretch.code_from_metres(height_m).to_le_bytes());
    }
    bytes
}

/// Decodes a `width x height` R16 file of `file_len` bytes; in metres with `stretch`, else as
/// raw code values. The file must hold exactly `width * height` codes.
pub(crate) fn decode(
    path: &Path,
    reader: impl Read,
    file_len: u64,
    [width, height]: [usize; 2],
    stretch: Option<Stretch>,
) -> Result<Heightmap, RasterError> {
    check_size(width as u64, height as u64)?;
    if width == 0 || height == 0 {
        return Err(RasterError::BadShape {
            width,
            height,
            len: 0,
        });
    }
    if let Some(stretch) = stretch.filter(|stretch| !stretch.is_valid()) {
        return Err(RasterError::decode(
            path,
            format!("invalid stretch {stretch:?}: expected finite ends with min_m <= max_m"),
        ));
    }
    let expected_len = (width * height) as u64 * 2;
    if file_len != expected_len {
        return Err(RasterError::decode(
            path,
            format!(
                "a {width} x {height} R16 file has {expected_len} bytes, this one has {file_len}"
            ),
        ));
    }

    let mut bytes = vec![0; width * height * 2];
    reader
        .take(expected_len)
        .read_exact(&mut bytes)
        .map_err(|source| RasterError::from_read(path, source))?;
    let codes = bytes
        .chunks_exact(2)
        .map(|pair| u16::from_le_bytes([pair[0], pair[1]]));
    let data = match stretch {
        Some(stretch) => codes.map(|code| stretch.metres_from_code(code)).collect(),
        None => codes.map(f32::from).collect(),
    };
    Ok(Heightmap {
        width,
        height,
        data,
        cell_size_m: [1.0, 1.0],
    })
}

/// The side of a square R16 file of `file_len` bytes, refusing lengths that are not twice a
/// perfect square.
pub(crate) fn square_side(path: &Path, file_len: u64) -> Result<usize, RasterError> {
    let codes = file_len / 2;
    let side = codes.isqrt();
    if !file_len.is_multiple_of(2) || side * side != codes || side == 0 {
        return Err(RasterError::decode(
            path,
            format!(
                "a {file_len}-byte R16 file is not a square of 16-bit samples; read it with \
                 read_r16 and explicit dimensions"
            ),
        ));
    }
    check_size(side, side)?;
    checks::nonzero_side(path, side, "side")
}
