//! The one error type of this crate.

use std::io;
use std::path::{Path, PathBuf};

/// Everything that can go wrong while reading or writing a heightmap.
///
/// Messages are written for people: they name the file, the limit or the sample involved.
#[derive(Debug, thiserror::Error)]
pub enum RasterError {
    /// The file system refused an operation (open, create, write, fsync, rename).
    #[error("I/O error on '{}': {error}", path.display())]
    Io {
        /// The file the operation was about (for writes: the target, not the temporary file).
        path: PathBuf,
        /// What the operating system said (in the message, not as a separate source, so that a
        /// chain of causes prints it once).
        error: io::Error,
    },

    /// The path's extension does not name a format this crate knows.
    #[error(
        "unsupported heightmap extension for '{}': expected one of {}",
        path.display(),
        crate::format::SUPPORTED_EXTENSIONS
    )]
    UnsupportedExtension {
        /// The path that was given.
        path: PathBuf,
    },

    /// A file to read is none of the formats this crate reads, by content or by extension.
    #[error(
        "cannot read '{}': not a heightmap or DEM file (by content: TIFF, PNG, OpenEXR, ESRI \
         ASCII grid; by extension: {}, .hgt, .asc)",
        path.display(),
        crate::format::SUPPORTED_EXTENSIONS
    )]
    UnknownFormat {
        /// The path that was given.
        path: PathBuf,
    },

    /// The file is not a valid heightmap of the format it was read as (corrupt, truncated, or an
    /// unsupported variant of the format).
    #[error("cannot read '{}' as {format}: {msg}", path.display())]
    Decode {
        /// The file being read.
        path: PathBuf,
        /// The format it was read as ("GeoTIFF", "PNG", ...).
        format: &'static str,
        /// What was wrong with it.
        msg: String,
    },

    /// The file gives no cell size and none was given.
    #[error(
        "cannot read '{}' as {format}: the file gives no cell size; give one (--cell-size, \
         ReadOptions::cell_size_m) or, for a PNG, a sidecar {} with {{\"cell_size_m\": ...}}",
        path.display(),
        path.with_extension("json").display()
    )]
    MissingCellSize {
        /// The file.
        path: PathBuf,
        /// The format it was read as.
        format: &'static str,
    },

    /// Every cell of the file is no-data: there is nothing to fill the holes from.
    #[error("cannot read '{}' as {format}: every cell is no-data", path.display())]
    AllNoData {
        /// The file.
        path: PathBuf,
        /// The format it was read as.
        format: &'static str,
    },

    /// A cell size is zero, negative or not finite.
    #[error("invalid cell size {cell_size_m:?} m: expected finite positive numbers")]
    InvalidCellSize {
        /// The offending cell size in metres.
        cell_size_m: [f64; 2],
    },

    /// The encoder of a format refused the heightmap.
    #[error("cannot encode heightmap: {msg}")]
    Encode {
        /// What the encoder or the validation said.
        msg: String,
    },

    /// The raster is larger than [`crate::MAX_SIDE`] on a side or holds more than 4 GiB of `f32`
    /// samples. Checked before anything of that size is allocated.
    #[error(
        "{}{width} x {height} raster is too large (limit: {} cells per side and 4 GiB of f32 samples)",
        read_prefix(read_as),
        crate::MAX_SIDE
    )]
    TooLarge {
        /// Columns claimed by the header or the caller.
        width: usize,
        /// Rows claimed by the header or the caller.
        height: usize,
        /// On a read, the file and the format it was read as; `None` on a write.
        read_as: Option<(PathBuf, &'static str)>,
    },

    /// The heightmap holds a NaN or an infinity; writing it would produce garbage.
    #[error(
        "height sample {index} (row-major index) is not finite (NaN or infinity); refusing to write"
    )]
    NonFinite {
        /// Row-major index of the first non-finite sample (`row * width + column`).
        index: usize,
    },

    /// A heightmap read from a file holds a number past the accepted bounds (a height beyond
    /// +-100 km, a cell below 1 cm, an extent past 40,000 km).
    #[error(
        "{}{field} is {value}, allowed: {allowed}",
        read_prefix(&Some((path.clone(), *format)))
    )]
    OutOfBounds {
        /// The file read.
        path: PathBuf,
        /// The format it was read as (empty when not known).
        format: &'static str,
        /// What the number is, e.g. `height at row 3, column 7 (m)` or `cell size x (m)`.
        field: String,
        /// The offending value.
        value: f64,
        /// The accepted range in words.
        allowed: &'static str,
    },

    /// The heightmap's `width`, `height` and `data.len()` do not agree, or a side is zero.
    #[error(
        "heightmap shape {width} x {height} does not match its {len} samples \
         (sides must be non-zero and width * height must equal the sample count)"
    )]
    BadShape {
        /// The map's `width`.
        width: usize,
        /// The map's `height`.
        height: usize,
        /// The map's `data.len()`.
        len: usize,
    },
}

impl RasterError {
    /// A [`RasterError::Decode`] for `path`; the reader's dispatch fills in the format.
    pub(crate) fn decode(path: &Path, msg: impl Into<String>) -> Self {
        RasterError::Decode {
            path: path.to_path_buf(),
            format: "",
            msg: msg.into(),
        }
    }

    /// Names the format of an error raised while reading `path` as `name`.
    pub(crate) fn read_as(mut self, path: &Path, name: &'static str) -> Self {
        match &mut self {
            RasterError::Decode { format, .. } | RasterError::OutOfBounds { format, .. }
                if format.is_empty() =>
            {
                *format = name;
            }
            RasterError::TooLarge { read_as, .. } if read_as.is_none() => {
                *read_as = Some((path.to_path_buf(), name));
            }
            _ => {}
        }
        self
    }

    /// A [`RasterError::Encode`].
    pub(crate) fn encode(msg: impl Into<String>) -> Self {
        RasterError::Encode { msg: msg.into() }
    }

    /// A [`RasterError::Io`] for `path`.
    pub(crate) fn io(path: &Path, source: io::Error) -> Self {
        RasterError::Io {
            path: path.to_path_buf(),
            error: source,
        }
    }

    /// An I/O error met while a decoder was reading `path`: running out of bytes means the file
    /// is truncated (a decode error); anything else is the file system's fault.
    pub(crate) fn from_read(path: &Path, source: io::Error) -> Self {
        if source.kind() == io::ErrorKind::UnexpectedEof {
            Self::decode(path, "the file ends early (truncated?)")
        } else {
            Self::io(path, source)
        }
    }
}

/// `cannot read 'PATH' as FORMAT: ` for errors met while reading, `'PATH': ` when the format is
/// not known, nothing on writes.
fn read_prefix(read_as: &Option<(PathBuf, &'static str)>) -> String {
    match read_as {
        Some((path, "")) => format!("'{}': ", path.display()),
        Some((path, format)) => format!("cannot read '{}' as {format}: ", path.display()),
        None => String::new(),
    }
}
