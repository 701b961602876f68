//! Hostile and broken input: truncated files, headers claiming huge rasters, duplicated EXR
//! blocks, flipped bytes. Every case must end in an error (never a panic, never a giant
//! allocation, never silently zeroed pixels) and run quickly.

mod common;

use std::fs;
use std::path::Path;
use std::time::{Duration, Instant};

use common::{ScratchDir, crc32, ramp_sine};
use terrasketch_raster::{
    Format, Heightmap, RasterError, encode_heightmap, read_heightmap, read_r16,
};

/// Reading must fail, and not because a decoder panicked.
fn assert_read_fails(path: &Path, what: &str) -> RasterError {
    let error = read_heightmap(path).expect_err(what);
    assert!(
        !error.to_string().contains("panic"),
        "{what}: decoder panicked: {error}"
    );
    error
}

/// Reading `bytes` as a file named `name` must be refused quickly with `TooLarge` or `Decode`.
fn assert_refused_quickly(dir: &ScratchDir, name: &str, bytes: &[u8]) -> RasterError {
    let path = dir.join(name);
    fs::write(&path, bytes).unwrap();
    let started = Instant::now();
    let error = assert_read_fails(&path, name);
    assert!(
        started.elapsed() < Duration::from_secs(2),
        "{name}: took {:?}",
        started.elapsed()
    );
    assert!(
        matches!(
            error,
            RasterError::TooLarge { .. } | RasterError::Decode { .. }
        ),
        "{name}: {error}"
    );
    error
}

#[test]
fn truncated_files_of_every_format_are_errors() {
    let dir = ScratchDir::new("truncated");
    let map = ramp_sine(37, 23);
    for format in [Format::Exr, Format::Tiff, Format::Png16] {
        let (bytes, _) = encode_heightmap(format, &map).unwrap();
        let path = dir.join(&format!("cut.{}", format.extension()));
        let mut cuts: Vec<usize> = (0..bytes.len()).step_by(7).collect();
        cuts.extend(bytes.len().saturating_sub(40)..bytes.len());
        for cut in cuts {
            fs::write(&path, &bytes[..cut]).unwrap();
            assert_read_fails(
                &path,
                &format!("{format:?} cut to {cut} of {} bytes", bytes.len()),
            );
        }
        fs::write(&path, &bytes).unwrap();
        assert!(
            read_heightmap(&path).is_ok(),
            "{format:?}: the whole file reads"
        );
    }
}

#[test]
fn truncated_r16_files_are_errors() {
    let dir = ScratchDir::new("truncated-r16");
    let (bytes, stretch) = encode_heightmap(Format::R16, &ramp_sine(16, 16)).unwrap();
    let path = dir.join("cut.r16");
    for cut in [0, 1, 3, 255, 510, 511] {
        fs::write(&path, &bytes[..cut]).unwrap();
        assert_read_fails(&path, &format!("square read, cut to {cut}"));
        let error = read_r16(&path, 16, 16, stretch).expect_err("explicit read of a cut file");
        assert!(
            matches!(error, RasterError::Decode { .. }),
            "cut {cut}: {error}"
        );
    }
}

/// A little-endian classic TIFF whose header claims `width x height` f32 samples in one strip
/// but holds only 64 bytes of data.
fn crafted_tiff(width: u32, height: u32) -> Vec<u8> {
    const LONG: u16 = 4;
    const SHORT: u16 = 3;
    let data_offset: u32 = 8 + 2 + 10 * 12 + 4;
    let strip_bytes = u64::from(width) * u64::from(height) * 4;
    let entries: [(u16, u16, u32); 10] = [
        (256, LONG, width),
        (257, LONG, height),
        (258, SHORT, 32),
        (259, SHORT, 1),
        (262, SHORT, 1),
        (273, LONG, data_offset),
        (277, SHORT, 1),
        (278, LONG, height),
        (279, LONG, u32::try_from(strip_bytes).unwrap_or(u32::MAX)),
        (339, SHORT, 3),
    ];
    let mut bytes = b"II".to_vec();
    bytes.extend_from_slice(&42u16.to_le_bytes());
    bytes.extend_from_slice(&8u32.to_le_bytes());
    bytes.extend_from_slice(&(entries.len() as u16).to_le_bytes());
    for (tag, field_type, value) in entries {
        bytes.extend_from_slice(&tag.to_le_bytes());
        bytes.extend_from_slice(&field_type.to_le_bytes());
        bytes.extend_from_slice(&1u32.to_le_bytes());
        if field_type == SHORT {
            bytes.extend_from_slice(&(value as u16).to_le_bytes());
            bytes.extend_from_slice(&[0, 0]);
        } else {
            bytes.extend_from_slice(&value.to_le_bytes());
        }
    }
    bytes.extend_from_slice(&0u32.to_le_bytes());
    assert_eq!(bytes.len(), data_offset as usize);
    bytes.extend_from_slice(&[0; 64]);
    bytes
}

#[test]
fn crafted_tiff_headers_are_refused_before_allocating() {
    let dir = ScratchDir::new("huge-tiff");
    // The crafted file itself is valid when its header tells the truth.
    fs::write(dir.join("honest.tif"), crafted_tiff(4, 4)).unwrap();
    let honest = read_heightmap(&dir.join("honest.tif")).unwrap();
    assert_eq!((honest.width, honest.height), (4, 4));

    let error = assert_refused_quickly(&dir, "huge.tif", &crafted_tiff(100_000, 100_000));
    assert!(
        matches!(
            error,
            RasterError::TooLarge {
                width: 100_000,
                height: 100_000,
                ..
            }
        ),
        "{error}"
    );
    // Within the side limit but over the 4 GiB sample budget.
    let error = assert_refused_quickly(&dir, "budget.tif", &crafted_tiff(65_536, 65_536));
    assert!(matches!(error, RasterError::TooLarge { .. }), "{error}");
    // Within every limit (3.6 GB) but impossible for a 198-byte file.
    let error = assert_refused_quickly(&dir, "liar.tif", &crafted_tiff(30_000, 30_000));
    assert!(
        error.to_string().contains("cannot hold"),
        "refused by the length check: {error}"
    );
}

/// A valid 16-bit PNG whose IHDR is rewritten to claim `width x height`.
fn crafted_png(width: u32, height: u32) -> Vec<u8> {
    let (mut bytes, _) = encode_heightmap(Format::Png16, &ramp_sine(4, 4)).unwrap();
    assert_eq!(&bytes[12..16], b"IHDR");
    bytes[16..20].copy_from_slice(&width.to_be_bytes());
    bytes[20..24].copy_from_slice(&height.to_be_bytes());
    let crc = crc32(&bytes[12..29]);
    bytes[29..33].copy_from_slice(&crc.to_be_bytes());
    bytes
}

#[test]
fn crafted_png_headers_are_refused_before_allocating() {
    let dir = ScratchDir::new("huge-png");
    fs::write(dir.join("honest.png"), crafted_png(4, 4)).unwrap();
    assert!(
        read_heightmap(&dir.join("honest.png")).is_ok(),
        "patching keeps the file valid"
    );

    let error = assert_refused_quickly(&dir, "huge.png", &crafted_png(100_000, 100_000));
    assert!(
        matches!(
            error,
            RasterError::TooLarge {
                width: 100_000,
                height: 100_000,
                ..
            }
        ),
        "{error}"
    );
    let error = assert_refused_quickly(&dir, "liar.png", &crafted_png(30_000, 30_000));
    assert!(
        error.to_string().contains("cannot hold"),
        "refused by the length check: {error}"
    );
}

/// Offset of the four `i32` bounds of the `dataWindow` attribute in an EXR file.
fn data_window_offset(bytes: &[u8]) -> usize {
    let name = b"dataWindow\0box2i\0";
    let at = bytes
        .windows(name.len())
        .position(|w| w == name)
        .expect("dataWindow attribute");
    let size_at = at + name.len();
    assert_eq!(bytes[size_at..size_at + 4], 16i32.to_le_bytes());
    size_at + 4
}

/// A valid EXR whose data window (and chunk count, if stored) is rewritten to claim
/// `width x height`, so that the `exr` crate's own consistency checks pass and ours decide.
fn crafted_exr(width: i32, height: i32) -> Vec<u8> {
    let (mut bytes, _) = encode_heightmap(Format::Exr, &ramp_sine(37, 23)).unwrap();
    let at = data_window_offset(&bytes);
    bytes[at + 8..at + 12].copy_from_slice(&(width - 1).to_le_bytes());
    bytes[at + 12..at + 16].copy_from_slice(&(height - 1).to_le_bytes());
    let name = b"chunkCount\0int\0";
    if let Some(at) = bytes.windows(name.len()).position(|w| w == name) {
        let value_at = at + name.len() + 4;
        let chunks = height; // uncompressed: one scanline per chunk
        bytes[value_at..value_at + 4].copy_from_slice(&chunks.to_le_bytes());
    }
    bytes
}

#[test]
fn crafted_exr_headers_are_refused_before_allocating() {
    let dir = ScratchDir::new("huge-exr");
    fs::write(dir.join("honest.exr"), crafted_exr(37, 23)).unwrap();
    assert!(
        read_heightmap(&dir.join("honest.exr")).is_ok(),
        "patching keeps the file valid"
    );

    let error = assert_refused_quickly(&dir, "huge.exr", &crafted_exr(100_000, 100_000));
    assert!(matches!(error, RasterError::TooLarge { .. }), "{error}");
    let error = assert_refused_quickly(&dir, "liar.exr", &crafted_exr(30_000, 30_000));
    assert!(
        error.to_string().contains("cannot hold"),
        "refused by the length check: {error}"
    );
}

#[test]
fn exr_with_a_duplicated_block_is_an_error_not_zeros() {
    let dir = ScratchDir::new("exr-duplicate");
    // Two rows: two one-scanline blocks, at y = 0 and y = 1.
    let (mut bytes, _) = encode_heightmap(Format::Exr, &ramp_sine(37, 2)).unwrap();
    // The offset table (two u64) sits right before the first chunk it points to.
    let read_u64 = |at: usize| u64::from_le_bytes(bytes[at..at + 8].try_into().unwrap());
    let table = (0..bytes.len() - 16)
        .find(|&at| read_u64(at) == at as u64 + 16 && read_u64(at + 8) > read_u64(at))
        .expect("offset table");
    let second_chunk = read_u64(table + 8) as usize;
    let second_y = &mut bytes[second_chunk..second_chunk + 4];
    assert_eq!(
        *second_y,
        1i32.to_le_bytes(),
        "second block starts at row 1"
    );
    // Claim row 0 again: row 0 arrives twice, row 1 never.
    second_y.copy_from_slice(&0i32.to_le_bytes());

    let path = dir.join("duplicate.exr");
    fs::write(&path, &bytes).unwrap();
    let error = assert_read_fails(&path, "duplicated block");
    assert!(error.to_string().contains("duplicate"), "{error}");
}

#[test]
fn r16_dimensions_are_checked_before_reading() {
    let dir = ScratchDir::new("huge-r16");
    let path = dir.join("small.r16");
    fs::write(&path, [0u8; 8]).unwrap();
    let error = read_r16(&path, 100_000, 100_000, None).unwrap_err();
    assert!(matches!(error, RasterError::TooLarge { .. }), "{error}");
    let error = read_r16(&path, 3, 3, None).unwrap_err();
    assert!(matches!(error, RasterError::Decode { .. }), "{error}");
    let error = read_r16(&path, 0, 4, None).unwrap_err();
    assert!(matches!(error, RasterError::BadShape { .. }), "{error}");
    assert_eq!(read_r16(&path, 2, 2, None).unwrap().data, [0.0; 4]);

    fs::write(&path, [0u8; 7]).unwrap();
    assert_read_fails(&path, "odd length");
    fs::write(&path, []).unwrap();
    assert_read_fails(&path, "empty file");
}

#[test]
fn flipped_bytes_never_panic() {
    let dir = ScratchDir::new("flipped");
    let map = ramp_sine(37, 23);
    for format in [Format::Exr, Format::Tiff, Format::Png16] {
        let (bytes, _) = encode_heightmap(format, &map).unwrap();
        let path = dir.join(&format!("flipped.{}", format.extension()));
        let positions = (0..bytes.len().min(512)).chain((512..bytes.len()).step_by(29));
        for position in positions {
            let mut corrupt = bytes.clone();
            corrupt[position] ^= 0xFF;
            fs::write(&path, &corrupt).unwrap();
            if let Err(error) = read_heightmap(&path) {
                let message = error.to_string();
                assert!(
                    !message.contains("panic"),
                    "{format:?} byte {position}: {message}"
                );
            }
        }
    }
}

#[test]
fn reading_unrelated_files_is_an_error() {
    let dir = ScratchDir::new("garbage");
    let garbage: Vec<u8> = (0..4096u32)
        .map(|i| (i.wrapping_mul(2_654_435_761) >> 24) as u8)
        .collect();
    for name in ["garbage.exr", "garbage.tif", "garbage.png"] {
        let path = dir.join(name);
        fs::write(&path, &garbage).unwrap();
        let error = assert_read_fails(&path, name);
        assert!(
            matches!(error, RasterError::Decode { .. }),
            "{name}: {error}"
        );
        assert!(
            error.to_string().contains(name),
            "{name}: message names the file: {error}"
        );
    }
}

/// The shape checks run on what callers hand in, too.
#[test]
fn malformed_maps_are_refused_before_encoding() {
    let bad_shape = Heightmap {
        width: 4,
        height: 4,
        data: vec![0.0; 15],
        cell_size_m: [1.0, 1.0],
    };
    let empty = Heightmap {
        width: 0,
        height: 4,
        data: vec![],
        cell_size_m: [1.0, 1.0],
    };
    let huge = Heightmap {
        width: 70_000,
        height: 1,
        data: vec![0.0; 70_000],
        cell_size_m: [1.0, 1.0],
    };
    let bad_cell = Heightmap {
        width: 1,
        height: 1,
        data: vec![0.0],
        cell_size_m: [0.0, 1.0],
    };
    for format in [Format::Exr, Format::Tiff, Format::Png16, Format::R16] {
        let error = encode_heightmap(format, &bad_shape).unwrap_err();
        assert!(
            matches!(
                error,
                RasterError::BadShape {
                    width: 4,
                    height: 4,
                    len: 15
                }
            ),
            "{error}"
        );
        let error = encode_heightmap(format, &empty).unwrap_err();
        assert!(matches!(error, RasterError::BadShape { .. }), "{error}");
        let error = encode_heightmap(format, &huge).unwrap_err();
        assert!(
            matches!(
                error,
                RasterError::TooLarge {
                    width: 70_000,
                    height: 1,
                    read_as: None
                }
            ),
            "{error}"
        );
        let error = encode_heightmap(format, &bad_cell).unwrap_err();
        assert!(matches!(error, RasterError::Encode { .. }), "{error}");
    }
}

/// Numbers past the accepted bounds are refused on reading, naming the field.
#[test]
fn out_of_bounds_heights_cells_and_extents_are_refused_on_reading() {
    let dir = ScratchDir::new("out-of-bounds");
    let mut far = ramp_sine(8, 6);
    far.data[2 * 8 + 5] = 1e30;
    let mut tiny_cell = ramp_sine(8, 6);
    tiny_cell.cell_size_m = [0.005, 1.0];
    let mut huge_extent = ramp_sine(8, 6);
    huge_extent.cell_size_m = [1.0, 1e7];
    let cases = [
        (far, "height at row 2, column 5", "100 km"),
        (tiny_cell, "cell size x", "1 cm"),
        (huge_extent, "extent y", "40,000 km"),
    ];
    for (map, field, allowed) in cases {
        for name in ["bad.exr", "bad.tif"] {
            let path = dir.join(name);
            terrasketch_raster::write_heightmap(&path, &map).unwrap();
            let error = assert_read_fails(&path, name);
            assert!(
                matches!(error, RasterError::OutOfBounds { .. }),
                "{name}: {error}"
            );
            let message = error.to_string();
            for part in [field, allowed, name] {
                assert!(message.contains(part), "{message:?} lacks {part:?}");
            }
        }
    }
    // The bounds themselves are accepted.
    let mut edge = ramp_sine(8, 6);
    edge.data[0] = -100_000.0;
    edge.cell_size_m = [0.01, 5_000_000.0];
    let path = dir.join("edge.exr");
    terrasketch_raster::write_heightmap(&path, &edge).unwrap();
    assert_eq!(read_heightmap(&path).unwrap(), edge);
}
