//! The one reader: picks the format from the file's first bytes (TIFF, PNG, OpenEXR signatures,
//! an ESRI ASCII header), else from the extension (`.hgt` and `.r16` have no signature), decodes,
//! fills no-data holes and checks the bounds. A failure is one error naming the format the file
//! was read as.

use std::fs::File;
use std::io::{BufReader, Read, Seek, SeekFrom};
use std::path::Path;

use crate::source::{RawGrid, ReadOptions, SourceFormat};
use crate::{
    Heightmap, Raster, RasterError, asc_file, check_bounds, decode_guarded, exr_file, fill,
    hgt_file, png_file, r16_file, tiff_file,
};

/// What the file is read as.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum Kind {
    Tiff,
    Png,
    Exr,
    Asc,
    Hgt,
    R16,
}

impl Kind {
    fn name(self) -> &'static str {
        match self {
            Kind::Tiff => "GeoTIFF",
            Kind::Png => "PNG",
            Kind::Exr => "OpenEXR",
            Kind::Asc => "ESRI ASCII grid",
            Kind::Hgt => "SRTM .hgt",
            Kind::R16 => "R16",
        }
    }

    /// The kind a file's first bytes announce.
    fn from_magic(magic: &[u8]) -> Option<Kind> {
        let tiff = [b"II*\0", b"MM\0*", b"II+\0", b"MM\0+"];
        if tiff.iter().any(|m| magic.starts_with(*m)) {
            Some(Kind::Tiff)
        } else if magic.starts_with(b"\x89PNG\r\n\x1a\n") {
            Some(Kind::Png)
        } else if magic.starts_with(&[0x76, 0x2f, 0x31, 0x01]) {
            Some(Kind::Exr)
        } else if asc_file::looks_like_header(magic) {
            Some(Kind::Asc)
        } else {
            None
        }
    }

    /// The kind a path's extension names.
    fn from_extension(path: &Path) -> Option<Kind> {
        let extension = path.extension()?.to_str()?.to_ascii_lowercase();
        Some(match extension.as_str() {
            "tif" | "tiff" => Kind::Tiff,
            "png" => Kind::Png,
            "exr" => Kind::Exr,
            "asc" => Kind::Asc,
            "hgt" => Kind::Hgt,
            "r16" => Kind::R16,
            _ => return None,
        })
    }

    /// What a file of this kind starts with, for the error when it does not.
    fn signature(self) -> Option<&'static str> {
        match self {
            Kind::Tiff => Some("a TIFF signature (II*/MM*)"),
            Kind::Png => Some("the PNG signature"),
            Kind::Exr => Some("the OpenEXR magic number"),
            Kind::Asc => Some("an ncols/nrows header"),
            Kind::Hgt | Kind::R16 => None,
        }
    }
}

/// Reads any heightmap or DEM file: GeoTIFF / TIFF (any grey sample type, georeference and
/// no-data kept in [`crate::Source`]), PNG (16-bit with terrasketch's stretch chunks, grey
/// levels, Terrarium RGB), OpenEXR, SRTM `.hgt`, ESRI ASCII grid, square R16.
///
/// No-data cells (the declared value, SRTM voids, non-finite samples) are filled by a smooth
/// pull-push interpolation and marked in [`Raster::nodata_mask`]. The cell size is converted to
/// metres (geographic grids at their centre latitude); `options.cell_size_m` overrides it.
/// The result passes [`check_bounds`].
///
/// Errors: [`RasterError::Io`] when the file cannot be opened; [`RasterError::UnknownFormat`]
/// when neither content nor extension names a format; otherwise one error naming the format
/// the file was read as ([`RasterError::Decode`], [`RasterError::MissingCellSize`],
/// [`RasterError::AllNoData`], [`RasterError::TooLarge`], [`RasterError::OutOfBounds`]).
pub fn read_raster(path: &Path, options: &ReadOptions) -> Result<Raster, RasterError> {
    if let Some(cell) = options.cell_size_m
        && !(cell.is_finite() && cell > 0.0)
    {
        return Err(RasterError::InvalidCellSize {
            cell_size_m: [cell, cell],
        });
    }
    let mut file = File::open(path).map_err(|source| RasterError::io(path, source))?;
    let file_len = file
        .metadata()
        .map_err(|source| RasterError::io(path, source))?
        .len();
    let mut magic = [0u8; 8];
    let magic_len = read_up_to(&mut file, &mut magic).map_err(|e| RasterError::io(path, e))?;
    file.seek(SeekFrom::Start(0))
        .map_err(|e| RasterError::io(path, e))?;
    let by_content = Kind::from_magic(&magic[..magic_len]);
    let by_extension = Kind::from_extension(path);
    let kind = match (by_content, by_extension) {
        (Some(kind), _) => kind,
        (None, Some(kind)) => {
            if let Some(signature) = kind.signature() {
                return Err(RasterError::decode(
                    path,
                    format!("the file does not start with {signature}"),
                )
                .read_as(path, kind.name()));
            }
            kind
        }
        (None, None) => {
            return Err(RasterError::UnknownFormat {
                path: path.to_path_buf(),
            });
        }
    };
    decode_guarded(path, || decode(path, kind, file, file_len, options))
        .and_then(|raw| finish(path, raw, kind.name(), options))
        .map_err(|e| e.read_as(path, kind.name()))
}

/// Decodes `file` as `kind`.
fn decode(
    path: &Path,
    kind: Kind,
    file: File,
    file_len: u64,
    options: &ReadOptions,
) -> Result<RawGrid, RasterError> {
    match kind {
        Kind::Tiff => tiff_file::decode(path, BufReader::new(file), file_len),
        Kind::Png => png_file::decode(path, BufReader::new(file), file_len, options),
        Kind::Exr => exr_file::decode(path, BufReader::new(file), file_len),
        Kind::Asc => asc_file::read(path, file, file_len, options),
        Kind::Hgt => hgt_file::read(path, file_len),
        Kind::R16 => {
            let side = r16_file::square_side(path, file_len)?;
            let map = r16_file::decode(path, BufReader::new(file), file_len, [side, side], None)?;
            Ok(RawGrid {
                width: map.width,
                height: map.height,
                heights_m: map.data,
                cell_size_m: None,
                source: crate::Source::new(path.to_owned(), SourceFormat::R16, "uint16"),
            })
        }
    }
}

/// Settles the cell size, fills the holes and checks the bounds.
fn finish(
    path: &Path,
    mut raw: RawGrid,
    format: &'static str,
    options: &ReadOptions,
) -> Result<Raster, RasterError> {
    let cell_size_m = match (options.cell_size_m, raw.cell_size_m) {
        (Some(cell), _) => [cell, cell],
        (None, Some(cell)) => cell,
        (None, None) if options.unit_cells_when_absent => {
            raw.source
                .warnings
                .push("the file gives no cell size: 1 m cells assumed".into());
            [1.0, 1.0]
        }
        (None, None) => {
            return Err(RasterError::MissingCellSize {
                path: path.to_path_buf(),
                format,
            });
        }
    };
    if !cell_size_m.iter().all(|c| c.is_finite() && *c > 0.0) {
        return Err(RasterError::InvalidCellSize { cell_size_m });
    }
    let nodata_mask: Vec<bool> = if raw.heights_m.iter().any(|h| !h.is_finite()) {
        raw.heights_m.iter().map(|h| !h.is_finite()).collect()
    } else {
        Vec::new()
    };
    if fill::fill_holes(raw.width, raw.height, &mut raw.heights_m).is_none() {
        return Err(RasterError::AllNoData {
            path: path.to_path_buf(),
            format,
        });
    }
    let map = Heightmap {
        width: raw.width,
        height: raw.height,
        data: raw.heights_m,
        cell_size_m,
    };
    check_bounds(path, &map)?;
    Ok(Raster {
        map,
        source: raw.source,
        nodata_mask,
    })
}

fn read_up_to(reader: &mut impl Read, buf: &mut [u8]) -> std::io::Result<usize> {
    let mut filled = 0;
    while filled < buf.len() {
        match reader.read(&mut buf[filled..])? {
            0 => break,
            n => filled += n,
        }
    }
    Ok(filled)
}
