//! Tiled export: one world raster cut into `NX x NY` files with shared edges, plus a JSON
//! manifest of the tiles and their extents.
//!
//! Tile `i` counts west to east and tile `j` south to north (world x and y), both from 0. Along
//! an axis of `n` samples cut into `k` tiles:
//! - corner-sampled worlds (`n - 1` divisible by `k`): tile `t` holds samples
//!   `t * T ..= (t + 1) * T` with `T = (n - 1) / k`, so neighbours share their edge samples;
//! - cell-centred worlds (`n` divisible by `k`): tile `t` holds cells `t * T .. (t + 1) * T`,
//!   `T = n / k`; neighbours abut without sharing.
//!
//! `--overlap PX` widens every tile by `PX` samples on each side that has a neighbour. Every
//! tile is cut from the one world raster, so shared samples are bit-identical; 16-bit formats
//! use the world's stretch so that equal heights get equal codes.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use terrasketch_raster::{
    Format, Georef, Heightmap, Sampling, Stretch, WriteOptions, write_file_atomically,
    write_heightmap_with,
};

use crate::output::{Place, refused};

/// Most tiles along one axis.
pub const MAX_TILES_PER_AXIS: usize = 256;

/// How to cut the export.
#[derive(Debug, Clone)]
pub struct TileSpec {
    /// Tiles west to east.
    pub nx: usize,
    /// Tiles south to north.
    pub ny: usize,
    /// Extra samples on each side that has a neighbour.
    pub overlap: usize,
    /// File name pattern with `{name}`, `{i}`, `{j}` and `{ext}`.
    pub pattern: String,
}

/// One tile: its indices and its window in the north-up world raster.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tile {
    /// Column index, west to east.
    pub i: usize,
    /// Row index, south to north.
    pub j: usize,
    /// First column of the window.
    pub column: usize,
    /// First (northernmost) row of the window.
    pub row: usize,
    /// Columns.
    pub width: usize,
    /// Rows.
    pub height: usize,
}

impl TileSpec {
    /// The command line's `--tiles NX,NY`, `--overlap PX` and `--tile-name PATTERN`, checked.
    pub fn from_args(tiles: &str, overlap: usize, pattern: &str) -> Result<TileSpec> {
        let [nx, ny] = parse_tiles(tiles)?;
        check_pattern(pattern)?;
        Ok(TileSpec {
            nx,
            ny,
            overlap,
            pattern: pattern.to_owned(),
        })
    }
}

/// Parses `--tiles NX,NY` (each 1 to [`MAX_TILES_PER_AXIS`]).
pub fn parse_tiles(text: &str) -> Result<[usize; 2]> {
    let bad = || {
        refused(format!(
            "--tiles {text:?} is not NX,NY: two whole numbers from 1 to {MAX_TILES_PER_AXIS}, e.g. 4,4"
        ))
    };
    let mut parts = text.split(',').map(|p| p.trim().parse::<usize>());
    match (parts.next(), parts.next(), parts.next()) {
        (Some(Ok(nx)), Some(Ok(ny)), None)
            if (1..=MAX_TILES_PER_AXIS).contains(&nx) && (1..=MAX_TILES_PER_AXIS).contains(&ny) =>
        {
            Ok([nx, ny])
        }
        _ => Err(bad()),
    }
}

/// `(first sample, sample count)` of each of `tiles` tiles along an axis of `samples` samples,
/// in increasing sample order.
fn axis(
    samples: usize,
    sampling: Sampling,
    tiles: usize,
    overlap: usize,
    flag: &str,
) -> Result<Vec<(usize, usize)>> {
    let span = match sampling {
        Sampling::Corners => samples - 1,
        Sampling::Cells => samples,
    };
    let what = match sampling {
        Sampling::Corners => format!("the {span} intervals between {samples} corner samples"),
        Sampling::Cells => format!("the {samples} cells"),
    };
    if !span.is_multiple_of(tiles) || span / tiles < 2 {
        return Err(refused(format!(
            "--tiles: {tiles} {flag} tiles cannot share {what} equally (at least 2 each); \
             corner-sampled sizes such as 4097 split into 2, 4, 8 ... tiles"
        )));
    }
    let core = span / tiles;
    if overlap > core {
        return Err(refused(format!(
            "--overlap {overlap} is wider than a tile ({core} samples)"
        )));
    }
    let own = match sampling {
        Sampling::Corners => core + 1,
        Sampling::Cells => core,
    };
    Ok((0..tiles)
        .map(|t| {
            let start = (t * core).saturating_sub(overlap);
            let end = (t * core + own + overlap).min(samples);
            (start, end - start)
        })
        .collect())
}

/// The tiles of a `width x height` world, `j = 0` first (south), `i = 0` first (west).
pub fn layout(
    width: usize,
    height: usize,
    sampling: Sampling,
    spec: &TileSpec,
) -> Result<Vec<Tile>> {
    let xs = axis(width, sampling, spec.nx, spec.overlap, "west-east")?;
    let ys = axis(height, sampling, spec.ny, spec.overlap, "south-north")?;
    let mut tiles = Vec::with_capacity(spec.nx * spec.ny);
    for (j, &(south_start, rows)) in ys.iter().enumerate() {
        for (i, &(column, width)) in xs.iter().enumerate() {
            tiles.push(Tile {
                i,
                j,
                column,
                // Samples along y count from the south; the raster's rows from the north.
                row: height - south_start - rows,
                width,
                height: rows,
            });
        }
    }
    Ok(tiles)
}

/// `[min x, min y, max x, max y]` in CRS units of a `width x height` raster's outer pixel
/// corners under `georef`.
fn crs_bounds(georef: &Georef, width: usize, height: usize) -> [f64; 4] {
    let half = if georef.pixel_is_point() { 0.5 } else { 0.0 };
    let corners = [
        georef.model_xy(-half, -half),
        georef.model_xy(width as f64 - half, height as f64 - half),
    ];
    [
        corners[0][0].min(corners[1][0]),
        corners[0][1].min(corners[1][1]),
        corners[0][0].max(corners[1][0]),
        corners[0][1].max(corners[1][1]),
    ]
}

/// The file name of tile `(i, j)` from the pattern.
pub(crate) fn tile_name(pattern: &str, name: &str, ext: &str, i: usize, j: usize) -> String {
    pattern
        .replace("{name}", name)
        .replace("{ext}", ext)
        .replace("{i}", &i.to_string())
        .replace("{j}", &j.to_string())
}

/// Checks the pattern before any work: it must name each tile differently and stay in the
/// output's folder.
pub fn check_pattern(pattern: &str) -> Result<()> {
    if !(pattern.contains("{i}") && pattern.contains("{j}")) {
        return Err(refused(format!(
            "--tile-name {pattern:?} must contain {{i}} and {{j}}"
        )));
    }
    if pattern.contains('/') || pattern.contains('\\') || pattern.len() > 200 {
        return Err(refused(format!(
            "--tile-name {pattern:?} must be a file name (no folder), at most 200 characters"
        )));
    }
    Ok(())
}

/// What [`write_tiles`] wrote.
pub struct TilesWritten {
    /// The manifest's path.
    pub manifest: PathBuf,
    /// The tiles' files.
    pub files: Vec<PathBuf>,
    /// The world stretch of 16-bit formats.
    pub stretch: Option<Stretch>,
}

/// Cuts `world` (north-up, `sampling`) into tiles next to `output` and writes them, then the
/// manifest `NAME.tiles.json` (atomically, last, so a manifest means every tile is written).
/// With a georeference in `place`, each GeoTIFF tile gets the world's CRS and transform moved
/// to its window, and the no-data value.
pub fn write_tiles(
    output: &Path,
    world: &Heightmap,
    sampling: Sampling,
    format: Format,
    spec: &TileSpec,
    place: &Place,
) -> Result<TilesWritten> {
    let tiles = layout(world.width, world.height, sampling, spec)?;
    let folder = output.parent().unwrap_or(Path::new(""));
    let name = output
        .file_stem()
        .and_then(|s| s.to_str())
        .ok_or_else(|| refused(format!("{}: the file name is not UTF-8", output.display())))?;
    let ext = output.extension().and_then(|s| s.to_str()).unwrap_or("");
    let stretch = matches!(format, Format::Png16 | Format::R16).then(|| {
        let (min_m, max_m) = world
            .data
            .iter()
            .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &h| {
                (lo.min(h), hi.max(h))
            });
        Stretch { min_m, max_m }
    });
    let [dx, dy] = world.cell_size_m;
    // Position of a sample's west / south side: cell-centred tiles cover their cells' edges,
    // corner-sampled tiles span their first to last sample.
    let edge = |count: usize| match sampling {
        Sampling::Cells => count as f64,
        Sampling::Corners => count.saturating_sub(1) as f64,
    };
    let mut files = Vec::with_capacity(tiles.len());
    let mut entries = Vec::with_capacity(tiles.len());
    for tile in &tiles {
        let file = tile_name(&spec.pattern, name, ext, tile.i, tile.j);
        let path = folder.join(&file);
        let mut data = Vec::with_capacity(tile.width * tile.height);
        for r in tile.row..tile.row + tile.height {
            let start = r * world.width + tile.column;
            data.extend_from_slice(&world.data[start..start + tile.width]);
        }
        let map = Heightmap {
            width: tile.width,
            height: tile.height,
            data,
            cell_size_m: world.cell_size_m,
        };
        let south_rows = world.height - tile.row - tile.height;
        let x_min_m = tile.column as f64 * dx;
        let y_min_m = south_rows as f64 * dy;
        let georef = place
            .georef
            .as_ref()
            .map(|g| g.remapped([tile.column as f64, 1.0], [tile.row as f64, 1.0]));
        let options = WriteOptions {
            sampling,
            stretch,
            origin_m: [x_min_m, y_min_m],
            georef: georef.as_ref(),
            nodata: place.nodata,
        };
        write_heightmap_with(&path, &map, &options)
            .with_context(|| format!("cannot write tile {}", path.display()))?;
        entries.push(serde_json::json!({
            "i": tile.i,
            "j": tile.j,
            "file": file,
            "column": tile.column,
            "row": tile.row,
            "width": tile.width,
            "height": tile.height,
            "x_min_m": x_min_m,
            "x_max_m": x_min_m + edge(tile.width) * dx,
            "y_min_m": y_min_m,
            "y_max_m": y_min_m + edge(tile.height) * dy,
            "crs_bounds": georef.as_ref().map(|g| crs_bounds(g, tile.width, tile.height)),
        }));
        files.push(path);
    }
    let manifest = serde_json::json!({
        "format": "terrasketch-tiles",
        "version": 1,
        "width": world.width,
        "height": world.height,
        "sampling": sampling.name(),
        "cell_size_m": world.cell_size_m,
        "extent_m": [edge(world.width) * dx, edge(world.height) * dy],
        "tiles_x": spec.nx,
        "tiles_y": spec.ny,
        "overlap": spec.overlap,
        "stretch_min_m": stretch.map(|s| s.min_m),
        "stretch_max_m": stretch.map(|s| s.max_m),
        "crs_epsg": place.georef.as_ref().and_then(|g| g.epsg()),
        "nodata": place.nodata,
        "tiles": entries,
    });
    let manifest_path = folder.join(format!("{name}.tiles.json"));
    let text = serde_json::to_string_pretty(&manifest)?;
    write_file_atomically(&manifest_path, text.as_bytes())
        .with_context(|| format!("cannot write {}", manifest_path.display()))?;
    Ok(TilesWritten {
        manifest: manifest_path,
        files,
        stretch,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec(nx: usize, ny: usize, overlap: usize) -> TileSpec {
        TileSpec {
            nx,
            ny,
            overlap,
            pattern: "{name}_x{i}_y{j}.{ext}".into(),
        }
    }

    #[test]
    fn corner_tiles_share_edges_and_overlap_widens_inner_sides() {
        let tiles = layout(257, 257, Sampling::Corners, &spec(4, 4, 0)).unwrap();
        assert_eq!(tiles.len(), 16);
        // South-west tile: the last 65 rows, the first 65 columns.
        assert_eq!(
            tiles[0],
            Tile {
                i: 0,
                j: 0,
                column: 0,
                row: 192,
                width: 65,
                height: 65
            }
        );
        assert_eq!(tiles[1].column, 64);
        let tiles = layout(257, 257, Sampling::Corners, &spec(4, 4, 3)).unwrap();
        assert_eq!(
            (tiles[0].width, tiles[1].column, tiles[1].width),
            (68, 61, 71)
        );
        assert!(layout(257, 257, Sampling::Corners, &spec(3, 4, 0)).is_err());
        assert!(layout(257, 257, Sampling::Corners, &spec(4, 4, 65)).is_err());
        let cells = layout(256, 256, Sampling::Cells, &spec(4, 2, 0)).unwrap();
        assert_eq!(
            (cells[1].column, cells[1].width, cells[0].height),
            (64, 64, 128)
        );
    }

    #[test]
    fn tile_arguments_are_checked() {
        assert_eq!(parse_tiles("4,2").unwrap(), [4, 2]);
        for bad in ["4", "0,4", "4,4,4", "a,b", "999,1", ""] {
            assert!(parse_tiles(bad).is_err(), "{bad}");
        }
        assert!(check_pattern("{name}_{i}_{j}.{ext}").is_ok());
        assert!(check_pattern("{name}_{i}.{ext}").is_err());
        assert!(check_pattern("../{i}_{j}.tif").is_err());
    }
}
