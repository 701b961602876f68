//! `terrasketch metrics`: terrain descriptors of a heightmap, optionally compared with a reference.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use terrasketch_synthesis::metrics::{Metrics, compare, terrain_metrics};
use terrasketch_synthesis::{LoadOptions, load_dem};

/// Arguments of `terrasketch metrics`.
pub struct MetricsArgs {
    pub file: PathBuf,
    pub reference: Option<PathBuf>,
    pub cell_size_m: Option<f64>,
    pub json: bool,
}

/// Loads a heightmap: real DEM formats through the synthesis loaders, terrasketch's own outputs
/// (EXR, R16, PNG with stretch chunks) through the raster crate.
fn load(path: &Path, cell_size_m: Option<f64>) -> Result<(Vec<f32>, usize, usize, [f64; 2])> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .unwrap_or_default();
    let via_raster = |why: Option<anyhow::Error>| -> Result<(Vec<f32>, usize, usize, [f64; 2])> {
        let m = terrasketch_raster::read_heightmap(path).with_context(|| match &why {
            Some(e) => format!(
                "cannot read {} as a DEM ({e:#}) nor as a heightmap",
                path.display()
            ),
            None => format!("cannot read {}", path.display()),
        })?;
        let cell = cell_size_m.map(|c| [c, c]).unwrap_or(m.cell_size_m);
        Ok((m.data, m.width, m.height, cell))
    };
    if ext == "exr" || ext == "r16" {
        return via_raster(None);
    }
    let opts = LoadOptions {
        cell_size_m,
        ..LoadOptions::default()
    };
    match load_dem(path, &opts) {
        Ok(d) => Ok((d.heights_m, d.width, d.height, d.cell_size_m)),
        Err(e) => via_raster(Some(e.into())),
    }
}

fn metrics_of(path: &Path, cell_size_m: Option<f64>) -> Result<Metrics> {
    let (h, w, ht, cell) = load(path, cell_size_m)?;
    if w < 16 || ht < 16 {
        bail!(
            "{} is {w} x {ht} cells: metrics need at least 16 x 16",
            path.display()
        );
    }
    Ok(terrain_metrics(&h, w, ht, cell))
}

/// Computes and prints the metrics.
pub fn run(args: &MetricsArgs) -> Result<()> {
    if let Some(c) = args.cell_size_m
        && !(c.is_finite() && c > 0.0)
    {
        bail!("--cell-size must be a positive number of metres, got {c}");
    }
    let m = metrics_of(&args.file, args.cell_size_m)?;
    let reference = match &args.reference {
        Some(r) => Some(metrics_of(r, args.cell_size_m)?),
        None => None,
    };
    let comparison = reference.as_ref().map(|r| compare(&m, r));
    let out = serde_json::json!({
        "file": args.file.display().to_string(),
        "metrics": m,
        "reference": args.reference.as_ref().map(|p| p.display().to_string()),
        "reference_metrics": reference,
        "comparison": comparison,
    });
    if args.json {
        println!("{out}");
    } else {
        println!("{}", serde_json::to_string_pretty(&out)?);
    }
    Ok(())
}
