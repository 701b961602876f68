//! `terrasketch metrics`: terrain descriptors of a heightmap, optionally compared with a reference.

use std::path::{Path, PathBuf};

use anyhow::{Result, bail};
use serde_json::{Value, json};
use terrasketch_raster::{Raster, ReadOptions, Transform, read_raster};
use terrasketch_synthesis::metrics::{Metrics, compare, terrain_metrics};

/// Arguments of `terrasketch metrics`.
pub struct MetricsArgs {
    pub file: PathBuf,
    pub reference: Option<PathBuf>,
    pub cell_size_m: Option<f64>,
    pub json: bool,
}

/// Loads a heightmap or DEM of any format through the raster crate's one reader.
fn load(path: &Path, cell_size_m: Option<f64>) -> Result<Raster> {
    let options = ReadOptions {
        cell_size_m,
        unit_cells_when_absent: true,
        ..ReadOptions::default()
    };
    let raster = read_raster(path, &options)?;
    for w in &raster.source.warnings {
        eprintln!("terrasketch: warning: {}: {w}", path.display());
    }
    Ok(raster)
}

fn metrics_of(path: &Path, cell_size_m: Option<f64>) -> Result<(Metrics, Value)> {
    let raster = load(path, cell_size_m)?;
    let m = &raster.map;
    if m.width < 16 || m.height < 16 {
        bail!(
            "{} is {} x {} cells: metrics need at least 16 x 16",
            path.display(),
            m.width,
            m.height
        );
    }
    let metrics = terrain_metrics(&m.data, m.width, m.height, m.cell_size_m);
    Ok((metrics, describe(&raster)))
}

/// What the file says about itself: format, size, cell size, CRS, transform and no-data.
fn describe(raster: &Raster) -> Value {
    let source = &raster.source;
    let georef = source.georef.as_ref().map(|g| {
        let transform = match &g.transform {
            Transform::ScaleTiepoints { scale, tiepoints } => {
                json!({ "pixel_scale": scale, "tiepoints": tiepoints })
            }
            Transform::Matrix(m) => json!({ "matrix": m }),
        };
        json!({
            "epsg": g.epsg(),
            "pixel_is_point": g.pixel_is_point(),
            "transform": transform,
            "geo_key_directory": g.geo_keys,
        })
    });
    json!({
        "format": source.format.name(),
        "sample_type": source.sample_type,
        "width": raster.map.width,
        "height": raster.map.height,
        "cell_size_m": raster.map.cell_size_m,
        "horizontal_units": format!("{:?}", source.horizontal_units).to_lowercase(),
        "native_cell_size": source.native_cell_size,
        "nodata": source.nodata,
        "nodata_cells_filled": raster.filled_cells(),
        "georeference": georef,
    })
}

/// Computes and prints the metrics.
pub fn run(args: &MetricsArgs) -> Result<()> {
    if let Some(c) = args.cell_size_m
        && !(c.is_finite() && c > 0.0)
    {
        bail!("--cell-size must be a positive number of metres, got {c}");
    }
    let (m, file) = metrics_of(&args.file, args.cell_size_m)?;
    let (reference, reference_file) = match &args.reference {
        Some(r) => {
            let (metrics, file) = metrics_of(r, args.cell_size_m)?;
            (Some(metrics), Some(file))
        }
        None => (None, None),
    };
    let comparison = reference.as_ref().map(|r| compare(&m, r));
    let out = json!({
        "file": args.file.display().to_string(),
        "source": file,
        "metrics": m,
        "reference": args.reference.as_ref().map(|p| p.display().to_string()),
        "reference_source": reference_file,
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
