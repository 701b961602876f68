//! Ridge and valley networks, after Tasse (2011) §3.2: profile recognition, candidate graph,
//! Kruskal minimum spanning forest, branch pruning.
//!
//! 1. **Profile recognition.** Along each of the 4 directions (E-W, N-S and both diagonals) a
//!    cell's *profile strength* is the smaller of its two side drops, each side's drop being the
//!    steepest descent `(h(p) - h(p + k d)) / (k |d|)` for `k` in `ceil(r/2)..=r`, `r` =
//!    `profile_radius` (a slope, so the threshold scales with the cell size: a drop of
//!    `min_profile_slope * distance` metres). Skipping the nearest cells means cell-to-cell
//!    noise (SRTM's metre steps, sensor noise) cannot make a candidate on its own.
//!    The cell's strength is the best over the 4 directions; it is a candidate if that exceeds
//!    `min_profile_slope`. Valleys are ridges of the negated field.
//! 2. **Candidate graph.** Candidates are joined to their 8-neighbour candidates. Where two
//!    diagonal edges cross, the weaker is dropped. An edge costs minus the mean strength of its
//!    two ends, so strong profiles are preferred.
//! 3. **Kruskal.** Edges sorted by cost (ties in cell order, for determinism) build a minimum
//!    spanning forest with a union-find: Tasse's replacement for PPA's polygon breaking.
//! 4. **Pruning.** Repeatedly, branches from a leaf to a junction shorter than
//!    `min_branch_cells` are removed, shortest first, and only while their junction still has
//!    three or more branches (so a line's ends are not eaten away with its spurs). Trees with
//!    fewer than `min_tree_cells` cells are then dropped.
//! 5. **Output.** Chains between leaves and junctions become polylines (cell coordinates,
//!    `[x = column, y = row]`, smoothed by `smoothing_iterations` passes of neighbour averaging
//!    with fixed ends) plus a mask of the cells kept.

use rayon::prelude::*;

/// Which feature to extract.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub enum FeatureKind {
    /// Ridge lines (crests).
    Ridge,
    /// Valley lines (thalwegs): ridges of the negated field.
    Valley,
}

/// Parameters of [`extract_features`].
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct FeatureParams {
    /// Half-length of the recognition profile, in cells.
    pub profile_radius: usize,
    /// Smallest side drop, as a slope (metres per metre), for a cell to be a candidate.
    pub min_profile_slope: f64,
    /// Leaf branches shorter than this (in cells) are pruned.
    pub min_branch_cells: usize,
    /// Trees with fewer cells than this are dropped.
    pub min_tree_cells: usize,
    /// Passes of neighbour averaging applied to each polyline.
    pub smoothing_iterations: usize,
}

impl Default for FeatureParams {
    fn default() -> Self {
        Self {
            profile_radius: 4,
            min_profile_slope: 0.05,
            min_branch_cells: 8,
            min_tree_cells: 16,
            smoothing_iterations: 2,
        }
    }
}

/// An extracted ridge or valley network.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct FeatureNetwork {
    /// Ridge or valley.
    pub kind: FeatureKind,
    /// Grid columns.
    pub width: usize,
    /// Grid rows.
    pub height: usize,
    /// Polylines in cell coordinates `[x, y]` (column, row), one per chain between leaves and
    /// junctions.
    pub polylines: Vec<Vec<[f32; 2]>>,
    /// `width * height` flags: true on cells of the kept network.
    pub mask: Vec<bool>,
    /// Number of profile candidates before the spanning forest and pruning.
    pub candidates: usize,
}

/// Profile strength of every cell (0 where no profile rises above both sides), as a slope.
pub fn profile_strength(
    heights: &[f32],
    width: usize,
    height: usize,
    cell: [f64; 2],
    kind: FeatureKind,
    radius: usize,
) -> Vec<f64> {
    let sign = if kind == FeatureKind::Ridge {
        1.0
    } else {
        -1.0
    };
    let h = |x: isize, y: isize| sign * f64::from(heights[y as usize * width + x as usize]);
    let dirs: [(isize, isize); 4] = [(1, 0), (0, 1), (1, 1), (1, -1)];
    let mut out = vec![0.0; heights.len()];
    if width == 0 || width.checked_mul(height) != Some(heights.len()) {
        return out;
    }
    let radius = radius.max(1);
    let (w, ht) = (width as isize, height as isize);
    out.par_chunks_mut(width).enumerate().for_each(|(y, row)| {
        let y = y as isize;
        for x in 0..w {
            let c = h(x, y);
            let mut best = 0.0f64;
            for (dx, dy) in dirs {
                let step_m = ((dx as f64 * cell[0]).powi(2) + (dy as f64 * cell[1]).powi(2)).sqrt();
                let side = |s: isize| {
                    let mut drop = f64::NEG_INFINITY;
                    for k in radius.div_ceil(2) as isize..=radius as isize {
                        let (nx, ny) = (x + s * k * dx, y + s * k * dy);
                        if nx < 0 || ny < 0 || nx >= w || ny >= ht {
                            break;
                        }
                        // NaN heights give NaN drops, which `max` ignores.
                        drop = drop.max((c - h(nx, ny)) / (k as f64 * step_m));
                    }
                    drop
                };
                best = best.max(side(1).min(side(-1)));
            }
            row[x as usize] = best;
        }
    });
    out
}

/// Union-find with path halving and union by size.
struct Dsu {
    parent: Vec<u32>,
    size: Vec<u32>,
}

impl Dsu {
    fn new(n: usize) -> Self {
        Self {
            parent: (0..n as u32).collect(),
            size: vec![1; n],
        }
    }
    fn find(&mut self, mut a: u32) -> u32 {
        while self.parent[a as usize] != a {
            let gp = self.parent[self.parent[a as usize] as usize];
            self.parent[a as usize] = gp;
            a = gp;
        }
        a
    }
    fn union(&mut self, a: u32, b: u32) -> bool {
        let (mut a, mut b) = (self.find(a), self.find(b));
        if a == b {
            return false;
        }
        if self.size[a as usize] < self.size[b as usize] {
            std::mem::swap(&mut a, &mut b);
        }
        self.parent[b as usize] = a;
        self.size[a as usize] += self.size[b as usize];
        true
    }
}

/// Extracts the ridge or valley network of a heightmap (row-major, metres; cell size in metres).
///
/// A grid whose length is not `width * height` gives an empty network.
pub fn extract_features(
    heights: &[f32],
    width: usize,
    height: usize,
    cell_size_m: [f64; 2],
    kind: FeatureKind,
    params: &FeatureParams,
) -> FeatureNetwork {
    let mut net = FeatureNetwork {
        kind,
        width,
        height,
        polylines: Vec::new(),
        mask: vec![false; heights.len()],
        candidates: 0,
    };
    if width == 0 || width.checked_mul(height) != Some(heights.len()) {
        return net;
    }
    let radius = params.profile_radius.max(1);
    let strength = profile_strength(heights, width, height, cell_size_m, kind, radius);
    let is_cand: Vec<bool> = strength
        .iter()
        .map(|&s| s > params.min_profile_slope)
        .collect();
    net.candidates = is_cand.iter().filter(|&&c| c).count();

    // Candidate graph: forward edges E, S, SE, SW; crossing diagonals keep the stronger.
    let mut edges: Vec<(f64, u32, u32)> = Vec::new();
    let cand = |x: usize, y: usize| x < width && y < height && is_cand[y * width + x];
    let mean = |a: usize, b: usize| 0.5 * (strength[a] + strength[b]);
    for y in 0..height {
        for x in 0..width {
            if !cand(x, y) {
                continue;
            }
            let i = y * width + x;
            for (dx, dy) in [(1usize, 0usize), (0, 1)] {
                if cand(x + dx, y + dy) {
                    let j = (y + dy) * width + x + dx;
                    edges.push((-mean(i, j), i as u32, j as u32));
                }
            }
            let se = cand(x + 1, y + 1).then(|| (y + 1) * width + x + 1);
            let anti = (cand(x + 1, y) && cand(x, y + 1)).then(|| mean(i + 1, i + width));
            if let Some(j) = se
                && anti.is_none_or(|s| mean(i, j) >= s)
            {
                edges.push((-mean(i, j), i as u32, j as u32));
            }
            // SW edge from (x, y) to (x - 1, y + 1), crossing (x - 1, y) -> (x, y + 1).
            if x > 0 && cand(x - 1, y + 1) {
                let j = (y + 1) * width + x - 1;
                let crossing = (cand(x - 1, y) && cand(x, y + 1)).then(|| mean(i - 1, i + width));
                if crossing.is_none_or(|s| mean(i, j) > s) {
                    edges.push((-mean(i, j), i as u32, j as u32));
                }
            }
        }
    }
    edges.par_sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)).then(a.2.cmp(&b.2)));

    let mut dsu = Dsu::new(heights.len());
    let mut adj: Vec<Vec<u32>> = vec![Vec::new(); heights.len()];
    for &(_, a, b) in &edges {
        if dsu.union(a, b) {
            adj[a as usize].push(b);
            adj[b as usize].push(a);
        }
    }
    let mut alive = is_cand;
    prune_branches(&mut adj, &mut alive, params.min_branch_cells);
    drop_small_trees(&adj, &mut alive, params.min_tree_cells);
    net.polylines = chains(&adj, &alive, width, params.smoothing_iterations);
    net.mask = alive;
    net
}

/// Removes the edge between `a` and `b`.
fn unlink(adj: &mut [Vec<u32>], a: usize, b: usize) {
    adj[a].retain(|&n| n as usize != b);
    adj[b].retain(|&n| n as usize != a);
}

/// Branches from a leaf to the first junction: (length, leaf, cells excluding the junction,
/// junction).
fn leaf_branches(adj: &[Vec<u32>], alive: &[bool]) -> Vec<(usize, usize, Vec<usize>, usize)> {
    let mut out = Vec::new();
    for leaf in 0..adj.len() {
        if !alive[leaf] || adj[leaf].len() != 1 {
            continue;
        }
        let mut cells = vec![leaf];
        let (mut prev, mut cur) = (leaf, adj[leaf][0] as usize);
        while adj[cur].len() == 2 {
            cells.push(cur);
            let next = if adj[cur][0] as usize == prev {
                adj[cur][1]
            } else {
                adj[cur][0]
            } as usize;
            prev = cur;
            cur = next;
        }
        if adj[cur].len() >= 3 {
            out.push((cells.len(), leaf, cells, cur));
        }
    }
    out
}

/// Prunes leaf branches shorter than `min_len`, shortest first, while their junction keeps at
/// least three branches; repeats until nothing changes.
fn prune_branches(adj: &mut [Vec<u32>], alive: &mut [bool], min_len: usize) {
    loop {
        let mut branches = leaf_branches(adj, alive);
        branches.retain(|b| b.0 < min_len);
        branches.sort_by_key(|b| (b.0, b.1));
        let mut changed = false;
        for (_, _, cells, junction) in branches {
            let last = cells[cells.len() - 1];
            if adj[junction].len() < 3 || !adj[junction].contains(&(last as u32)) {
                continue;
            }
            if cells.iter().any(|&c| !alive[c]) {
                continue;
            }
            unlink(adj, last, junction);
            for w in cells.windows(2) {
                unlink(adj, w[0], w[1]);
            }
            for &c in &cells {
                alive[c] = false;
            }
            changed = true;
        }
        if !changed {
            return;
        }
    }
}

/// Drops connected components with fewer than `min_cells` cells (and isolated cells).
fn drop_small_trees(adj: &[Vec<u32>], alive: &mut [bool], min_cells: usize) {
    let mut seen = vec![false; adj.len()];
    let mut stack = Vec::new();
    for start in 0..adj.len() {
        if !alive[start] || seen[start] {
            continue;
        }
        seen[start] = true;
        stack.push(start);
        let mut comp = Vec::new();
        while let Some(c) = stack.pop() {
            comp.push(c);
            for &n in &adj[c] {
                let n = n as usize;
                if alive[n] && !seen[n] {
                    seen[n] = true;
                    stack.push(n);
                }
            }
        }
        if comp.len() < min_cells.max(2) {
            for c in comp {
                alive[c] = false;
            }
        }
    }
}

/// Chains between nodes of degree other than 2, as smoothed polylines.
fn chains(adj: &[Vec<u32>], alive: &[bool], width: usize, smooth: usize) -> Vec<Vec<[f32; 2]>> {
    let mut used = std::collections::HashSet::new();
    let mut out = Vec::new();
    for start in 0..adj.len() {
        if !alive[start] || adj[start].len() == 2 {
            continue;
        }
        for &first in &adj[start] {
            let key = |a: usize, b: usize| (a.min(b), a.max(b));
            if !used.insert(key(start, first as usize)) {
                continue;
            }
            let mut cells = vec![start];
            let (mut prev, mut cur) = (start, first as usize);
            loop {
                cells.push(cur);
                if adj[cur].len() != 2 {
                    break;
                }
                let next = if adj[cur][0] as usize == prev {
                    adj[cur][1]
                } else {
                    adj[cur][0]
                } as usize;
                used.insert(key(cur, next));
                prev = cur;
                cur = next;
            }
            let mut pts: Vec<[f32; 2]> = cells
                .iter()
                .map(|&c| [(c % width) as f32, (c / width) as f32])
                .collect();
            for _ in 0..smooth {
                let prev_pts = pts.clone();
                for i in 1..pts.len().saturating_sub(1) {
                    for k in 0..2 {
                        pts[i][k] = 0.25 * prev_pts[i - 1][k]
                            + 0.5 * prev_pts[i][k]
                            + 0.25 * prev_pts[i + 1][k];
                    }
                }
            }
            out.push(pts);
        }
    }
    out
}

/// Length of a polyline in cells.
pub fn polyline_length(points: &[[f32; 2]]) -> f64 {
    points
        .windows(2)
        .map(|w| f64::from(w[1][0] - w[0][0]).hypot(f64::from(w[1][1] - w[0][1])))
        .sum()
}

/// A stable key for caching an exemplar's feature networks: 64-bit FNV-1a over the DEM's path,
/// grid size, cell size, byte length, every height and the parameters, as 16 hex digits.
/// Stable across runs and platforms (unlike `std`'s `DefaultHasher`).
pub fn feature_cache_key(dem: &crate::Dem, params: &FeatureParams) -> String {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    let mut eat = |bytes: &[u8]| {
        for &b in bytes {
            h ^= u64::from(b);
            h = h.wrapping_mul(0x0100_0000_01b3);
        }
    };
    eat(dem.source.path.to_string_lossy().as_bytes());
    eat(&(dem.width as u64).to_le_bytes());
    eat(&(dem.height as u64).to_le_bytes());
    eat(&dem.cell_size_m[0].to_le_bytes());
    eat(&dem.cell_size_m[1].to_le_bytes());
    eat(&((dem.heights_m.len() * 4) as u64).to_le_bytes());
    for v in &dem.heights_m {
        eat(&v.to_le_bytes());
    }
    eat(&(params.profile_radius as u64).to_le_bytes());
    eat(&params.min_profile_slope.to_le_bytes());
    eat(&(params.min_branch_cells as u64).to_le_bytes());
    eat(&(params.min_tree_cells as u64).to_le_bytes());
    eat(&(params.smoothing_iterations as u64).to_le_bytes());
    format!("{h:016x}")
}
