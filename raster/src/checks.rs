//! Size limits for hostile headers and validation of maps before they are written.

use std::path::Path;

use crate::{Heightmap, RasterError};

/// Largest accepted side, in cells, of any raster read or written.
pub const MAX_SIDE: usize = 65536;

/// Largest accepted raster, in bytes of `f32` samples (4 GiB).
pub(crate) const MAX_SAMPLE_BYTES: u64 = 4 << 30;
/// Largest accepted raster, in cells (4 GiB of `f32`).
pub const MAX_CELLS: usize = (MAX_SAMPLE_BYTES / 4) as usize;

/// Largest accepted height magnitude in a heightmap read from a file, metres (100 km).
pub const MAX_ABS_HEIGHT_M: f32 = 100_000.0;
/// Smallest accepted cell size of a heightmap read from a file, metres (1 cm).
pub const MIN_CELL_SIZE_M: f64 = 0.01;
/// Largest accepted extent (cells times cell size) of a heightmap read from a file, metres
/// (40,000 km).
pub const MAX_EXTENT_M: f64 = 40_000_000.0;

/// Refuses a heightmap read from `path` whose heights are not finite or lie past
/// +-[`MAX_ABS_HEIGHT_M`] (the first such sample is named by row and column), whose cell is
/// smaller than [`MIN_CELL_SIZE_M`] or whose extent is larger than [`MAX_EXTENT_M`].
pub fn check_bounds(path: &Path, map: &Heightmap) -> Result<(), RasterError> {
    let out = |field: String, value: f64, allowed| RasterError::OutOfBounds {
        path: path.to_path_buf(),
        format: "",
        field,
        value,
        allowed,
    };
    for (axis, cell_m, cells) in [
        ("x", map.cell_size_m[0], map.width),
        ("y", map.cell_size_m[1], map.height),
    ] {
        // Written so that NaN fails the test.
        if !(MIN_CELL_SIZE_M..).contains(&cell_m) {
            return Err(out(
                format!("cell size {axis} (m)"),
                cell_m,
                "0.01 m (1 cm) or more",
            ));
        }
        let extent_m = cell_m * cells as f64;
        if !(..=MAX_EXTENT_M).contains(&extent_m) {
            return Err(out(
                format!("extent {axis} ({cells} cells x {cell_m} m)"),
                extent_m,
                "up to 40000000 m (40,000 km)",
            ));
        }
    }
    let bad = map
        .data
        .iter()
        .position(|height_m| !(-MAX_ABS_HEIGHT_M..=MAX_ABS_HEIGHT_M).contains(height_m));
    if let Some(index) = bad {
        let (row, column) = (index / map.width.max(1), index % map.width.max(1));
        return Err(out(
            format!("height at row {row}, column {column} (m)"),
            f64::from(map.data[index]),
            "finite, -100000 to 100000 m (+-100 km)",
        ));
    }
    Ok(())
}

/// Refuses `width x height` rasters over [`MAX_SIDE`] on a side or over [`MAX_SAMPLE_BYTES`] of
/// `f32` samples. Call it on header values before allocating anything of that size.
pub(crate) fn check_size(width: u64, height: u64) -> Result<(), RasterError> {
    let max_side = MAX_SIDE as u64;
    let too_large = width > max_side
        || height > max_side
        || width.saturating_mul(height).saturating_mul(4) > MAX_SAMPLE_BYTES;
    if too_large {
        return Err(RasterError::TooLarge {
            width: usize::try_from(width).unwrap_or(usize::MAX),
            height: usize::try_from(height).unwrap_or(usize::MAX),
            read_as: None,
        });
    }
    Ok(())
}

/// Refuses a header whose `raw_bytes` of pixel data cannot come out of a `file_len`-byte file
/// whose codec expands its input at most `max_expansion` times (1 for uncompressed data).
pub(crate) fn check_payload(
    path: &Path,
    raw_bytes: u64,
    file_len: u64,
    max_expansion: u64,
) -> Result<(), RasterError> {
    if raw_bytes > file_len.saturating_mul(max_expansion) {
        return Err(RasterError::decode(
            path,
            format!(
                "the header claims {raw_bytes} bytes of pixel data, which a {file_len}-byte file \
                 cannot hold (truncated or corrupt)"
            ),
        ));
    }
    Ok(())
}

/// A dimension from a header as `usize`, refusing zero (an empty raster is not a heightmap).
pub(crate) fn nonzero_side(path: &Path, value: u64, what: &str) -> Result<usize, RasterError> {
    match usize::try_from(value) {
        Ok(0) => Err(RasterError::decode(
            path,
            format!("the image {what} is zero"),
        )),
        Ok(side) => Ok(side),
        Err(_) => Err(RasterError::decode(
            path,
            format!("the image {what} {value} is too large"),
        )),
    }
}

/// Checks everything every encoder relies on: size limits, shape, finite samples and a usable
/// cell size.
pub(crate) fn check_writable(map: &Heightmap) -> Result<(), RasterError> {
    check_size(map.width as u64, map.height as u64)?;
    let cells = map.width.checked_mul(map.height);
    if map.width == 0 || map.height == 0 || cells != Some(map.data.len()) {
        return Err(RasterError::BadShape {
            width: map.width,
            height: map.height,
            len: map.data.len(),
        });
    }
    if let Some(index) = map.data.iter().position(|height_m| !height_m.is_finite()) {
        return Err(RasterError::NonFinite { index });
    }
    let [cell_x_m, cell_y_m] = map.cell_size_m;
    let usable = |cell_m: f64| cell_m.is_finite() && cell_m > 0.0;
    if !usable(cell_x_m) || !usable(cell_y_m) {
        return Err(RasterError::encode(format!(
            "cell size must be finite and positive, got [{cell_x_m}, {cell_y_m}] m"
        )));
    }
    Ok(())
}

/// Formats a cell size as the `"x y"` text stored in PNG and EXR metadata (shortest form that
/// parses back to the same `f64`).
pub(crate) fn cell_size_text(cell_size_m: [f64; 2]) -> String {
    format!("{} {}", cell_size_m[0], cell_size_m[1])
}

/// Parses the `"x y"` cell size text, refusing anything but two finite positive numbers.
pub(crate) fn parse_cell_size(path: &Path, text: &str) -> Result<[f64; 2], RasterError> {
    let mut parts = text.split_ascii_whitespace().map(str::parse::<f64>);
    match (parts.next(), parts.next(), parts.next()) {
        (Some(Ok(x)), Some(Ok(y)), None)
            if x.is_finite() && y.is_finite() && x > 0.0 && y > 0.0 =>
        {
            Ok([x, y])
        }
        _ => Err(RasterError::decode(
            path,
            format!("invalid cell size metadata {text:?}: expected two positive numbers \"x y\""),
        )),
    }
}
