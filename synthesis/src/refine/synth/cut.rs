//! The graph cut that decides which cells of its window a candidate patch takes.

use super::super::field::{unit_hash, value_noise};
use super::super::graphcut::{FlowGraph, INFINITE};
use super::{NO_OWNER, Placed, Synth};

/// The cells of a candidate's window as the cut sees them.
struct CutCells {
    /// The window `(x0, y0, x1, y1)` and its width.
    x0: i32,
    y0: i32,
    x1: i32,
    y1: i32,
    ww: usize,
    /// The candidate's value per window cell.
    b: Vec<f32>,
    /// Filled cells before the seam band: they keep the old output.
    fixed: Vec<bool>,
    /// Graph node of each filled cell the cut decides (`u32::MAX`: none).
    node: Vec<u32>,
    /// Whether the new patch takes each cell (the cut overrides it on the nodes).
    take: Vec<bool>,
    /// Nodes past the seam band, forced to the new patch.
    forced_new: Vec<usize>,
    /// Nodes.
    count: usize,
}

impl CutCells {
    fn at(&self, x: i32, y: i32) -> usize {
        (y - self.y0) as usize * self.ww + (x - self.x0) as usize
    }
}

impl Synth<'_> {
    /// Graph cut of candidate `pl` against the output in its window. Returns the cut cost and,
    /// per window cell, whether the new patch takes it. With `core`, the central quarter of the
    /// window is forced to the new patch (feature patches must carry their feature).
    pub(super) fn cut(&self, pl: &Placed, core: bool) -> (f64, Vec<bool>) {
        let mut cells = self.cut_cells(pl, core);
        if cells.count == 0 {
            return (0.0, cells.take);
        }
        let mut g = self.cut_graph(&cells, pl, core);
        let flow = g.max_flow();
        let side = g.source_side();
        for (t, &ni) in cells.take.iter_mut().zip(&cells.node) {
            if ni != u32::MAX {
                *t = side[ni as usize];
            }
        }
        (flow, cells.take)
    }

    /// Whether output cell `(x, y)` is on the map and already filled.
    fn filled(&self, x: i32, y: i32) -> bool {
        let n = self.n as i32;
        x >= 0 && y >= 0 && x < n && y < n && self.owner[(y * n + x) as usize] != NO_OWNER
    }

    /// Whether `(x, y)` lies in the central quarter a feature patch (`core`) must keep.
    fn core_cell(&self, pl: &Placed, core: bool, x: i32, y: i32) -> bool {
        let q = (self.half / 4).max(1);
        core && (x - pl.p[0]).abs() <= q && (y - pl.p[1]).abs() <= q
    }

    /// Which cells of `pl`'s window stay, which the cut decides, and which go to the new patch.
    fn cut_cells(&self, pl: &Placed, core: bool) -> CutCells {
        let n = self.n as i32;
        let (x0, y0, x1, y1) = self.window(pl.p);
        let (ww, wh) = ((x1 - x0) as usize, (y1 - y0) as usize);
        let b: Vec<f32> = (y0..y1)
            .flat_map(|y| (x0..x1).map(move |x| (x, y)))
            .map(|(x, y)| self.value(pl, x, y))
            .collect();
        // Seams between fill patches lie in a band `seam_band` cells wide along a wavy contour
        // at a noisy depth from the window's sides (sides on the map border excepted): filled
        // cells before the band stay the old output's, a fill patch's cells after it go to
        // the new patch, and the cut chooses within it. A free minimum cut (shortest seams
        // win) ran straight along rows and columns next to the window edges.
        let band = ((self.params.patch_size / 4).max(1) - 1) as f32;
        let period = (self.params.patch_size as i32 / 2).max(2);
        let seed = self.params.seed ^ 0x5EA4;
        let old_seed = self.params.seed ^ 0x01D5;
        let seam_band = (self.params.patch_size / 8).max(2) as f32;
        // World position (see `RefineParams::origin`): the same noise in every tile.
        let [ox, oy] = self.params.origin.map(|o| o as i32);
        let inner = [x0 > 0, x1 < n, y0 > 0, y1 < n];
        // Depth of a cell past the contour (negative before it); `None` if no side is inner.
        let depth = |x: i32, y: i32| {
            let margin = wavy_margin(old_seed, x + ox, y + oy, band, period);
            let dist = [x - x0, x1 - 1 - x, y - y0, y1 - 1 - y];
            (0..4)
                .filter(|&s| inner[s])
                .map(|s| dist[s] as f32 - margin)
                .min_by(f32::total_cmp)
        };
        let fill_owned =
            |x: i32, y: i32| self.owner[(y * n + x) as usize] as usize >= self.patches_feature;
        let mut fixed = vec![false; ww * wh];
        let mut forced_new = Vec::new();
        let mut node = vec![u32::MAX; ww * wh];
        let mut count = 0usize;
        for y in y0..y1 {
            for x in x0..x1 {
                if self.filled(x, y) {
                    let d = if band > 0.0 && !self.core_cell(pl, core, x, y) {
                        depth(x, y)
                    } else {
                        None
                    };
                    if d.is_some_and(|d| d < 0.0) {
                        fixed[(y - y0) as usize * ww + (x - x0) as usize] = true;
                        continue;
                    }
                    if !core && d.is_some_and(|d| d >= seam_band) && fill_owned(x, y) {
                        forced_new.push(count);
                    }
                    node[(y - y0) as usize * ww + (x - x0) as usize] = count as u32;
                    count += 1;
                }
            }
        }
        // Unfilled cells in a noisy band along the open sides are left to a later patch, so
        // that patch's seam with this one does not follow the window's straight edge.
        let mut take = vec![true; ww * wh];
        for y in y0..y1 {
            for x in x0..x1 {
                let wi = (y - y0) as usize * ww + (x - x0) as usize;
                if fixed[wi] {
                    take[wi] = false;
                    continue;
                }
                if node[wi] != u32::MAX || band <= 0.0 {
                    continue;
                }
                let dist = [x - x0, x1 - 1 - x, y - y0, y1 - 1 - y];
                let margin = wavy_margin(seed, x + ox, y + oy, band, period);
                take[wi] = !(0..4).any(|s| self.open_sides[s] && (dist[s] as f32) < margin);
            }
        }
        CutCells {
            x0,
            y0,
            x1,
            y1,
            ww,
            b,
            fixed,
            node,
            take,
            forced_new,
            count,
        }
    }

    /// The flow graph of the cut over `cells`: seam costs between the old output and the
    /// candidate, terminals for forced, fixed and unfilled neighbours.
    fn cut_graph(&self, cells: &CutCells, pl: &Placed, core: bool) -> FlowGraph {
        let n = self.n as i32;
        let CutCells { x0, y0, x1, y1, .. } = *cells;
        let a = |x: i32, y: i32| self.dout[(y * n + x) as usize];
        let bw = |x: i32, y: i32| cells.b[cells.at(x, y)];
        let eps = 0.05f32;
        let inside =
            |x: i32, y: i32| x >= x0 && y >= y0 && x < x1 && y < y1 && !cells.fixed[cells.at(x, y)];
        let mut g = FlowGraph::new(cells.count);
        for &ni in &cells.forced_new {
            g.add_terminals(ni, INFINITE, 0.0);
        }
        for y in y0..y1 {
            for x in x0..x1 {
                let ni = cells.node[cells.at(x, y)];
                if ni == u32::MAX {
                    continue;
                }
                let ni = ni as usize;
                if self.core_cell(pl, core, x, y) {
                    g.add_terminals(ni, INFINITE, 0.0);
                }
                for (dx, dy) in [(1, 0), (-1, 0), (0, 1), (0, -1)] {
                    let (qx, qy) = (x + dx, y + dy);
                    if !inside(qx, qy) {
                        if self.filled(qx, qy) {
                            g.add_terminals(ni, 0.0, INFINITE);
                        }
                        continue;
                    }
                    // Forward gradients along the edge direction, at both ends.
                    let dp = (a(x, y) - bw(x, y)).abs();
                    let qw = cells.at(qx, qy);
                    let qi = cells.node[qw];
                    if qi == u32::MAX && !cells.take[qw] {
                        continue; // left for a later patch: no constraint
                    }
                    if qi == u32::MAX {
                        // Unfilled neighbour: it belongs to the new patch (source side).
                        let gb = (bw(qx, qy) - bw(x, y)).abs();
                        let m = 2.0 * dp / (2.0 * gb + eps);
                        g.add_terminals(ni, f64::from(m), 0.0);
                        continue;
                    }
                    if dx < 0 || dy < 0 {
                        continue; // each pair once
                    }
                    let dq = (a(qx, qy) - bw(qx, qy)).abs();
                    let ga = (a(qx, qy) - a(x, y)).abs();
                    let gb = (bw(qx, qy) - bw(x, y)).abs();
                    let m = f64::from((dp + dq) / (2.0 * ga + 2.0 * gb + eps));
                    g.add_edge(ni, qi as usize, m, m);
                }
            }
        }
        g
    }
}

/// A margin in `[0, band]` for world cell `(x, y)`: a sine along `x + y` whose wavelength
/// keeps its slope at most one cell per cell, its phase shifted by value noise (period
/// `period`) and by the seed. Smooth noise alone was flat over tens of cells in places, and
/// its contour at whole-cell distances then ran straight along the window edge.
fn wavy_margin(seed: u64, x: i32, y: i32, band: f32, period: i32) -> f32 {
    let wavelength = (std::f32::consts::PI * band).max(4.0);
    let phase = (x + y) as f32 / wavelength
        + 0.5 * value_noise(seed, x, y, period)
        + unit_hash(seed, 0x3A5E, 0);
    band * (0.5 + 0.5 * (std::f32::consts::TAU * phase).sin())
}
