//! Files: opening sketches (checked before anything changes), atomic saves, heightmap export and the
//! periodic recovery autosave.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::{Context, Result};
use terrasketch_sketch::{
    RefinedRecord, Sketch, Warning, load_sketch, save_sketch_atomic, save_sketch_atomic_with,
    validate,
};

/// How often unsaved work is written to the recovery file.
pub const AUTOSAVE_EVERY: Duration = Duration::from_secs(30);

/// An opened sketch file.
pub struct Opened {
    /// The sketch.
    pub sketch: Sketch,
    /// Its refined-terrain record, if any (well formed; its parameters are checked on use).
    pub refined: Option<RefinedRecord>,
    /// Warnings for the user (a refused refined record); the others go to stderr only.
    pub warnings: Vec<String>,
}

/// Reads and validates a sketch; on any problem returns the message and changes nothing.
pub fn open_sketch(path: &Path) -> Result<Opened> {
    let parsed = load_sketch(path).with_context(|| format!("cannot open {}", path.display()))?;
    let mut warnings = Vec::new();
    for w in &parsed.warnings {
        match w {
            Warning::RefinedIgnored { .. } => warnings.push(format!("{}: {w}", path.display())),
            _ => eprintln!("terrasketch: warning: {}: {w}", path.display()),
        }
    }
    Ok(Opened {
        sketch: parsed.sketch,
        refined: parsed.refined,
        warnings,
    })
}

/// Validates, then saves atomically (with the refined-terrain record when given).
pub fn save(sketch: &Sketch, refined: Option<&RefinedRecord>, path: &Path) -> Result<()> {
    validate(sketch)
        .with_context(|| format!("the sketch is not valid, not saved to {}", path.display()))?;
    save_sketch_atomic_with(sketch, refined, path)
        .with_context(|| format!("cannot save {}", path.display()))
}

/// Exports south-up heights (`n x n`) through the command line's export paths. The dialog's text
/// is a path, optionally followed by the command line's `--size N` (64 to 16385; default the
/// grid's own `n`), `--tiles NX,NY`, `--overlap PX` and `--tile-name PATTERN` for heightmaps,
/// `--max-error M` for a `.glb` / `.obj` mesh, or `--masks png|exr` to write the texturing masks
/// into the path as a folder.
pub fn export(request: &Path, n: usize, heights: &[f32], cell_size_m: [f64; 2]) -> Result<String> {
    use crate::output::{ExportPlan, OutputKind, check_output, refused};
    let request = ExportRequest::parse(&request.to_string_lossy())?;
    let kind = match request.masks {
        Some(_) => None,
        None => Some(check_output(&request.path)?),
    };
    let size = request.size.unwrap_or(n);
    let plan = match kind {
        Some(OutputKind::Glb | OutputKind::Obj) => {
            ExportPlan::from_grid(crate::solve::mesh_samples(size, request.max_error_m)?, n)?
        }
        _ => ExportPlan::from_grid(size, n)?,
    };
    plan.check_memory(0)?;
    if request.tiles.is_some() && !matches!(kind, Some(OutputKind::Raster(_))) {
        return Err(refused(
            "export: --tiles is for heightmaps, not meshes or masks",
        ));
    }
    if request.max_error_m.is_some() && !matches!(kind, Some(OutputKind::Glb | OutputKind::Obj)) {
        return Err(refused("export: --max-error is for .glb and .obj meshes"));
    }
    if let Some(spec) = &request.tiles {
        crate::tiles::check_pattern(&spec.pattern)?;
        crate::tiles::layout(plan.samples, plan.samples, plan.sampling, spec)?;
    }
    let extent_m = [cell_size_m[0] * n as f64, cell_size_m[1] * n as f64];
    let map = plan.sample(heights, extent_m)?;
    let how = if plan.resampled() {
        format!(" ({})", plan.describe())
    } else {
        String::new()
    };
    match kind {
        None => {
            let format = request.masks.unwrap_or(crate::masks::MaskFormat::Png);
            crate::masks::write_masks(&map, &request.path, format)?;
            Ok(format!("masks written to {}{how}", request.path.display()))
        }
        Some(OutputKind::Raster(format)) => export_raster(&request, format, &plan, &map),
        Some(mesh_kind) => {
            let mesh = crate::mesh::build(&map, request.max_error_m)?;
            let bytes = match mesh_kind {
                OutputKind::Glb => crate::mesh::to_glb(&mesh)?,
                _ => crate::mesh::to_obj(&mesh)?,
            };
            terrasketch_raster::write_file_atomically(&request.path, &bytes)
                .with_context(|| format!("cannot write {}", request.path.display()))?;
            Ok(format!(
                "exported {}: {} triangles{how}",
                request.path.display(),
                mesh.indices.len() / 3
            ))
        }
    }
}

/// The heightmap part of [`export`]: one file or tiles.
fn export_raster(
    request: &ExportRequest,
    format: terrasketch_raster::Format,
    plan: &crate::output::ExportPlan,
    map: &terrasketch_raster::Heightmap,
) -> Result<String> {
    use crate::output::{Place, write_raster};
    let quiet = true;
    let (written, _) = write_raster(
        &request.path,
        format,
        map,
        plan.sampling,
        request.tiles.as_ref(),
        &Place::default(),
        quiet,
    )?;
    let what = match &written.manifest {
        Some(manifest) => format!("exported tiles, manifest {}", manifest.display()),
        None => format!("exported {}", request.path.display()),
    };
    let how = if plan.resampled() {
        format!(", {}", plan.describe())
    } else {
        String::new()
    };
    Ok(match written.stretch {
        Some(s) => format!("{what} ({} .. {} m stretched{how})", s.min_m, s.max_m),
        None if how.is_empty() => what,
        None => format!("{what} ({})", plan.describe()),
    })
}

/// What the export dialog asks for.
#[derive(Debug, Clone)]
pub struct ExportRequest {
    /// The output file (tiles and manifest go next to it).
    pub path: PathBuf,
    /// `--size`: samples per side.
    pub size: Option<usize>,
    /// `--tiles` with `--overlap` and `--tile-name`.
    pub tiles: Option<crate::tiles::TileSpec>,
    /// `--max-error M` of a mesh.
    pub max_error_m: Option<f64>,
    /// `--masks png|exr`: the path is a folder for the texturing masks.
    pub masks: Option<crate::masks::MaskFormat>,
}

impl ExportRequest {
    /// Parses `PATH [--size N] [--tiles NX,NY] [--overlap PX] [--tile-name PATTERN]
    /// [--max-error M] [--masks png|exr]`; a path without options is taken whole (it may
    /// contain spaces).
    pub fn parse(text: &str) -> Result<ExportRequest> {
        use crate::output::refused;
        let (path, options) = match text.find(" --") {
            Some(at) => (&text[..at], &text[at..]),
            None => (text, ""),
        };
        let mut words = options.split_whitespace();
        let (mut size, mut tiles, mut overlap, mut pattern) =
            (None, None, 0, "{name}_x{i}_y{j}.{ext}".to_string());
        let (mut max_error_m, mut masks) = (None, None);
        while let Some(flag) = words.next() {
            let value = words
                .next()
                .ok_or_else(|| refused(format!("export: {flag} needs a value")))?;
            let number = || {
                value
                    .parse::<usize>()
                    .map_err(|_| refused(format!("export: {flag} {value:?} is not a whole number")))
            };
            match flag {
                "--size" => size = Some(number()?),
                "--tiles" => tiles = Some(crate::tiles::parse_tiles(value)?),
                "--overlap" => overlap = number()?,
                "--tile-name" => pattern = value.to_string(),
                "--max-error" => {
                    max_error_m = Some(value.parse::<f64>().map_err(|_| {
                        refused(format!("export: --max-error {value:?} is not a number"))
                    })?)
                }
                "--masks" => {
                    masks = Some(match value {
                        "png" => crate::masks::MaskFormat::Png,
                        "exr" => crate::masks::MaskFormat::Exr,
                        _ => {
                            return Err(refused(format!(
                                "export: --masks {value:?} is not png or exr"
                            )));
                        }
                    })
                }
                _ => {
                    return Err(refused(format!(
                        "export: unknown option {flag} (--size, --tiles, --overlap, \
                         --tile-name, --max-error, --masks)"
                    )));
                }
            }
        }
        if tiles.is_none() && overlap != 0 {
            return Err(refused("export: --overlap needs --tiles"));
        }
        Ok(ExportRequest {
            path: PathBuf::from(path.trim()),
            size,
            tiles: tiles.map(|[nx, ny]| crate::tiles::TileSpec {
                nx,
                ny,
                overlap,
                pattern,
            }),
            max_error_m,
            masks,
        })
    }
}

/// The recovery autosave file: `$TERRASKETCH_RECOVERY_DIR`, else `$XDG_STATE_HOME/terrasketch`, else
/// `~/.local/state/terrasketch`, file `recovery.json`.
pub fn recovery_path() -> Option<PathBuf> {
    let dir = if let Some(d) = std::env::var_os("TERRASKETCH_RECOVERY_DIR") {
        PathBuf::from(d)
    } else if let Some(d) = std::env::var_os("XDG_STATE_HOME") {
        PathBuf::from(d).join("terrasketch")
    } else {
        PathBuf::from(std::env::var_os("HOME")?).join(".local/state/terrasketch")
    };
    Some(dir.join("recovery.json"))
}

/// Periodic autosave of unsaved work.
pub struct Autosave {
    path: Option<PathBuf>,
    last: Instant,
    every: Duration,
}

impl Autosave {
    /// An autosaver writing to `path` (None disables it).
    pub fn new(path: Option<PathBuf>) -> Autosave {
        Autosave {
            path,
            last: Instant::now(),
            every: AUTOSAVE_EVERY,
        }
    }

    /// The same, saving every `every` (replay sessions).
    pub fn with_interval(path: Option<PathBuf>, every: Duration) -> Autosave {
        Autosave {
            every,
            ..Autosave::new(path)
        }
    }

    /// Writes the sketch if it is dirty and the period has passed. Errors are reported, not fatal.
    pub fn tick(&mut self, sketch: &Sketch, dirty: bool) -> Option<String> {
        let path = self.path.as_ref()?;
        if !dirty || self.last.elapsed() < self.every {
            return None;
        }
        self.last = Instant::now();
        if let Some(dir) = path.parent()
            && let Err(e) = std::fs::create_dir_all(dir)
        {
            return Some(format!(
                "recovery autosave failed: cannot create {}: {e}",
                dir.display()
            ));
        }
        save_sketch_atomic(sketch, path)
            .err()
            .map(|e| format!("recovery autosave failed: {e}"))
    }

    /// Removes the recovery file (clean exit or explicit save of everything).
    /// Saves now, whatever the interval (the device was lost); the path written, or why not.
    pub fn save_now(&mut self, sketch: &Sketch) -> Result<PathBuf, String> {
        let path = self
            .path
            .clone()
            .ok_or_else(|| "no recovery file in this session".to_string())?;
        if let Some(dir) = path.parent() {
            std::fs::create_dir_all(dir)
                .map_err(|e| format!("cannot create {}: {e}", dir.display()))?;
        }
        save_sketch_atomic(sketch, &path).map_err(|e| e.to_string())?;
        self.last = Instant::now();
        Ok(path)
    }

    pub fn clear(&self) {
        if let Some(p) = &self.path {
            let _ = std::fs::remove_file(p);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::{ExportRequest, export};
    use std::path::Path;

    /// The editor's export goes through the command line's path: the grid itself by default,
    /// any size and tiles on request.
    #[test]
    fn export_writes_the_grid_any_size_and_tiles() {
        let dir = tempfile::tempdir().unwrap();
        let n = 64;
        // South-up heights: row 0 is the south edge.
        let heights: Vec<f32> = (0..n * n)
            .map(|i| (i / n) as f32 * 2.0 + (i % n) as f32)
            .collect();
        let out = dir.path().join("e.exr");
        let msg = export(&out, n, &heights, [10.0, 10.0]).unwrap();
        assert!(msg.contains("exported"), "{msg}");
        let map = terrasketch_raster::read_heightmap(&out).unwrap();
        assert_eq!((map.width, map.cell_size_m), (64, [10.0, 10.0]));
        assert_eq!(map.data[0], 63.0 * 2.0, "north-up: row 0 is the north edge");
        let request = format!(
            "{} --size 65 --tiles 2,2",
            dir.path().join("t.tif").display()
        );
        let msg = export(Path::new(&request), n, &heights, [10.0, 10.0]).unwrap();
        assert!(msg.contains("manifest") && msg.contains("corners"), "{msg}");
        let tile = terrasketch_raster::read_heightmap(&dir.path().join("t_x1_y1.tif")).unwrap();
        assert_eq!((tile.width, tile.height), (33, 33));
        // The north-east corner sample is the mean of nothing but the north-east cell's value
        // held past the last centre.
        assert_eq!(tile.data[32], 63.0 * 2.0 + 63.0);
        assert!(dir.path().join("t.tiles.json").is_file());
        let bad = format!("{} --size 63", dir.path().join("b.tif").display());
        assert!(export(Path::new(&bad), n, &heights, [10.0, 10.0]).is_err());
    }

    /// Meshes and masks from the editor: the same writers as `solve` and `masks`.
    #[test]
    fn export_writes_meshes_and_masks() {
        let dir = tempfile::tempdir().unwrap();
        let n = 64;
        let heights: Vec<f32> = (0..n * n)
            .map(|i| ((i % n) as f32 * 0.2).sin() * 30.0 + (i / n) as f32)
            .collect();
        let glb = dir.path().join("m.glb");
        let msg = export(&glb, n, &heights, [10.0, 10.0]).unwrap();
        // 65 x 65 corners of the 64 cells: 2 triangles per square.
        assert!(msg.contains(&format!("{} triangles", 2 * 64 * 64)), "{msg}");
        assert_eq!(&std::fs::read(&glb).unwrap()[..4], b"glTF");
        let simple = format!("{} --max-error 1", dir.path().join("s.obj").display());
        let msg = export(Path::new(&simple), n, &heights, [10.0, 10.0]).unwrap();
        let triangles: usize = msg
            .split(": ")
            .nth(1)
            .and_then(|t| t.split(' ').next())
            .and_then(|t| t.parse().ok())
            .unwrap();
        assert!(triangles < 2 * 64 * 64, "{msg}");
        let masks = dir.path().join("masks");
        let request = format!("{} --masks exr", masks.display());
        let msg = export(Path::new(&request), n, &heights, [10.0, 10.0]).unwrap();
        assert!(msg.contains("masks written"), "{msg}");
        for f in [
            "slope.exr",
            "curvature.exr",
            "flow.exr",
            "height.exr",
            "hillshade.png",
        ] {
            assert!(masks.join(f).is_file(), "{f}");
        }
        let slope = terrasketch_raster::read_heightmap(&masks.join("slope.exr")).unwrap();
        assert_eq!((slope.width, slope.height), (64, 64));
        // Refused before writing: tiles of a mesh, an error bound on a heightmap, a bad bound.
        for bad in [
            "x.glb --tiles 2,2",
            "x.tif --max-error 1",
            "x.glb --max-error -1",
            "x --masks tga",
        ] {
            let request = format!("{}/{bad}", dir.path().display());
            assert!(
                export(Path::new(&request), n, &heights, [10.0, 10.0]).is_err(),
                "{bad}"
            );
        }
        assert!(!dir.path().join("x.glb").exists() && !dir.path().join("x.tif").exists());
    }

    #[test]
    fn export_requests_parse_like_the_command_line() {
        let r = ExportRequest::parse("my map.tif").unwrap();
        assert_eq!(r.path.to_str(), Some("my map.tif"));
        assert!(r.size.is_none() && r.tiles.is_none());
        let r = ExportRequest::parse("w.png --size 1025 --tiles 4,4 --overlap 8").unwrap();
        assert_eq!((r.path.to_str(), r.size), (Some("w.png"), Some(1025)));
        let t = r.tiles.unwrap();
        assert_eq!((t.nx, t.ny, t.overlap), (4, 4, 8));
        for bad in [
            "w.tif --size",
            "w.tif --size x",
            "w.tif --colour red",
            "w.tif --overlap 2",
        ] {
            assert!(ExportRequest::parse(bad).is_err(), "{bad}");
        }
    }
}
