//! ESRI ASCII grid reader.
//!
//! Header lines `KEY value` (keys case-insensitive): `ncols`, `nrows`, `xllcorner` or
//! `xllcenter`, `yllcorner` or `yllcenter`, `cellsize` (or GDAL's `dx` and `dy`), optional
//! `NODATA_value`; then `nrows * ncols` numbers, row 0 = north. The format does not state units:
//! the cell size is metres unless `LoadOptions::asc_units` says degrees.

use std::fs::File;
use std::io::{BufRead, BufReader, Read};
use std::path::Path;

use crate::RasterError;
use crate::checks::{self, check_size};
use crate::fill::mark_holes;
use crate::source::{
    HorizontalUnits, RawGrid, ReadOptions, Source, SourceFormat, degrees_to_metres,
};

/// Longest header line accepted; protects against a binary file without newlines.
const MAX_HEADER_LINE: u64 = 256;

/// True if `start` (the first bytes of a file) looks like an ESRI ASCII grid header.
pub(crate) fn looks_like_header(start: &[u8]) -> bool {
    let text = String::from_utf8_lossy(start).to_ascii_lowercase();
    let text = text.trim_start();
    ["ncols", "nrows"].iter().any(|k| text.starts_with(k))
}

#[derive(Default)]
struct Header {
    ncols: Option<u64>,
    nrows: Option<u64>,
    yll: Option<f64>,
    y_is_centre: bool,
    cell: Option<[f64; 2]>,
    nodata: Option<f64>,
}

/// Reads an ESRI ASCII grid.
pub(crate) fn read(
    path: &Path,
    file: File,
    file_len: u64,
    opts: &ReadOptions,
) -> Result<RawGrid, RasterError> {
    let mut reader = BufReader::new(file);
    let (header, first_values) = read_header(path, &mut reader)?;
    let missing = |what: &str| RasterError::decode(path, format!("header has no {what}"));
    let ncols = header.ncols.ok_or_else(|| missing("ncols"))?;
    let nrows = header.nrows.ok_or_else(|| missing("nrows"))?;
    check_size(ncols, nrows)?;
    let width = checks::nonzero_side(path, ncols, "ncols")?;
    let height = checks::nonzero_side(path, nrows, "nrows")?;
    // Every value takes at least one character and one separator.
    checks::check_payload(path, ncols * nrows, file_len / 2 + 1, 1)?;
    let native = header.cell.ok_or_else(|| missing("cellsize"))?;

    // The first data line may have been cut at MAX_HEADER_LINE: append the rest before splitting.
    let mut values = first_values;
    reader
        .read_to_string(&mut values)
        .map_err(|e| RasterError::decode(path, e.to_string()))?;
    let mut heights = Vec::with_capacity(width * height);
    for word in values.split_ascii_whitespace() {
        if heights.len() == width * height {
            return Err(RasterError::decode(path, "more values than ncols * nrows"));
        }
        let h: f64 = word
            .parse()
            .map_err(|_| RasterError::decode(path, format!("bad height {word:?}")))?;
        heights.push(if Some(h) == header.nodata {
            f32::NAN
        } else {
            h as f32
        });
    }
    if heights.len() != width * height {
        return Err(RasterError::decode(
            path,
            format!(
                "{} values, expected {} (truncated?)",
                heights.len(),
                width * height
            ),
        ));
    }
    mark_holes(&mut heights, header.nodata);

    let (cell_size_m, centre_lat_deg) = match opts.asc_units {
        HorizontalUnits::Metres => (native, None),
        HorizontalUnits::Degrees => {
            let yll = header.yll.ok_or_else(|| missing("yllcorner"))?;
            let rows_to_mid = if header.y_is_centre {
                (height as f64 - 1.0) / 2.0
            } else {
                height as f64 / 2.0
            };
            let lat = yll + rows_to_mid * native[1];
            if !(-90.0..=90.0).contains(&lat) {
                return Err(RasterError::decode(
                    path,
                    format!("centre latitude {lat} is not on Earth"),
                ));
            }
            (degrees_to_metres(native, lat), Some(lat))
        }
    };
    let mut source = Source::new(path.to_owned(), SourceFormat::EsriAsciiGrid, "text");
    source.horizontal_units = opts.asc_units;
    source.native_cell_size = native;
    source.centre_lat_deg = centre_lat_deg;
    source.nodata = header.nodata;
    Ok(RawGrid {
        width,
        height,
        heights_m: heights,
        cell_size_m: Some(cell_size_m),
        source,
    })
}

/// Reads the header lines; returns them and the first data line (which ends the header).
fn read_header(path: &Path, reader: &mut BufReader<File>) -> Result<(Header, String), RasterError> {
    let mut header = Header::default();
    let mut first_values = String::new(); // the header loop reads the first data line too
    let mut line = String::new();
    loop {
        line.clear();
        let n = (&mut *reader)
            .take(MAX_HEADER_LINE)
            .read_line(&mut line)
            .map_err(|e| RasterError::decode(path, format!("header: {e}")))?;
        if n == 0 {
            return Err(RasterError::decode(path, "file ends inside the header"));
        }
        let mut words = line.split_whitespace();
        let Some(key) = words.next() else { continue };
        if key.starts_with(|c: char| c.is_ascii_digit() || c == '-' || c == '+' || c == '.') {
            first_values.push_str(&line); // the first data row
            break;
        }
        let value = words
            .next()
            .ok_or_else(|| RasterError::decode(path, format!("no value for {key}")))?;
        let bad = || RasterError::decode(path, format!("bad value {value:?} for {key}"));
        let number = || value.parse::<f64>().map_err(|_| bad());
        match key.to_ascii_lowercase().as_str() {
            "ncols" => header.ncols = Some(value.parse().map_err(|_| bad())?),
            "nrows" => header.nrows = Some(value.parse().map_err(|_| bad())?),
            "xllcorner" | "xllcenter" => {
                number()?;
            }
            "yllcorner" => header.yll = Some(number()?),
            "yllcenter" => (header.yll, header.y_is_centre) = (Some(number()?), true),
            "cellsize" => header.cell = Some([number()?; 2]),
            "dx" => header.cell = Some([number()?, header.cell.map_or(f64::NAN, |c| c[1])]),
            "dy" => header.cell = Some([header.cell.map_or(f64::NAN, |c| c[0]), number()?]),
            "nodata_value" => header.nodata = Some(number()?),
            other => {
                return Err(RasterError::decode(
                    path,
                    format!("unknown header key {other:?}"),
                ));
            }
        }
    }
    Ok((header, first_values))
}
