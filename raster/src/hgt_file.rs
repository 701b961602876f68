//! SRTM `.hgt` reader: raw big-endian `i16`, row 0 = north, 1201x1201 (3 arc-seconds) or
//! 3601x3601 (1 arc-second) cells covering one degree; voids are -32768. The south-west corner is
//! in the file name (`N37W120.hgt`, also `n37w120.SRTMGL1.hgt`).

use std::path::Path;

use crate::RasterError;
use crate::source::{HorizontalUnits, RawGrid, Source, SourceFormat, degrees_to_metres};

/// The SRTM void value.
pub(crate) const SRTM_VOID: i16 = -32768;
const SIDES: [usize; 2] = [1201, 3601];

/// Reads an `.hgt` tile of `len` bytes. The latitude comes from the file name; without one the
/// cell size is unknown (`None`).
pub(crate) fn read(path: &Path, len: u64) -> Result<RawGrid, RasterError> {
    let Some(side) = SIDES.into_iter().find(|&n| (n * n * 2) as u64 == len) else {
        return Err(RasterError::decode(
            path,
            format!("{len} bytes; an .hgt tile has 2*1201^2 or 2*3601^2 bytes"),
        ));
    };
    let corner = path
        .file_name()
        .and_then(|n| n.to_str())
        .and_then(parse_corner);
    let bytes = std::fs::read(path).map_err(|e| RasterError::from_read(path, e))?;
    if bytes.len() != side * side * 2 {
        return Err(RasterError::decode(
            path,
            "the file changed size while being read",
        ));
    }
    let heights = bytes
        .chunks_exact(2)
        .map(|b| match i16::from_be_bytes([b[0], b[1]]) {
            SRTM_VOID => f32::NAN,
            h => f32::from(h),
        })
        .collect();
    let step_deg = 1.0 / (side - 1) as f64;
    let centre_lat = corner.map(|(lat0, _lon0)| lat0 + 0.5);
    let cell_size_m = centre_lat.map(|lat| degrees_to_metres([step_deg, step_deg], lat));
    let mut source = Source::new(path.to_owned(), SourceFormat::SrtmHgt, "int16");
    source.horizontal_units = HorizontalUnits::Degrees;
    source.native_cell_size = [step_deg, step_deg];
    source.centre_lat_deg = centre_lat;
    source.nodata = Some(f64::from(SRTM_VOID));
    if corner.is_none() {
        source
            .warnings
            .push("the name does not start with the tile corner (like N37W120)".into());
    }
    Ok(RawGrid {
        width: side,
        height: side,
        heights_m: heights,
        cell_size_m,
        source,
    })
}

/// Parses `N37W120...` into (south latitude, west longitude) in degrees.
pub(crate) fn parse_corner(name: &str) -> Option<(f64, f64)> {
    let b = name.as_bytes();
    if b.len() < 7 || !b[1..3].iter().chain(&b[4..7]).all(u8::is_ascii_digit) {
        return None;
    }
    let lat: f64 = name[1..3].parse().ok()?;
    let lon: f64 = name[4..7].parse().ok()?;
    let lat = match b[0].to_ascii_uppercase() {
        b'N' => lat,
        b'S' => -lat,
        _ => return None,
    };
    let lon = match b[3].to_ascii_uppercase() {
        b'E' => lon,
        b'W' => -lon,
        _ => return None,
    };
    (lat.abs() < 90.0 && lon.abs() <= 180.0).then_some((lat, lon))
}

#[cfg(test)]
mod tests {
    use super::parse_corner;

    #[test]
    fn corner_names() {
        assert_eq!(parse_corner("N37W120.hgt"), Some((37.0, -120.0)));
        assert_eq!(parse_corner("s05e011.SRTMGL1.hgt"), Some((-5.0, 11.0)));
        assert_eq!(parse_corner("N37X120.hgt"), None);
        assert_eq!(parse_corner("N3"), None);
        assert_eq!(parse_corner("N99W120.hgt"), None);
    }
}
