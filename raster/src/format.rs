//! File formats and how a path's extension picks one.

use std::path::Path;

use crate::RasterError;

/// The extensions [`Format::from_path`] accepts, for error messages.
pub(crate) const SUPPORTED_EXTENSIONS: &str = ".exr, .tif, .tiff, .png, .r16";

/// A heightmap file format. The extension of a path picks it (see [`Format::from_path`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Format {
    /// OpenEXR, one 32-bit float channel named `Y`, uncompressed scanlines. Exact.
    Exr,
    /// TIFF with one 32-bit IEEE float sample per pixel and GeoTIFF georeferencing tags. Exact.
    Tiff,
    /// PNG, 16-bit greyscale stretched over the data's range; the stretch and the cell size are
    /// stored in `tEXt` chunks. Quantised.
    Png16,
    /// Raw little-endian `u16`, no header, same stretch as [`Format::Png16`]. Quantised.
    R16,
}

impl Format {
    /// The format named by `path`'s extension, compared case-insensitively: `exr`, `tif`, `tiff`,
    /// `png`, `r16`. Any other extension, or none, is [`RasterError::UnsupportedExtension`].
    pub fn from_path(path: &Path) -> Result<Format, RasterError> {
        let extension = path
            .extension()
            .and_then(|extension| extension.to_str())
            .map(str::to_ascii_lowercase);
        match extension.as_deref() {
            Some("exr") => Ok(Format::Exr),
            Some("tif" | "tiff") => Ok(Format::Tiff),
            Some("png") => Ok(Format::Png16),
            Some("r16") => Ok(Format::R16),
            _ => Err(RasterError::UnsupportedExtension {
                path: path.to_path_buf(),
            }),
        }
    }

    /// The canonical extension for this format, without the dot (`"exr"`, `"tif"`, `"png"`,
    /// `"r16"`).
    pub fn extension(self) -> &'static str {
        match self {
            Format::Exr => "exr",
            Format::Tiff => "tif",
            Format::Png16 => "png",
            Format::R16 => "r16",
        }
    }
}
