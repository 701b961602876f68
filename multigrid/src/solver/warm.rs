//! Where a warm update works: the cells of the field and height problems that an edit's
//! re-rasterised windows and changed field cells can reach.

use std::ops::Range;

use super::raster::RASTER_ROWS;

/// The cells of a field problem on a level of side `side` (`f` level-0 cells per side of a cell)
/// under the re-rasterised windows (`windows`, one per group of `RASTER_ROWS` level-0 rows), with
/// a margin of one cell: a row range and one column range per row of it.
pub(super) fn field_region(side: usize, f: usize, windows: &[(usize, usize)]) -> Region {
    let mut cols = vec![(side, 0usize); side];
    for (b, &(c0, c1)) in windows.iter().enumerate() {
        if c0 >= c1 {
            continue;
        }
        let rows =
            (b * RASTER_ROWS / f).saturating_sub(1)..((b + 1) * RASTER_ROWS / f + 1).min(side);
        let (a, e) = ((c0 / f).saturating_sub(1), (c1.div_ceil(f) + 1).min(side));
        for c in &mut cols[rows] {
            *c = (c.0.min(a), c.1.max(e));
        }
    }
    trim_region(cols)
}

/// The rows holding a column range, and their ranges.
fn trim_region(cols: Vec<(usize, usize)>) -> Region {
    let lo = cols.iter().position(|c| c.0 < c.1).unwrap_or(0);
    let hi = cols.iter().rposition(|c| c.0 < c.1).map_or(0, |k| k + 1);
    let cols = if lo < hi {
        cols[lo..hi].to_vec()
    } else {
        Vec::new()
    };
    (lo..hi.max(lo), cols)
}

/// The level-0 cells where the height problem can have changed after an edit, as a row range and
/// one column range per row of it: around the re-rasterised windows (`windows`, one per group of
/// `RASTER_ROWS` rows) and the level-1 cells changed by the field solves (`fields`: row spans
/// `(row, first column, end column)`), each widened by `ASSEMBLY_MARGIN` level-0 cells.
pub(super) fn assembly_region(
    n: usize,
    windows: &[(usize, usize)],
    fields: [&[(u32, u32, u32)]; 2],
) -> Region {
    let m = ASSEMBLY_MARGIN;
    let mut cols = vec![(n, 0usize); n];
    let mut add = |rows: Range<usize>, c0: usize, c1: usize| {
        for c in &mut cols[rows.start.min(n)..rows.end.min(n)] {
            *c = (c.0.min(c0.saturating_sub(m)), c.1.max((c1 + m).min(n)));
        }
    };
    for (b, &(c0, c1)) in windows.iter().enumerate() {
        if c0 < c1 {
            add(
                (b * RASTER_ROWS).saturating_sub(m)..(b + 1) * RASTER_ROWS + m,
                c0,
                c1,
            );
        }
    }
    for spans in fields {
        for &(j, a, b) in spans {
            let (j, a, b) = (2 * j as usize, 2 * a as usize, 2 * b as usize);
            add(j.saturating_sub(m)..j + 2 + m, a, b);
        }
    }
    trim_region(cols)
}

/// Cells as row spans `(row, first column, end column)`.
pub(super) type RowSpans = Vec<(u32, u32, u32)>;

/// Cells as a row range and one column range per row of it.
pub(super) type Region = (Range<usize>, Vec<(usize, usize)>);

/// Margin, in level-0 cells, around a re-rasterised window within which the height problem's
/// right-hand side can change: a changed level-1 field cell `I` moves the prolonged field on
/// level-0 columns `2I - 2 ..= 2I + 3`, hence the edges there and the cells west of them.
const ASSEMBLY_MARGIN: usize = 4;
