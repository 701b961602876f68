//! The world's shared coarse structure for tiled refinement: a coarse-world file (written once by
//! `refine --coarse-out`, read by region by every tile) or the same computed in the tile's own
//! process.

use std::fs::File;
use std::io::{Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use serde::{Deserialize, Serialize};
use terrasketch_raster::{Heightmap, write_file_atomically};
use terrasketch_synthesis::refine::field::Field;
use terrasketch_synthesis::refine::levels::{Level, level1_window, upsample2_region};
use terrasketch_synthesis::refine::{CoarseWorld, RefineInput};

use crate::output::refused;
use crate::tiled::{FORMAT_VERSION, Region, WorldKey};

/// Magic bytes of a coarse-world file.
const COARSE_MAGIC: &[u8; 8] = b"TSCOARSE";

/// One array of a coarse-world file.
#[derive(Serialize, Deserialize, Clone, Debug)]
struct ArrayEntry {
    /// `target`, `constraint` (NaN where unconstrained), `tolerance`, `roughness`, `level1`.
    name: String,
    /// Side in cells (f32, row 0 = north).
    side: usize,
    /// Byte offset after the header.
    offset: u64,
}

/// The JSON header of a coarse-world file.
#[derive(Serialize, Deserialize, Clone, Debug)]
pub(crate) struct CoarseHeader {
    format: String,
    version: u32,
    key: WorldKey,
    /// World side in cells (a power of two).
    n: usize,
    cell_size_m: f64,
    /// The world's pyramid plan, coarsest first.
    plan: Vec<Level>,
    arrays: Vec<ArrayEntry>,
}

/// The world as the tiles see it: in this process, or in a coarse-world file read by region.
pub(crate) enum World {
    Memory {
        input: RefineInput,
        coarse: CoarseWorld,
    },
    File {
        file: File,
        path: PathBuf,
        data_start: u64,
        header: CoarseHeader,
    },
}

/// Crops the `n`-wide square `v` to `r`.
fn crop<T: Copy>(v: &[T], n: usize, r: &Region) -> Vec<T> {
    let mut out = Vec::with_capacity(r.side * r.side);
    for y in r.row..r.row + r.side {
        out.extend_from_slice(&v[y * n + r.column..y * n + r.column + r.side]);
    }
    out
}

impl World {
    pub(crate) fn n(&self) -> usize {
        match self {
            World::Memory { input, .. } => input.target.width,
            World::File { header, .. } => header.n,
        }
    }

    pub(crate) fn cell_size_m(&self) -> f64 {
        match self {
            World::Memory { input, .. } => input.target.cell_size_m[0],
            World::File { header, .. } => header.cell_size_m,
        }
    }

    pub(crate) fn plan(&self) -> Vec<Level> {
        match self {
            World::Memory { coarse, .. } => coarse.plan.clone(),
            World::File { header, .. } => header.plan.clone(),
        }
    }

    /// The refinement input of region `r` and the coarse synthesis brought up to it.
    pub(crate) fn region(&mut self, r: &Region) -> Result<(RefineInput, Option<Field>)> {
        let n = self.n();
        let cell = self.cell_size_m();
        let start_window = level1_window([r.column, r.row], r.side, n / 2);
        match self {
            World::Memory { input, coarse } => {
                let start = coarse.level1.as_ref().map(|l1| {
                    let (c0, c1) = start_window;
                    let w = c1[0] - c0[0];
                    let mut v = Vec::with_capacity(w * (c1[1] - c0[1]));
                    for y in c0[1]..c1[1] {
                        v.extend_from_slice(&l1.v[y * l1.w + c0[0]..y * l1.w + c1[0]]);
                    }
                    let crop = Field::new(w, c1[1] - c0[1], v);
                    upsample2_region(&crop, c0, [r.column, r.row], r.side)
                });
                let region = RefineInput {
                    target: Heightmap {
                        width: r.side,
                        height: r.side,
                        data: crop(&input.target.data, n, r),
                        cell_size_m: [cell; 2],
                    },
                    constraint_mask: input.constraint_mask.as_ref().map(|m| crop(m, n, r)),
                    constraint_values: input.constraint_values.as_ref().map(|m| crop(m, n, r)),
                    roughness: input.roughness.as_ref().map(|m| crop(m, n, r)),
                    sinks: None,
                    constraint_tolerance: input
                        .constraint_tolerance
                        .as_ref()
                        .map(|m| crop(m, n, r)),
                };
                Ok((region, start))
            }
            World::File {
                file,
                path,
                data_start,
                header,
            } => {
                let mut read = |name: &str, x0: usize, y0: usize, w: usize, h: usize| {
                    read_window(file, path, *data_start, header, name, [x0, y0], [w, h])
                };
                let target = read("target", r.column, r.row, r.side, r.side)?
                    .ok_or_else(|| refused(format!("{}: no target array", path.display())))?;
                let constraint = read("constraint", r.column, r.row, r.side, r.side)?;
                let tolerance = read("tolerance", r.column, r.row, r.side, r.side)?;
                let roughness = read("roughness", r.column, r.row, r.side, r.side)?;
                let (c0, c1) = start_window;
                let level1 = read("level1", c0[0], c0[1], c1[0] - c0[0], c1[1] - c0[1])?;
                let start = level1.map(|v| {
                    let crop = Field::new(c1[0] - c0[0], c1[1] - c0[1], v);
                    upsample2_region(&crop, c0, [r.column, r.row], r.side)
                });
                let (mask, values) = match constraint {
                    Some(c) => (
                        Some(c.iter().map(|v| !v.is_nan()).collect()),
                        Some(
                            c.iter()
                                .map(|v| if v.is_nan() { 0.0 } else { *v })
                                .collect(),
                        ),
                    ),
                    None => (None, None),
                };
                let region = RefineInput {
                    target: Heightmap {
                        width: r.side,
                        height: r.side,
                        data: target,
                        cell_size_m: [cell; 2],
                    },
                    constraint_mask: mask,
                    constraint_values: values,
                    roughness,
                    sinks: None,
                    constraint_tolerance: tolerance,
                };
                Ok((region, start))
            }
        }
    }
}

/// Reads the `size` window at `at` of array `name` (None when the file has no such array).
fn read_window(
    file: &mut File,
    path: &Path,
    data_start: u64,
    header: &CoarseHeader,
    name: &str,
    at: [usize; 2],
    size: [usize; 2],
) -> Result<Option<Vec<f32>>> {
    let Some(entry) = header.arrays.iter().find(|a| a.name == name) else {
        return Ok(None);
    };
    if at[0] + size[0] > entry.side || at[1] + size[1] > entry.side {
        return Err(refused(format!(
            "{}: array {name} is {} a side, too small for this world",
            path.display(),
            entry.side
        )));
    }
    let mut out = Vec::with_capacity(size[0] * size[1]);
    let mut row = vec![0u8; size[0] * 4];
    for y in at[1]..at[1] + size[1] {
        let offset = data_start + entry.offset + ((y * entry.side + at[0]) * 4) as u64;
        file.seek(SeekFrom::Start(offset))
            .and_then(|_| file.read_exact(&mut row))
            .map_err(|e| refused(format!("{}: truncated coarse file ({e})", path.display())))?;
        out.extend(
            row.chunks_exact(4)
                .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])),
        );
    }
    Ok(Some(out))
}

/// Opens a coarse-world file and checks that it was made for this world.
pub(crate) fn open_coarse(path: &Path, key: &WorldKey, n: usize) -> Result<World> {
    let bad = |what: &str| {
        refused(format!(
            "--coarse {} is not a terrasketch coarse-world file ({what})",
            path.display()
        ))
    };
    let mut file = File::open(path)
        .map_err(|e| refused(format!("--coarse {}: cannot open ({e})", path.display())))?;
    let mut head = [0u8; 16];
    file.read_exact(&mut head).map_err(|_| bad("too short"))?;
    if &head[..8] != COARSE_MAGIC {
        return Err(bad("wrong magic"));
    }
    let len = u64::from_le_bytes(head[8..16].try_into().unwrap_or([0; 8]));
    if len > 1 << 20 {
        return Err(bad("header too long"));
    }
    let mut json = vec![0u8; len as usize];
    file.read_exact(&mut json).map_err(|_| bad("truncated"))?;
    let header: CoarseHeader = serde_json::from_slice(&json).map_err(|e| bad(&e.to_string()))?;
    if header.format != "terrasketch-coarse" || header.version != FORMAT_VERSION {
        return Err(bad("unknown format or version"));
    }
    if let Some(d) = header.key.difference(key) {
        return Err(refused(format!(
            "--coarse {} was made for another world: {d}",
            path.display()
        )));
    }
    if header.n != n || header.plan.is_empty() {
        return Err(bad("world size"));
    }
    let file_len = file.metadata().map(|m| m.len()).unwrap_or(0);
    let data_start = 16 + len;
    for a in &header.arrays {
        let end = data_start + a.offset + (a.side * a.side * 4) as u64;
        if end > file_len {
            return Err(bad(&format!("array {} truncated", a.name)));
        }
    }
    Ok(World::File {
        file,
        path: path.to_path_buf(),
        data_start,
        header,
    })
}

/// Writes the world's input and coarse levels to `path` (atomically); returns the file's bytes.
pub(crate) fn write_coarse(
    path: &Path,
    key: WorldKey,
    input: RefineInput,
    coarse: CoarseWorld,
) -> Result<usize> {
    let n = input.target.width;
    let mut arrays: Vec<(&str, usize, Vec<f32>)> = vec![("target", n, input.target.data)];
    if let (Some(m), Some(v)) = (&input.constraint_mask, &input.constraint_values) {
        let c = m
            .iter()
            .zip(v)
            .map(|(&m, &v)| if m { v } else { f32::NAN })
            .collect();
        arrays.push(("constraint", n, c));
    }
    if let Some(t) = input.constraint_tolerance {
        arrays.push(("tolerance", n, t));
    }
    if let Some(r) = input.roughness {
        arrays.push(("roughness", n, r));
    }
    if let Some(l1) = coarse.level1 {
        arrays.push(("level1", l1.w, l1.v));
    }
    let mut entries = Vec::new();
    let mut offset = 0u64;
    for (name, side, _) in &arrays {
        entries.push(ArrayEntry {
            name: (*name).to_owned(),
            side: *side,
            offset,
        });
        offset += (side * side * 4) as u64;
    }
    let header = CoarseHeader {
        format: "terrasketch-coarse".into(),
        version: FORMAT_VERSION,
        key,
        n,
        cell_size_m: input.target.cell_size_m[0],
        plan: coarse.plan.clone(),
        arrays: entries,
    };
    let json = serde_json::to_vec(&header)?;
    let mut bytes = Vec::with_capacity(16 + json.len() + offset as usize);
    bytes.extend_from_slice(COARSE_MAGIC);
    bytes.extend_from_slice(&(json.len() as u64).to_le_bytes());
    bytes.extend_from_slice(&json);
    for (_, _, v) in &arrays {
        for x in v {
            bytes.extend_from_slice(&x.to_le_bytes());
        }
    }
    write_file_atomically(path, &bytes)
        .with_context(|| format!("cannot write {}", path.display()))?;
    Ok(bytes.len())
}
