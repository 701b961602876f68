//! What a sketch file is, as the other modules need it: the format's name and version and the size
//! limits refused as hostile input (a leaf module: the errors, the reader and the writer import it).

/// Value of the `format` field of every sketch file.
pub const FORMAT_NAME: &str = "terrasketch-sketch";
/// The file-format version this build writes and the only one it reads.
pub const FORMAT_VERSION: u64 = 1;
/// Most strokes a sketch may have; more is refused as hostile input.
pub const MAX_STROKES: usize = 100_000;
/// Most points a sketch may have over all its strokes; more is refused as hostile input.
pub const MAX_POINTS: usize = 1_000_000;
