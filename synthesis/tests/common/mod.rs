//! Helpers shared by the integration tests: a scratch folder and small file writers.

#![allow(dead_code)] // each test binary uses a different subset

use std::path::{Path, PathBuf};

use std::sync::atomic::{AtomicUsize, Ordering};
use terrasketch_raster::Heightmap;
use terrasketch_synthesis::refine::RefineInput;

/// A fresh folder under the system temp dir, removed on drop.
pub struct ScratchDir(pub PathBuf);

impl ScratchDir {
    pub fn new(tag: &str) -> Self {
        static COUNTER: AtomicUsize = AtomicUsize::new(0);
        let n = COUNTER.fetch_add(1, Ordering::Relaxed);
        let dir = std::env::temp_dir().join(format!(
            "terrasketch-synthesis-{tag}-{}-{n}",
            std::process::id()
        ));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        Self(dir)
    }

    pub fn path(&self, name: &str) -> PathBuf {
        self.0.join(name)
    }
}

impl Drop for ScratchDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// The shipped exemplar file `name`.
pub fn exemplar(name: &str) -> PathBuf {
    terrasketch_synthesis::shipped_exemplar_dir().join(name)
}

/// Writes a PNG with the `png` crate.
pub fn write_png(
    path: &Path,
    width: u32,
    height: u32,
    color: png::ColorType,
    depth: png::BitDepth,
    data: &[u8],
) {
    let file = std::fs::File::create(path).unwrap();
    let mut encoder = png::Encoder::new(std::io::BufWriter::new(file), width, height);
    encoder.set_color(color);
    encoder.set_depth(depth);
    let mut writer = encoder.write_header().unwrap();
    writer.write_image_data(data).unwrap();
    writer.finish().unwrap();
}

/// CRC-32 (IEEE) as used by PNG chunks.
pub fn crc32(bytes: &[u8]) -> u32 {
    let mut crc = 0xffff_ffffu32;
    for &b in bytes {
        crc ^= u32::from(b);
        for _ in 0..8 {
            crc = if crc & 1 != 0 {
                (crc >> 1) ^ 0xedb8_8320
            } else {
                crc >> 1
            };
        }
    }
    !crc
}

/// A little-endian TIFF with one IFD of the given (tag, type, count, value-or-offset) entries,
/// followed by `payload` at offset `8 + 2 + 12 * entries.len() + 4`.
pub fn tiff_bytes(entries: &[(u16, u16, u32, u32)], payload: &[u8]) -> Vec<u8> {
    let mut out = b"II*\0".to_vec();
    out.extend_from_slice(&8u32.to_le_bytes());
    out.extend_from_slice(&(entries.len() as u16).to_le_bytes());
    for &(tag, typ, count, value) in entries {
        out.extend_from_slice(&tag.to_le_bytes());
        out.extend_from_slice(&typ.to_le_bytes());
        out.extend_from_slice(&count.to_le_bytes());
        if typ == 3 && count == 1 {
            out.extend_from_slice(&(value as u16).to_le_bytes());
            out.extend_from_slice(&[0, 0]);
        } else {
            out.extend_from_slice(&value.to_le_bytes());
        }
    }
    out.extend_from_slice(&0u32.to_le_bytes());
    out.extend_from_slice(payload);
    out
}

/// Offset of the payload in [`tiff_bytes`] output for `n` entries.
pub fn tiff_payload_offset(n: usize) -> u32 {
    (8 + 2 + 12 * n + 4) as u32
}

/// A diagonal Gaussian ridge on a tilted plane with its crest constrained.
pub fn ridge_input(n: usize, cell: f64, tolerance: Option<f32>) -> RefineInput {
    let data: Vec<f32> = (0..n * n)
        .map(|i| {
            let (x, y) = ((i % n) as f32, (i / n) as f32);
            let d = (x - y) / n as f32;
            300.0 + 600.0 * (-d * d * 30.0).exp() + 0.05 * x * cell as f32
        })
        .collect();
    let mut mask = vec![false; n * n];
    for t in 8..n - 8 {
        mask[t * n + t] = true;
    }
    RefineInput {
        target: Heightmap {
            width: n,
            height: n,
            data: data.clone(),
            cell_size_m: [cell; 2],
        },
        constraint_mask: Some(mask),
        constraint_values: Some(data),
        roughness: None,
        sinks: None,
        constraint_tolerance: tolerance.map(|t| vec![t; n * n]),
    }
}
