//! Atomic file replacement: write a temporary file next to the target, fsync it, rename it over
//! the target. Readers see the old file or the new one, never a mix; on error the target is
//! untouched and the temporary file is removed.

use std::ffi::OsString;
use std::fs::{self, File, OpenOptions};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use crate::RasterError;

/// Distinguishes temporary files of concurrent writes within this process.
static NEXT_TEMP_ID: AtomicU64 = AtomicU64::new(0);

/// Replaces the file at `path` with `bytes`, atomically.
///
/// The temporary file is `.NAME.tmp-PID-N` in the target's directory (the same file system,
/// so the rename is atomic). Every error is reported as [`RasterError::Io`] on `path`.
pub(crate) fn write_atomically(path: &Path, bytes: &[u8]) -> Result<(), RasterError> {
    let temp_path = temp_path_for(path)?;
    // `create_new` never clobbers a stray file of the same name; a missing or read-only
    // directory fails here, before anything exists.
    let mut file = OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(&temp_path)
        .map_err(|source| RasterError::io(path, source))?;

    let written = write_and_sync(&mut file, bytes);
    drop(file);
    let renamed = written.and_then(|()| fs::rename(&temp_path, path));
    if let Err(source) = renamed {
        // The error being returned is the one that matters; a failed clean-up of the temporary
        // file cannot be reported any better than that error.
        let _ = fs::remove_file(&temp_path);
        return Err(RasterError::io(path, source));
    }
    sync_directory(path);
    Ok(())
}

/// `.NAME.tmp-PID-N` in the directory of `path`.
fn temp_path_for(path: &Path) -> Result<PathBuf, RasterError> {
    let Some(name) = path.file_name() else {
        let source = std::io::Error::new(
            std::io::ErrorKind::InvalidInput,
            "the path does not end in a file name",
        );
        return Err(RasterError::io(path, source));
    };
    let id = NEXT_TEMP_ID.fetch_add(1, Ordering::Relaxed);
    let mut temp_name = OsString::from(".");
    temp_name.push(name);
    temp_name.push(format!(".tmp-{}-{id}", std::process::id()));
    Ok(path.with_file_name(temp_name))
}

/// Writes all of `bytes` and waits until they are on disk.
fn write_and_sync(file: &mut File, bytes: &[u8]) -> std::io::Result<()> {
    file.write_all(bytes)?;
    file.flush()?;
    file.sync_all()
}

/// Makes the rename itself durable by syncing the directory entry (Unix only).
///
/// Best effort: the new file is already in place and complete, and some file systems refuse to
/// fsync a directory, so a failure here is not worth failing the write for.
fn sync_directory(path: &Path) {
    #[cfg(unix)]
    {
        let directory = match path.parent() {
            Some(parent) if !parent.as_os_str().is_empty() => parent,
            _ => Path::new("."),
        };
        if let Ok(directory) = File::open(directory) {
            let _ = directory.sync_all();
        }
    }
    #[cfg(not(unix))]
    let _ = path;
}
