//! Writing solved heights to files, and checks done before any work starts.

use std::path::Path;

use anyhow::{Context, Result};
use terrasketch_raster::{Format, Heightmap, WriteInfo, write_heightmap};

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

/// Writes south-up solver heights (`n x n`, row 0 = south) as a north-up heightmap file.
pub fn write_south_up(
    path: &Path,
    n: usize,
    heights: &[f32],
    cell_size_m: [f64; 2],
) -> Result<WriteInfo> {
    let mut data = Vec::with_capacity(n * n);
    for j in (0..n).rev() {
        data.extend_from_slice(&heights[j * n..(j + 1) * n]);
    }
    let map = Heightmap {
        width: n,
        height: n,
        data,
        cell_size_m,
    };
    write_heightmap(path, &map).with_context(|| format!("cannot write {}", path.display()))
}

/// Peak resident memory of this process in MB (VmHWM), if the OS tells.
pub fn peak_rss_mb() -> Option<f64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb / 1024.0)
}
