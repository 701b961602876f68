//! Files: opening sketches (checked before anything changes), atomic saves, heightmap export and the
//! periodic recovery autosave.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::{Context, Result};
use terrasketch_sketch::{Sketch, load_sketch, save_sketch_atomic, validate};

/// How often unsaved work is written to the recovery file.
pub const AUTOSAVE_EVERY: Duration = Duration::from_secs(30);

/// Reads and validates a sketch; on any problem returns the message and changes nothing.
pub fn open_sketch(path: &Path) -> Result<Sketch> {
    let parsed = load_sketch(path).with_context(|| format!("cannot open {}", path.display()))?;
    for w in &parsed.warnings {
        eprintln!("terrasketch: warning: {}: {w}", path.display());
    }
    Ok(parsed.sketch)
}

/// Validates, then saves atomically.
pub fn save(sketch: &Sketch, path: &Path) -> Result<()> {
    validate(sketch)
        .with_context(|| format!("the sketch is not valid, not saved to {}", path.display()))?;
    save_sketch_atomic(sketch, path).with_context(|| format!("cannot save {}", path.display()))
}

/// Exports south-up heights (`n x n`) in the format the extension names (as `terrasketch solve`).
pub fn export(path: &Path, n: usize, heights: &[f32], cell_size_m: [f64; 2]) -> Result<String> {
    crate::output::check_writable(path)?;
    let info = crate::output::write_south_up(path, n, heights, cell_size_m)?;
    Ok(match info.stretch {
        Some(s) => format!(
            "exported {} ({} .. {} m stretched)",
            path.display(),
            s.min_m,
            s.max_m
        ),
        None => format!("exported {}", path.display()),
    })
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
