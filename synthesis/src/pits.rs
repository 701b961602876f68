//! Depression (pit) handling on a heightmap by priority flood: filling, breaching and a hybrid.
//!
//! All three modes share one flood (Soille; Barnes, Lehman & Mulla 2014). Seeds are the border
//! cells and the user-marked sinks; a binary min-heap pops the lowest open cell `p`, and every
//! unvisited 8-neighbour `n` gets `p` as its parent in the flood tree. Following parents from any
//! cell leads to a seed over the lowest possible pass (the spill point), so the flood tree holds,
//! for every cell, the least-cost path to an outlet where the cost of a path is the highest point
//! it crosses. When `n` is not strictly above `p`, `n` lies in a depression (or on a flat):
//!
//! * [`PitMode::Fill`] raises `n` to `p`'s height, or with `epsilon` to the next `f32` above it,
//!   so that flats get a tiny gradient and drain;
//! * [`PitMode::Breach`] (the default, as chosen by Scott & Dodgson 2021) keeps `n` and lowers the
//!   flood-tree path from `p` towards the outlet, each cell to the next `f32` below its
//!   predecessor, until a cell is already lower (a one-cell-wide monotone channel). Border cells
//!   may be lowered (they remain outlets); a channel that would have to lower a marked sink is
//!   not cut, and `n` is filled instead;
//! * [`PitMode::Hybrid`] breaches like `Breach` when the channel needs no cut deeper than
//!   `max_depth_m` below the original surface and no more than `max_length` lowered cells, and
//!   fills `n` (with the epsilon gradient) otherwise. Deep pits therefore get a breach down to the
//!   depth limit and the rest is filled (Lindsay's selective breaching, in spirit).
//!
//! After `Breach`, `Hybrid`, or `Fill` with `epsilon`, every cell that is not a seed has a strictly
//! lower 8-neighbour (its flood parent), so water reaches the border or a marked sink. User sinks
//! are seeds: they are never changed. Cost: O(n log n) for the heap, plus the channel walks.

use std::cmp::Reverse;
use std::collections::BinaryHeap;

/// 8-neighbour offsets `(dx, dy)`, in a fixed order so results are deterministic.
pub(crate) const N8: [(isize, isize); 8] = [
    (-1, -1),
    (0, -1),
    (1, -1),
    (-1, 0),
    (1, 0),
    (-1, 1),
    (0, 1),
    (1, 1),
];

/// How depressions are removed.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub enum PitMode {
    /// Raise each depression to its spill level.
    Fill {
        /// Add the smallest `f32` step per cell across filled areas and flats so they drain.
        epsilon: bool,
    },
    /// Carve a monotone channel from each pit cell along the flood tree to a lower outlet.
    Breach,
    /// Breach when the channel stays within both limits, fill (with epsilon) otherwise.
    Hybrid {
        /// Deepest allowed cut below the original surface, in metres.
        max_depth_m: f32,
        /// Longest allowed channel, in cells lowered.
        max_length: usize,
    },
}

impl Default for PitMode {
    /// Breaching, the method Scott & Dodgson found best.
    fn default() -> Self {
        Self::Breach
    }
}

/// What a pit-removal run did.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct PitStats {
    /// Closed depressions found before removal (connected regions a plain fill would raise,
    /// any depth, regions containing a marked sink excluded).
    pub pits_found: usize,
    /// Cells whose height changed, by any amount: the epsilon gradient and breach channels across
    /// flats (a lake surface in a DEM) change many cells by a few `f32` steps only.
    pub cells_changed: usize,
    /// Largest absolute height change in metres.
    pub max_change_m: f32,
    /// Cells raised (filled).
    pub cells_raised: usize,
    /// Cells lowered (breached).
    pub cells_lowered: usize,
}

/// Heap entry: height first, then cell index, so equal heights pop in index order (deterministic).
/// The height is kept as its `f32::total_cmp` rank in a `u32`, so ordering is two integer
/// compares (the same order as comparing the heights with `total_cmp`).
#[derive(Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
struct Entry {
    key: u32,
    i: usize,
}

impl Entry {
    fn new(h: f32, i: usize) -> Self {
        // The standard total-order map: negative values flip all bits, others the sign bit.
        let b = h.to_bits();
        let key = if b >> 31 == 1 { !b } else { b | 0x8000_0000 };
        Entry { key, i }
    }
}

const NO_PARENT: usize = usize::MAX;

/// Checks the grid shape; returns false for a mismatched or empty grid (callers then do nothing).
fn shape_ok(len: usize, width: usize, height: usize, sinks: Option<&[bool]>) -> bool {
    width > 0
        && height > 0
        && width.checked_mul(height) == Some(len)
        && sinks.is_none_or(|s| s.len() == len)
}

/// Pushes the seeds (border cells and marked sinks) and marks them closed.
fn seed(
    heights: &[f32],
    width: usize,
    height: usize,
    sinks: Option<&[bool]>,
    closed: &mut [bool],
    heap: &mut BinaryHeap<Reverse<Entry>>,
) {
    for (i, &h) in heights.iter().enumerate() {
        let (x, y) = (i % width, i / width);
        let border = x == 0 || y == 0 || x + 1 == width || y + 1 == height;
        let sink = sinks.is_some_and(|s| s[i]);
        if border || sink {
            closed[i] = true;
            heap.push(Reverse(Entry::new(h, i)));
        }
    }
}

/// Visits the unvisited 8-neighbours of cell `i`.
fn for_neighbours(i: usize, width: usize, height: usize, mut f: impl FnMut(usize)) {
    let (x, y) = ((i % width) as isize, (i / width) as isize);
    for (dx, dy) in N8 {
        let (nx, ny) = (x + dx, y + dy);
        if nx >= 0 && ny >= 0 && (nx as usize) < width && (ny as usize) < height {
            f(ny as usize * width + nx as usize);
        }
    }
}

/// A plain priority-flood fill (no epsilon): returns the spill-level surface. Marked sinks and
/// the border are outlets. Returns `None` for a mismatched grid.
pub fn filled_surface(
    heights: &[f32],
    width: usize,
    height: usize,
    sinks: Option<&[bool]>,
) -> Option<Vec<f32>> {
    if !shape_ok(heights.len(), width, height, sinks) {
        return None;
    }
    let mut out = heights.to_vec();
    let mut closed = vec![false; out.len()];
    let mut heap = BinaryHeap::new();
    seed(&out, width, height, sinks, &mut closed, &mut heap);
    while let Some(Reverse(Entry { i: p, .. })) = heap.pop() {
        let hp = out[p];
        for_neighbours(p, width, height, |n| {
            if !closed[n] {
                closed[n] = true;
                if out[n] < hp {
                    out[n] = hp;
                }
                heap.push(Reverse(Entry::new(out[n], n)));
            }
        });
    }
    Some(out)
}

/// One closed depression found by [`find_depressions`].
#[derive(Clone, Debug, PartialEq)]
pub struct Depression {
    /// Cells a plain fill raises, as row-major indices (ascending).
    pub cells: Vec<usize>,
    /// Largest fill depth in metres (spill level minus the lowest cell).
    pub depth_m: f32,
}

/// Closed depressions: the 8-connected regions of cells that a plain priority-flood fill raises.
///
/// The border drains off the grid, so a region open to the border is not a depression: the fill
/// never raises border cells, and any region that still contains a border cell is skipped
/// explicitly. Marked sinks are outlets (a lake is not a pit). Returns an empty list for a
/// mismatched grid.
pub fn find_depressions(
    heights: &[f32],
    width: usize,
    height: usize,
    sinks: Option<&[bool]>,
) -> Vec<Depression> {
    let Some(filled) = filled_surface(heights, width, height, sinks) else {
        return Vec::new();
    };
    let raised: Vec<bool> = filled.iter().zip(heights).map(|(f, h)| f > h).collect();
    let mut seen = vec![false; raised.len()];
    let mut out = Vec::new();
    let mut stack = Vec::new();
    for start in 0..raised.len() {
        if !raised[start] || seen[start] {
            continue;
        }
        seen[start] = true;
        stack.push(start);
        let mut cells = Vec::new();
        let mut depth = 0.0f32;
        let mut touches_border = false;
        while let Some(c) = stack.pop() {
            cells.push(c);
            depth = depth.max(filled[c] - heights[c]);
            let (x, y) = (c % width, c / width);
            touches_border |= x == 0 || y == 0 || x + 1 == width || y + 1 == height;
            for_neighbours(c, width, height, |n| {
                if raised[n] && !seen[n] {
                    seen[n] = true;
                    stack.push(n);
                }
            });
        }
        if !touches_border {
            cells.sort_unstable();
            out.push(Depression {
                cells,
                depth_m: depth,
            });
        }
    }
    out
}

/// Number of closed depressions deeper than `min_depth_m` (see [`find_depressions`]).
pub fn count_pits(
    heights: &[f32],
    width: usize,
    height: usize,
    sinks: Option<&[bool]>,
    min_depth_m: f32,
) -> usize {
    find_depressions(heights, width, height, sinks)
        .iter()
        .filter(|d| d.depth_m > min_depth_m)
        .count()
}

/// Removes depressions in place with the given mode (see the module documentation).
///
/// `sinks`, if given, marks cells that must stay sinks (lakes, sinkholes): they are outlets like
/// the border and are never changed. A grid whose length is not `width * height` (or whose mask
/// length differs) is left untouched and gives zero statistics.
pub fn remove_pits(
    heights: &mut [f32],
    width: usize,
    height: usize,
    sinks: Option<&[bool]>,
    mode: PitMode,
) -> PitStats {
    if !shape_ok(heights.len(), width, height, sinks) {
        return PitStats::default();
    }
    let pits_found = find_depressions(heights, width, height, sinks).len();
    PitStats {
        pits_found,
        ..remove_pits_uncounted(heights, width, height, sinks, mode)
    }
}

/// [`remove_pits`] without counting the depressions first (`pits_found` is 0): one flood fewer.
pub(crate) fn remove_pits_uncounted(
    heights: &mut [f32],
    width: usize,
    height: usize,
    sinks: Option<&[bool]>,
    mode: PitMode,
) -> PitStats {
    if !shape_ok(heights.len(), width, height, sinks) {
        return PitStats::default();
    }
    let original = heights.to_vec();
    let mut closed = vec![false; heights.len()];
    let mut parent = vec![NO_PARENT; heights.len()];
    let mut heap = BinaryHeap::new();
    seed(heights, width, height, sinks, &mut closed, &mut heap);
    let mut path = Vec::new();
    while let Some(Reverse(Entry { i: p, .. })) = heap.pop() {
        let (x, y) = ((p % width) as isize, (p / width) as isize);
        for (dx, dy) in N8 {
            let (nx, ny) = (x + dx, y + dy);
            if nx < 0 || ny < 0 || nx as usize >= width || ny as usize >= height {
                continue;
            }
            let n = ny as usize * width + nx as usize;
            if closed[n] {
                continue;
            }
            closed[n] = true;
            parent[n] = p;
            if heights[n] <= heights[p] {
                match mode {
                    PitMode::Fill { epsilon: false } => heights[n] = heights[p],
                    PitMode::Fill { epsilon: true } => heights[n] = heights[p].next_up(),
                    PitMode::Breach | PitMode::Hybrid { .. } => {
                        let limits = match mode {
                            PitMode::Hybrid {
                                max_depth_m,
                                max_length,
                            } => Some((max_depth_m, max_length)),
                            _ => None,
                        };
                        let tree = Tree {
                            parent: &parent,
                            sinks,
                            original: &original,
                        };
                        if !breach_path(heights, &tree, n, &mut path, limits) {
                            heights[n] = heights[p].next_up();
                        }
                    }
                }
            }
            heap.push(Reverse(Entry::new(heights[n], n)));
        }
    }
    let mut stats = PitStats::default();
    for (new, old) in heights.iter().zip(&original) {
        if new != old {
            stats.cells_changed += 1;
            stats.max_change_m = stats.max_change_m.max((new - old).abs());
            if new > old {
                stats.cells_raised += 1;
            } else {
                stats.cells_lowered += 1;
            }
        }
    }
    stats
}

/// The flood tree and what a breach must respect.
struct Tree<'a> {
    parent: &'a [usize],
    sinks: Option<&'a [bool]>,
    original: &'a [f32],
}

/// Lowers the flood-tree path above pit cell `n` so that it descends strictly from `n` to a cell
/// that was already lower. With `limits = Some((max_depth, max_len))` the channel is planned
/// first and nothing is changed (returning false) if a cut would exceed `max_depth` below the
/// original surface or more than `max_len` cells would be lowered.
///
/// Border cells may be lowered (they stay outlets: water leaves the grid there); marked sinks
/// never are. A channel that would have to lower a marked sink returns false, and the caller
/// fills `n` instead so it drains into the sink.
fn breach_path(
    heights: &mut [f32],
    tree: &Tree<'_>,
    n: usize,
    path: &mut Vec<(usize, f32)>,
    limits: Option<(f32, usize)>,
) -> bool {
    path.clear();
    let mut prev_h = heights[n];
    let mut q = tree.parent[n];
    while q != NO_PARENT && heights[q] >= prev_h {
        if tree.sinks.is_some_and(|s| s[q]) {
            return false;
        }
        let new_h = prev_h.next_down();
        if let Some((max_depth, max_len)) = limits
            && (tree.original[q] - new_h > max_depth || path.len() >= max_len)
        {
            return false;
        }
        path.push((q, new_h));
        prev_h = new_h;
        q = tree.parent[q];
    }
    for &(c, h) in path.iter() {
        heights[c] = h;
    }
    true
}

/// True if cell `i` (not on the border, not a sink) has no strictly lower 8-neighbour: water
/// entering it cannot leave. Used by tests and by callers checking a result.
pub fn is_interior_sink(heights: &[f32], width: usize, height: usize, i: usize) -> bool {
    if width == 0 || width.checked_mul(height) != Some(heights.len()) {
        return false;
    }
    let (x, y) = (i % width, i / width);
    if x == 0 || y == 0 || x + 1 >= width || y + 1 >= height || i >= heights.len() {
        return false;
    }
    let mut lower = false;
    for_neighbours(i, width, height, |n| lower |= heights[n] < heights[i]);
    !lower
}
