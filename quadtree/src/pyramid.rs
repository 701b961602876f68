//! The min/max height pyramid: exact height bounds of every quadtree node, from a few KB of data.

use crate::QuadtreeError;

/// Per-cell minimum and maximum of the full-resolution heights, for a chain of square levels
/// from the finest stored one (e.g. 64x64) down to 1x1.
///
/// Cells are indexed `row * side + column`, row 0 south, column 0 west, like the heightmap. A
/// cell of a level with side `s` covers the fraction `[c/s, (c+1)/s] x [r/s, (r+1)/s]` of the
/// terrain extent. The solver produces it on the GPU (a few KB read back); [`Self::from_heights`]
/// builds the same thing from a full grid on the CPU.
#[derive(Debug, Clone, PartialEq)]
pub struct MinMaxPyramid {
    /// All levels, coarsest (1x1) first: depth `d` has side `2^d` and starts at `offsets[d]`.
    cells: Vec<[f32; 2]>,
    /// Start of each depth in `cells`; `offsets.len() == finest_depth + 1`.
    offsets: Vec<usize>,
    /// log2 of the finest stored side.
    finest_depth: u32,
}

impl MinMaxPyramid {
    /// Builds a pyramid from levels given finest first: `(side, cells)` with `cells[row * side +
    /// column] = [min, max]`.
    ///
    /// Checks that the first side is a power of two, each next side is half the previous one, the
    /// last is 1, each level holds `side * side` cells, every value is finite with `min <= max`,
    /// and every coarse cell is exactly the min/max of its four finer cells.
    pub fn from_levels(levels: Vec<(usize, Vec<[f32; 2]>)>) -> Result<Self, QuadtreeError> {
        let Some(&(finest_side, _)) = levels.first() else {
            return Err(QuadtreeError::EmptyPyramid);
        };
        if !finest_side.is_power_of_two() {
            return Err(QuadtreeError::SideNotPowerOfTwo {
                level: 0,
                side: finest_side,
            });
        }
        let mut expected = finest_side;
        for (level, (side, cells)) in levels.iter().enumerate() {
            if *side != expected {
                return Err(QuadtreeError::SidesDoNotHalve {
                    level,
                    side: *side,
                    expected,
                });
            }
            if cells.len() != side * side {
                let (expected, got) = (side * side, cells.len());
                return Err(QuadtreeError::WrongCellCount {
                    level,
                    expected,
                    got,
                });
            }
            for (cell, &[min, max]) in cells.iter().enumerate() {
                if !min.is_finite() || !max.is_finite() {
                    return Err(QuadtreeError::NonFinite { level, cell });
                }
                if min > max {
                    return Err(QuadtreeError::MinAboveMax {
                        level,
                        cell,
                        min,
                        max,
                    });
                }
            }
            expected = side / 2;
        }
        let last_side = levels[levels.len() - 1].0;
        if last_side != 1 {
            return Err(QuadtreeError::CoarsestNotOneByOne { side: last_side });
        }
        for (level, pair) in levels.windows(2).enumerate() {
            let ((fine_side, fine), (side, coarse)) = (&pair[0], &pair[1]);
            for (cell, &bounds) in coarse.iter().enumerate() {
                let (column, row) = (cell % side, cell / side);
                if reduce_children(fine, *fine_side, column, row) != bounds {
                    return Err(QuadtreeError::NotNested {
                        level: level + 1,
                        cell,
                    });
                }
            }
        }
        let finest_depth = finest_side.trailing_zeros();
        let mut offsets = Vec::with_capacity(levels.len());
        let mut cells = Vec::with_capacity(levels.iter().map(|(_, c)| c.len()).sum());
        for (_, level_cells) in levels.into_iter().rev() {
            offsets.push(cells.len());
            cells.extend_from_slice(&level_cells);
        }
        Ok(Self {
            cells,
            offsets,
            finest_depth,
        })
    }

    /// Builds the pyramid of a full `side x side` height grid (`heights[row * side + column]`,
    /// row 0 south), keeping levels of at most `max_side x max_side` cells.
    ///
    /// Used by tests and by the CPU fallback; the GPU path reads the same levels back and calls
    /// [`Self::from_levels`].
    pub fn from_heights(
        side: usize,
        heights: &[f32],
        max_side: usize,
    ) -> Result<Self, QuadtreeError> {
        if !side.is_power_of_two() {
            return Err(QuadtreeError::SideNotPowerOfTwo { level: 0, side });
        }
        if !max_side.is_power_of_two() {
            return Err(QuadtreeError::SideNotPowerOfTwo {
                level: 0,
                side: max_side,
            });
        }
        if heights.len() != side * side {
            let (expected, got) = (side * side, heights.len());
            return Err(QuadtreeError::WrongCellCount {
                level: 0,
                expected,
                got,
            });
        }
        if let Some(cell) = heights.iter().position(|h| !h.is_finite()) {
            return Err(QuadtreeError::NonFinite { level: 0, cell });
        }
        let top = side.min(max_side);
        let block = side / top;
        let mut finest = vec![[f32::INFINITY, f32::NEG_INFINITY]; top * top];
        for (j, row) in heights.chunks_exact(side).enumerate() {
            for (i, &h) in row.iter().enumerate() {
                let b = &mut finest[(j / block) * top + i / block];
                b[0] = b[0].min(h);
                b[1] = b[1].max(h);
            }
        }
        let mut levels = vec![(top, finest)];
        while levels[levels.len() - 1].0 > 1 {
            let (fine_side, fine) = &levels[levels.len() - 1];
            let s = fine_side / 2;
            let coarse = (0..s * s)
                .map(|c| reduce_children(fine, *fine_side, c % s, c / s))
                .collect();
            levels.push((s, coarse));
        }
        Self::from_levels(levels)
    }

    /// Side of the finest stored level (e.g. 64).
    pub fn finest_side(&self) -> usize {
        1 << self.finest_depth
    }

    /// `[min, max]` of the heights over the whole terrain (the 1x1 level).
    pub fn total_bounds(&self) -> [f32; 2] {
        self.cells[0]
    }

    /// Bounds of the quadtree node at `depth` (root = 0, side `2^depth` nodes) and column/row
    /// `(ix, iy)`. Exact for `2^depth <= finest_side()`; finer nodes inherit the bounds of the
    /// finest stored cell that contains them (conservative). Indices out of range are clamped.
    #[inline]
    pub fn node_bounds(&self, depth: u32, ix: u32, iy: u32) -> [f32; 2] {
        let (d, shift) = if depth <= self.finest_depth {
            (depth, 0)
        } else {
            (self.finest_depth, depth - self.finest_depth)
        };
        let last = (1u32 << d) - 1;
        let (i, j) = ((ix >> shift).min(last), (iy >> shift).min(last));
        self.cells[self.offsets[d as usize] + ((j as usize) << d) + i as usize]
    }

    /// `[min, max]` of the heights over the square `[x0, x0 + size] x [y0, y0 + size]`, in
    /// fractions of the extent (clamped to `[0, 1]`).
    ///
    /// Exact for quadtree-aligned squares down to the finest stored cell (`x0`, `y0` multiples of
    /// `size = 2^-d`); otherwise the union of the stored cells the square overlaps (always a
    /// superset of the true range). The smallest stored cells at least as fine as `size` are used.
    pub fn bounds(&self, x0: f32, y0: f32, size: f32) -> [f32; 2] {
        let clamp01 = |v: f32| if v.is_nan() { 0.0 } else { v.clamp(0.0, 1.0) };
        let (x0, y0) = (clamp01(x0), clamp01(y0));
        let (x1, y1) = (clamp01(x0 + size.max(0.0)), clamp01(y0 + size.max(0.0)));
        // Coarsest depth whose cells are no larger than `size`.
        let mut depth = 0;
        while depth < self.finest_depth && (1.0 / (1u64 << depth) as f32) > size {
            depth += 1;
        }
        let side = 1usize << depth;
        let to_cell = |v: f32| ((v * side as f32).floor() as usize).min(side - 1);
        let (i0, j0) = (to_cell(x0), to_cell(y0));
        // The last cell whose start lies strictly before the end (an end on a cell boundary does
        // not pull in the next cell).
        let last_before = |v: f32, first: usize| {
            ((v * side as f32).ceil() as usize)
                .saturating_sub(1)
                .clamp(first, side - 1)
        };
        let (i1, j1) = (last_before(x1, i0), last_before(y1, j0));
        let base = self.offsets[depth as usize];
        let mut out = [f32::INFINITY, f32::NEG_INFINITY];
        for j in j0..=j1 {
            for i in i0..=i1 {
                let [lo, hi] = self.cells[base + j * side + i];
                out = [out[0].min(lo), out[1].max(hi)];
            }
        }
        out
    }
}

/// Min/max of the four cells of `fine` (side `fine_side`) under coarse cell `(column, row)`.
fn reduce_children(fine: &[[f32; 2]], fine_side: usize, column: usize, row: usize) -> [f32; 2] {
    let mut out = [f32::INFINITY, f32::NEG_INFINITY];
    for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
        let [lo, hi] = fine[(2 * row + dy) * fine_side + 2 * column + dx];
        out = [out[0].min(lo), out[1].max(hi)];
    }
    out
}
