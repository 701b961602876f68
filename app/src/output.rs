//! Writing solved heights to files, and checks done before any work starts.

use std::path::Path;

use anyhow::{Context, Result};
use serde_json::{Value, json};
use terrasketch_raster::{
    Format, Georef, Heightmap, Sampling, Stretch, WriteOptions, resample_cells,
    write_heightmap_with,
};

use crate::tiles::{TileSpec, write_tiles};

/// An argument or input the command refuses (exit status 2, like a usage error), as opposed to a
/// failure while working (exit status 1).
#[derive(Debug)]
pub struct Refused(pub String);

impl std::fmt::Display for Refused {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for Refused {}

/// A [`Refused`] error with `message`.
pub fn refused(message: impl Into<String>) -> anyhow::Error {
    anyhow::Error::new(Refused(message.into()))
}

/// What an output path asks for, by its extension.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OutputKind {
    /// A heightmap file.
    Raster(Format),
    /// A glTF 2.0 binary mesh.
    Glb,
    /// A Wavefront OBJ mesh.
    Obj,
}

/// [`check_writable`] for any output of `solve`: a heightmap extension or `.glb` / `.obj`.
pub fn check_output(path: &Path) -> Result<OutputKind> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    let kind = match ext.as_deref() {
        Some("glb") => OutputKind::Glb,
        Some("obj") => OutputKind::Obj,
        _ => OutputKind::Raster(
            Format::from_path(path).map_err(|e| refused(format!("{e}, or a mesh: .glb, .obj")))?,
        ),
    };
    check_folder(path)?;
    Ok(kind)
}

/// Checks that `path` has a supported extension and that its folder exists and is writable, so that a
/// long solve never ends in a write error. Leaves nothing behind.
pub fn check_writable(path: &Path) -> Result<Format> {
    let format = Format::from_path(path)?;
    check_folder(path)?;
    Ok(format)
}

/// Checks that the folder of `path` exists and is writable and that `path` is not a folder
/// (refused as a bad argument otherwise). Leaves nothing behind.
pub fn check_folder(path: &Path) -> Result<()> {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => std::env::current_dir().context("cannot read the current directory")?,
    };
    if !dir.is_dir() {
        return Err(refused(format!(
            "cannot write {}: folder {} does not exist",
            path.display(),
            dir.display()
        )));
    }
    if path.is_dir() {
        return Err(refused(format!(
            "cannot write {}: it is a folder",
            path.display()
        )));
    }
    let probe = dir.join(format!(".terrasketch-write-probe-{}", std::process::id()));
    std::fs::write(&probe, b"").with_context(|| {
        format!(
            "cannot write {}: folder {} is not writable",
            path.display(),
            dir.display()
        )
    })?;
    let _ = std::fs::remove_file(&probe);
    Ok(())
}

/// Smallest export side, samples.
pub const MIN_EXPORT_SIDE: usize = 64;
/// Largest export side, samples (the largest solve grid, 16384, plus its corner row).
pub const MAX_EXPORT_SIDE: usize = 16385;
/// Bytes per solve-grid cell at a CPU solve's peak, with the heights' copy: peak RSS over n^2 is
/// 61-67 bytes for `solve` and `bench solver` at 2048 and 4096, rounded up for safety.
const SOLVE_BYTES_PER_CELL: u64 = 72;
/// Bytes per exported sample at the peak of an export: the resampled f32 map and the encoded
/// file in memory (at most 8 bytes a sample for TIFF and EXR), with room for a tile's copy.
const EXPORT_BYTES_PER_SAMPLE: u64 = 16;

/// Bytes of a refinement's peak besides its grid: the shipped exemplar library prepared, rounded
/// up from the measured peak (synthesis/README.md, "Memory").
const REFINE_BASE_BYTES: u64 = 256 << 20;
/// Bytes per refined cell at the refinement's peak, rounded up from the measured growth
/// (synthesis/README.md, "Memory").
pub const REFINE_BYTES_PER_CELL: u64 = 128;

/// How an export of `samples x samples` is made from the solver's power-of-two grid.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ExportPlan {
    /// Samples per side of the file.
    pub samples: usize,
    /// Cells per side of the solve (a power of two, 64..=16384).
    pub solve_n: usize,
    /// Where the samples sit: a power of two is cell-centred (the solve itself), every other size
    /// samples corners, bilinearly from the solve.
    pub sampling: Sampling,
}

impl ExportPlan {
    /// The plan for `samples` per side; refused outside 64..=16385. Corner-sampled sizes use the
    /// smallest power-of-two solve with at least `samples - 1` cells (1025 from 1024, 1009 from
    /// 1024, 8129 from 8192); 16385 comes from the 16384 solve, the largest.
    pub fn new(samples: usize) -> Result<ExportPlan> {
        if !(MIN_EXPORT_SIDE..=MAX_EXPORT_SIDE).contains(&samples) {
            return Err(refused(format!(
                "--size {samples} is not supported: the output side must be from \
                 {MIN_EXPORT_SIDE} to {MAX_EXPORT_SIDE} samples"
            )));
        }
        let sampling = Sampling::for_size(samples);
        let solve_n = match sampling {
            Sampling::Cells => samples,
            Sampling::Corners => (samples - 1)
                .next_power_of_two()
                .clamp(MIN_EXPORT_SIDE, MAX_EXPORT_SIDE - 1),
        };
        Ok(ExportPlan {
            samples,
            solve_n,
            sampling,
        })
    }

    /// The plan for `samples` per side from an existing `grid_n`-cell solve (the editor's grid):
    /// any size 64..=16385, cell-centred at powers of two, bilinear from the grid otherwise
    /// (upsampled when `samples` exceeds it).
    pub fn from_grid(samples: usize, grid_n: usize) -> Result<ExportPlan> {
        let plan = ExportPlan::new(samples)?;
        Ok(ExportPlan {
            solve_n: grid_n,
            ..plan
        })
    }

    /// Whether the file's samples are interpolated from the solve rather than the solve itself.
    pub fn resampled(&self) -> bool {
        self.sampling != Sampling::Cells || self.samples != self.solve_n
    }

    /// Estimated peak memory of solving and exporting, bytes, with `extra_per_sample` bytes per
    /// exported sample on top (a mesh's vertices, triangles and file).
    pub fn memory_bytes(&self, extra_per_sample: u64) -> u64 {
        let cells = (self.solve_n as u64).pow(2);
        let samples = (self.samples as u64).pow(2);
        cells * SOLVE_BYTES_PER_CELL + samples * (EXPORT_BYTES_PER_SAMPLE + extra_per_sample)
    }

    /// Refuses the plan up front when its estimate (see [`ExportPlan::memory_bytes`]) exceeds the
    /// memory available (MemAvailable, or `TERRASKETCH_MEMORY_LIMIT_MB` when set), naming both.
    pub fn check_memory(&self, extra_per_sample: u64) -> Result<()> {
        let Some((limit, source)) = memory_limit_bytes() else {
            return Ok(());
        };
        let need = self.memory_bytes(extra_per_sample);
        if need > limit {
            return Err(refused(format!(
                "--size {} needs about {:.1} GiB (a {}^2 solve and the export), more than the \
                 {:.1} GiB available ({source}): use a smaller --size",
                self.samples,
                need as f64 / GIB,
                self.solve_n,
                limit as f64 / GIB
            )));
        }
        Ok(())
    }

    /// [`ExportPlan::check_memory`] for a refinement on the `solve_n` grid: the exemplar library
    /// plus [`REFINE_BYTES_PER_CELL`] per cell and the export.
    pub fn check_refine_memory(&self) -> Result<()> {
        let Some((limit, source)) = memory_limit_bytes() else {
            return Ok(());
        };
        let cells = (self.solve_n as u64).pow(2);
        let samples = (self.samples as u64).pow(2);
        let need =
            REFINE_BASE_BYTES + cells * REFINE_BYTES_PER_CELL + samples * EXPORT_BYTES_PER_SAMPLE;
        if need > limit {
            return Err(refused(format!(
                "--size {} needs about {:.1} GiB (a {}^2 refinement and the export), more than \
                 the {:.1} GiB available ({source}): use a smaller --size",
                self.samples,
                need as f64 / GIB,
                self.solve_n,
                limit as f64 / GIB
            )));
        }
        Ok(())
    }

    /// The file's samples from south-up solve heights (`solve_n^2`, row 0 = south) over
    /// `extent_m`: north-up, resampled when the plan says so.
    pub fn sample(&self, heights: &[f32], extent_m: [f64; 2]) -> Result<Heightmap> {
        let n = self.solve_n;
        let solved = north_up(n, heights, [extent_m[0] / n as f64, extent_m[1] / n as f64]);
        if !self.resampled() {
            return Ok(solved);
        }
        Ok(resample_cells(
            &solved,
            self.samples,
            self.samples,
            self.sampling,
        )?)
    }

    /// The file's samples from a north-up `solve_n^2` map (a refinement): the map itself, or
    /// resampled when the plan says so.
    pub fn sample_north_up(&self, map: Heightmap) -> Result<Heightmap> {
        if !self.resampled() {
            return Ok(map);
        }
        Ok(resample_cells(
            &map,
            self.samples,
            self.samples,
            self.sampling,
        )?)
    }

    /// Where sample `k` of the file sits along an axis whose solve grid covers `[0, cells)` of
    /// some raster: `(a, b)` such that the sample's pixel spans `[a + b k, a + b (k + 1)]`
    /// (cell-centred: the solve's cells; corner-sampled: centred on the corners, half a pixel
    /// past the extent's edges).
    pub fn pixel_span(&self, cells: f64) -> (f64, f64) {
        match self.sampling {
            Sampling::Cells => (0.0, cells / self.samples as f64),
            Sampling::Corners => {
                let b = cells / (self.samples - 1) as f64;
                (-0.5 * b, b)
            }
        }
    }

    /// One line for the user: how the samples were made.
    pub fn describe(&self) -> String {
        if self.resampled() {
            format!(
                "{0} x {0} samples on cell corners (edges included), bilinear from the {1}^2 solve{2}",
                self.samples,
                self.solve_n,
                if self.samples > MAX_EXPORT_SIDE - 1 {
                    ", the largest solve grid"
                } else {
                    ""
                }
            )
        } else {
            format!(
                "{0} x {0} samples on cell centres (the solve)",
                self.samples
            )
        }
    }
}

const GIB: f64 = (1u64 << 30) as f64;

/// The memory limit for up-front checks, bytes, and where it comes from.
fn memory_limit_bytes() -> Option<(u64, &'static str)> {
    if let Ok(text) = std::env::var("TERRASKETCH_MEMORY_LIMIT_MB")
        && let Ok(mb) = text.trim().parse::<u64>()
    {
        return Some((mb.saturating_mul(1 << 20), "TERRASKETCH_MEMORY_LIMIT_MB"));
    }
    let info = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = info.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some((kb.saturating_mul(1024), "MemAvailable"))
}

/// South-up solver heights (`n x n`, row 0 = south) as a north-up heightmap.
pub fn north_up(n: usize, heights: &[f32], cell_size_m: [f64; 2]) -> Heightmap {
    let mut data = Vec::with_capacity(n * n);
    for j in (0..n).rev() {
        data.extend_from_slice(&heights[j * n..(j + 1) * n]);
    }
    Heightmap {
        width: n,
        height: n,
        data,
        cell_size_m,
    }
}

/// Peak resident memory of this process in MB (VmHWM), if the OS tells.
pub fn peak_rss_mb() -> Option<f64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb / 1024.0)
}

/// What an exported raster keeps of its input's place: the GeoTIFF georeference of the map as
/// written and its no-data value. Empty for a sketch's local metric frame.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Place {
    /// CRS and transform of the written map (GeoTIFF only).
    pub georef: Option<Georef>,
    /// The `GDAL_NODATA` value (GeoTIFF only); samples equal to it are no-data.
    pub nodata: Option<f64>,
}

/// What [`write_raster`] wrote.
pub struct RasterWritten {
    /// The 16-bit stretch (PNG, R16).
    pub stretch: Option<Stretch>,
    /// The tiles' manifest, with `--tiles`.
    pub manifest: Option<std::path::PathBuf>,
}

/// Writes an export (`solve`, `refine`, the editor): the whole raster, or its tiles and
/// manifest, with the sampling's tie point or the input's georeference (GeoTIFF). Prints what
/// was written on stderr unless `quiet`; returns the JSON fields that describe it.
pub fn write_raster(
    output: &Path,
    format: Format,
    map: &Heightmap,
    sampling: Sampling,
    tiles: Option<&TileSpec>,
    place: &Place,
    quiet: bool,
) -> Result<(RasterWritten, Value)> {
    if format != Format::Tiff && (place.georef.is_some() || place.nodata.is_some()) && !quiet {
        eprintln!(
            "terrasketch: warning: only GeoTIFF (.tif) keeps the input's CRS, transform and \
             no-data value; {} has none",
            output.display()
        );
    }
    let written = match tiles {
        Some(spec) => {
            let written = write_tiles(output, map, sampling, format, spec, place)?;
            if !quiet {
                eprintln!(
                    "terrasketch: {} tiles written, manifest {}",
                    written.files.len(),
                    written.manifest.display()
                );
            }
            RasterWritten {
                stretch: written.stretch,
                manifest: Some(written.manifest),
            }
        }
        None => {
            let options = WriteOptions {
                sampling,
                georef: place.georef.as_ref(),
                nodata: place.nodata,
                ..WriteOptions::default()
            };
            let info = write_heightmap_with(output, map, &options)
                .with_context(|| format!("cannot write {}", output.display()))?;
            RasterWritten {
                stretch: info.stretch,
                manifest: None,
            }
        }
    };
    if let Some(s) = written.stretch
        && !quiet
    {
        let what = match tiles {
            Some(_) => format!("the tiles of {}", output.display()),
            None => output.display().to_string(),
        };
        eprintln!(
            "terrasketch: {what} stretched over {} .. {} m (0 -> {} m, 65535 -> {} m){}",
            s.min_m,
            s.max_m,
            s.min_m,
            s.max_m,
            if format == Format::Png16 {
                "; stored in the PNG's text chunks"
            } else {
                ""
            }
        );
    }
    let json = json!({
        "format": format.extension(),
        "stretch_min_m": written.stretch.map(|s| s.min_m),
        "stretch_max_m": written.stretch.map(|s| s.max_m),
        "manifest": written.manifest.as_ref().map(|m| m.display().to_string()),
        "tiles": tiles.map(|t| t.nx * t.ny),
        "crs_epsg": place.georef.as_ref().and_then(|g| g.epsg()),
        "georeferenced": place.georef.is_some() && format == Format::Tiff,
        "nodata": place.nodata,
    });
    Ok((written, json))
}
