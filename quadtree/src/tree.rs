//! The per-frame quadtree: flat node storage with same-depth neighbour links, refinement by the
//! projected-box rule, and the balancing pass.
//!
//! Invariant after [`Tree::build`]: for every internal node, each of its 8 same-depth neighbours
//! inside the domain exists as a node. Hence any two leaves that touch (along an edge or at a
//! corner) differ by at most one depth; see the crate docs for the proof sketch.

use glam::{BVec4A, Mat4, Vec4};

use crate::MinMaxPyramid;

/// "No node" in links.
pub(crate) const NONE: u32 = u32::MAX;
/// Deepest depth handled (heightmaps up to 2^20 with 2 cells per patch need 20).
pub(crate) const MAX_DEPTH: usize = 24;

/// Neighbour directions `(dx, dy)`; `DIRS[7 - d]` is the opposite of `DIRS[d]`.
pub(crate) const DIRS: [(i32, i32); 8] = [
    (-1, -1),
    (0, -1),
    (1, -1),
    (-1, 0),
    (1, 0),
    (-1, 1),
    (0, 1),
    (1, 1),
];

/// Index into [`DIRS`] of a non-zero offset in `{-1, 0, 1}^2`.
#[inline]
pub(crate) const fn dir_index(dx: i32, dy: i32) -> usize {
    const TABLE: [usize; 9] = [0, 1, 2, 3, usize::MAX, 4, 5, 6, 7];
    TABLE[((dy + 1) * 3 + dx + 1) as usize]
}

/// `SIBLINGS[slot]`: `(direction, sibling slot)` of the three same-parent neighbours of a child.
const SIBLINGS: [[(usize, u32); 3]; 4] = {
    let mut table = [[(0, 0); 3]; 4];
    let mut slot = 0;
    while slot < 4 {
        let (sx, sy) = ((slot & 1) as i32, (slot >> 1) as i32);
        let (mut d, mut k) = (0, 0);
        while d < 8 {
            let (tx, ty) = (sx + DIRS[d].0, sy + DIRS[d].1);
            if tx >= 0 && tx < 2 && ty >= 0 && ty < 2 {
                table[slot][k] = (d, (tx + 2 * ty) as u32);
                k += 1;
            }
            d += 1;
        }
        slot += 1;
    }
    table
};

/// `COUSINS[pd]`: the child pairs linked across the parent's neighbour in direction `pd`, as
/// `(our child slot, direction from it, the neighbour's child slot)`; 4 pairs across an edge,
/// 1 across a corner (`COUSIN_COUNT`).
const COUSINS: [[(u32, usize, u32); 4]; 8] = {
    let mut table = [[(0, 0, 0); 4]; 8];
    let mut count = [0; 8];
    let mut slot: u32 = 0;
    while slot < 4 {
        let (sx, sy) = ((slot & 1) as i32, (slot >> 1) as i32);
        let mut d = 0;
        while d < 8 {
            let (tx, ty) = (sx + DIRS[d].0, sy + DIRS[d].1);
            if !(tx >= 0 && tx < 2 && ty >= 0 && ty < 2) {
                let pd = dir_index(tx.div_euclid(2), ty.div_euclid(2));
                table[pd][count[pd]] = (slot, d, (tx.rem_euclid(2) + 2 * ty.rem_euclid(2)) as u32);
                count[pd] += 1;
            }
            d += 1;
        }
        slot += 1;
    }
    let mut pd = 0;
    while pd < 8 {
        assert!(count[pd] == COUSIN_COUNT[pd]);
        pd += 1;
    }
    table
};

/// Number of valid entries per row of [`COUSINS`].
const COUSIN_COUNT: [usize; 8] = [1, 4, 1, 4, 4, 1, 4, 1];

/// Node flag: the box is outside the view frustum (the node and its descendants are not drawn).
pub(crate) const CULLED: u8 = 1;
/// Node flag: `q > 1`, not culled and above the finest allowed depth: refinement splits it.
pub(crate) const WANTS_SPLIT: u8 = 2;
/// Node flag: the box is entirely inside the frustum (so are its children's boxes).
pub(crate) const INSIDE: u8 = 4;

/// One quadtree node. Children are stored consecutively, slot `sx + 2 * sy` (`sx` east, `sy`
/// north).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Node {
    /// Column and row among the `2^depth x 2^depth` nodes of its depth (row 0 south).
    pub ix: u32,
    pub iy: u32,
    /// 0 = root.
    pub depth: u8,
    /// [`CULLED`], [`WANTS_SPLIT`], [`INSIDE`].
    pub flags: u8,
    /// First of the four children, or [`NONE`] for a leaf.
    pub first_child: u32,
    /// Parent, [`NONE`] for the root.
    pub parent: u32,
    /// Same-depth neighbour per direction of [`DIRS`], [`NONE`] when that node does not exist.
    pub nbr: [u32; 8],
    /// `[min, max]` height of the node's footprint.
    pub z: [f32; 2],
    /// Projected size over budget: the larger side of the box's viewport-clipped screen
    /// rectangle divided by the pixel budget (infinite if the box reaches behind the camera
    /// plane; 0 at the finest allowed depth, where it is not needed).
    pub q: f32,
}

impl Node {
    pub fn is_leaf(&self) -> bool {
        self.first_child == NONE
    }

    pub fn is_culled(&self) -> bool {
        self.flags & CULLED != 0
    }
}

/// Clip-space `(x, y, z, w)` of four box corners, one corner per lane.
type ClipLanes = (Vec4, Vec4, Vec4, Vec4);

/// Everything the node evaluation needs for one frame.
pub(crate) struct Frame<'a> {
    pub pyramid: &'a MinMaxPyramid,
    pub clip_from_world: Mat4,
    /// NDC extent to budget units: half the viewport in pixels divided by the pixel budget.
    pub ndc_to_budget: [f32; 2],
    /// Node size in metres per depth.
    pub node_size_m: [[f32; 2]; MAX_DEPTH + 1],
    /// Nodes at depth `< split_depth_limit` may be split (finest level and finest ready mip).
    pub split_depth_limit: u32,
}

impl Frame<'_> {
    /// Fills the node's bounds, `q` and flags: culled if its parent is or its box is outside
    /// one frustum plane; `q` from the projected, viewport-clipped screen rectangle of the box
    /// (computed for culled nodes too, so it varies continuously as a node enters the view).
    #[inline]
    fn evaluate(&self, node: &mut Node, parent_flags: u8) {
        node.z = self
            .pyramid
            .node_bounds(node.depth as u32, node.ix, node.iy);
        node.q = 0.0;
        let needs_q = (node.depth as u32) < self.split_depth_limit;
        let (parent_culled, parent_inside) =
            (parent_flags & CULLED != 0, parent_flags & INSIDE != 0);
        if !needs_q && (parent_culled || parent_inside) {
            node.flags = parent_flags & (CULLED | INSIDE);
            return;
        }
        let [sx, sy] = self.node_size_m[node.depth as usize];
        let (x0, x1) = (node.ix as f32 * sx, (node.ix + 1) as f32 * sx);
        let (y0, y1) = (node.iy as f32 * sy, (node.iy + 1) as f32 * sy);
        // Structure of arrays: lane k is footprint corner k (SW, SE, NW, NE); `lo` / `hi` are
        // the bottom and top faces of the box, each as clip-space (x, y, z, w) lanes.
        let (xs, ys) = (Vec4::new(x0, x1, x0, x1), Vec4::new(y0, y0, y1, y1));
        let m = &self.clip_from_world;
        let (cols, z_col) = ([m.x_axis, m.y_axis, m.w_axis], m.z_axis);
        let base = |row: usize| xs * cols[0][row] + ys * cols[1][row] + Vec4::splat(cols[2][row]);
        let (bx, by, bz, bw) = (base(0), base(1), base(2), base(3));
        let face = |z: f32| {
            let shift = z_col * z;
            (
                bx + Vec4::splat(shift.x),
                by + Vec4::splat(shift.y),
                bz + Vec4::splat(shift.z),
                bw + Vec4::splat(shift.w),
            )
        };
        let (lo, hi) = (face(node.z[0]), face(node.z[1]));
        node.flags = if parent_culled || parent_inside {
            parent_flags & (CULLED | INSIDE)
        } else {
            // Per clip plane, which of the 8 corners are outside it.
            let planes: [fn(&ClipLanes) -> BVec4A; 6] = [
                |c| c.0.cmplt(-c.3),
                |c| c.0.cmpgt(c.3),
                |c| c.1.cmplt(-c.3),
                |c| c.1.cmpgt(c.3),
                |c| c.2.cmplt(Vec4::ZERO),
                |c| c.2.cmpgt(c.3),
            ];
            let (mut culled, mut any_out) = (false, false);
            for plane in planes {
                let (out_lo, out_hi) = (plane(&lo), plane(&hi));
                culled |= (out_lo & out_hi).all();
                any_out |= (out_lo | out_hi).any();
            }
            if culled {
                CULLED
            } else if any_out {
                0
            } else {
                INSIDE
            }
        };
        let culled = node.flags & CULLED != 0;
        if needs_q {
            let eps = Vec4::splat(f32::EPSILON);
            node.q = if (lo.3.cmple(eps) | hi.3.cmple(eps)).any() {
                f32::INFINITY
            } else {
                // Screen rectangle of the 8 projected corners, clipped to the viewport.
                let (rcp_lo, rcp_hi) = (lo.3.recip(), hi.3.recip());
                let (nx_lo, ny_lo, nx_hi, ny_hi) =
                    (lo.0 * rcp_lo, lo.1 * rcp_lo, hi.0 * rcp_hi, hi.1 * rcp_hi);
                let clip = |v: f32| v.clamp(-1.0, 1.0);
                let width =
                    clip(nx_lo.max(nx_hi).max_element()) - clip(nx_lo.min(nx_hi).min_element());
                let height =
                    clip(ny_lo.max(ny_hi).max_element()) - clip(ny_lo.min(ny_hi).min_element());
                (width * self.ndc_to_budget[0]).max(height * self.ndc_to_budget[1])
            };
            if !culled && node.q > 1.0 {
                node.flags |= WANTS_SPLIT;
            }
        }
    }
}

/// Counters of one build.
#[derive(Debug, Default, Clone, Copy)]
pub(crate) struct BuildCounts {
    pub nodes: u32,
    pub balance_splits: u32,
}

/// The node arena and scratch lists, kept across frames (no allocation after warm-up).
#[derive(Debug, Default, Clone)]
pub(crate) struct Tree {
    pub nodes: Vec<Node>,
    stack: Vec<u32>,
    /// Internal nodes per depth, for the balancing pass.
    internal: Vec<Vec<u32>>,
}

impl Tree {
    /// Refines from the root by the projected-box rule, then balances.
    pub fn build(&mut self, frame: &Frame, max_depth: u32) -> BuildCounts {
        self.nodes.clear();
        self.stack.clear();
        if self.internal.len() <= max_depth as usize {
            self.internal.resize_with(max_depth as usize + 1, Vec::new);
        }
        self.internal.iter_mut().for_each(Vec::clear);

        let mut root = Node {
            ix: 0,
            iy: 0,
            depth: 0,
            flags: 0,
            first_child: NONE,
            parent: NONE,
            nbr: [NONE; 8],
            z: [0.0; 2],
            q: 0.0,
        };
        frame.evaluate(&mut root, 0);
        self.nodes.push(root);
        self.stack.push(0);
        while let Some(i) = self.stack.pop() {
            if self.nodes[i as usize].flags & WANTS_SPLIT != 0 {
                let first = self.split(frame, i);
                self.stack.extend(first..first + 4);
            }
        }
        let refined = self.nodes.len();

        // Balance: deepest internal nodes first. Making a neighbour exist only splits nodes that
        // are shallower than the node being processed, so each depth's list is final when reached.
        for depth in (1..=max_depth as usize).rev() {
            let mut k = 0;
            while k < self.internal[depth].len() {
                let x = self.internal[depth][k];
                for d in 0..8 {
                    if self.nodes[x as usize].nbr[d] == NONE {
                        self.ensure_neighbour(frame, x, d);
                    }
                }
                k += 1;
            }
        }
        let nodes = self.nodes.len() as u32;
        BuildCounts {
            nodes,
            balance_splits: (self.nodes.len() - refined) as u32 / 4,
        }
    }

    /// Splits leaf `i`: evaluates its four children and links them with the existing
    /// same-depth nodes around them (both directions). Returns the first child's index.
    fn split(&mut self, frame: &Frame, i: u32) -> u32 {
        let parent = self.nodes[i as usize];
        debug_assert!(parent.is_leaf());
        let first = self.nodes.len() as u32;
        for (slot, siblings) in SIBLINGS.iter().enumerate() {
            let mut nbr = [NONE; 8];
            for &(d, sibling) in siblings {
                nbr[d] = first + sibling;
            }
            let (sx, sy) = (slot as u32 & 1, slot as u32 >> 1);
            let mut child = Node {
                ix: parent.ix * 2 + sx,
                iy: parent.iy * 2 + sy,
                depth: parent.depth + 1,
                flags: 0,
                first_child: NONE,
                parent: i,
                nbr,
                z: [0.0; 2],
                q: 0.0,
            };
            frame.evaluate(&mut child, parent.flags);
            self.nodes.push(child);
        }
        self.nodes[i as usize].first_child = first;
        self.internal[parent.depth as usize].push(i);

        let (older, children) = self.nodes.split_at_mut(first as usize);
        for (pd, pairs) in COUSINS.iter().enumerate() {
            let q = parent.nbr[pd];
            if q == NONE {
                continue;
            }
            let q_first = older[q as usize].first_child;
            if q_first == NONE {
                continue;
            }
            for &(slot, d, q_slot) in &pairs[..COUSIN_COUNT[pd]] {
                children[slot as usize].nbr[d] = q_first + q_slot;
                older[(q_first + q_slot) as usize].nbr[7 - d] = first + slot;
            }
        }
        first
    }

    /// Makes the same-depth neighbour of node `x` in direction `d` exist, splitting the leaves
    /// above it as needed (recursively through the parent's neighbour). Returns it, or
    /// [`NONE`] when that position is outside the domain.
    fn ensure_neighbour(&mut self, frame: &Frame, x: u32, d: usize) -> u32 {
        let node = self.nodes[x as usize];
        if node.nbr[d] != NONE {
            return node.nbr[d];
        }
        let (dx, dy) = DIRS[d];
        let side = 1i64 << node.depth;
        let (tx, ty) = (node.ix as i64 + dx as i64, node.iy as i64 + dy as i64);
        if tx < 0 || ty < 0 || tx >= side || ty >= side {
            return NONE;
        }
        // Not a sibling (siblings always exist), so it lies under the parent's neighbour.
        let (sx, sy) = ((node.ix & 1) as i32, (node.iy & 1) as i32);
        let pd = dir_index((sx + dx).div_euclid(2), (sy + dy).div_euclid(2));
        let q = self.ensure_neighbour(frame, node.parent, pd);
        debug_assert_ne!(
            q, NONE,
            "an in-domain position always has an in-domain parent"
        );
        if self.nodes[q as usize].is_leaf() {
            self.split(frame, q);
        }
        self.nodes[x as usize].nbr[d]
    }

    /// Which leaves touch the corners of leaf `i`: returns `(coarser, finer)` bit masks over the
    /// corners `SW, SE, NW, NE` (bit `cx + 2 * cy`), set when a leaf one depth shallower / one
    /// depth deeper touches that corner. Culled leaves count: the answer depends on the tree
    /// only, so every leaf sharing a corner sees the same neighbourhood.
    #[inline]
    pub fn corner_neighbourhood(&self, i: u32) -> (u8, u8) {
        let node = &self.nodes[i as usize];
        let last = (1u32 << node.depth) - 1;
        // Per direction: 1 = a shallower leaf lies there, 2 = a deeper one touches this leaf.
        let mut class = [0u8; 8];
        for (d, &(dx, dy)) in DIRS.iter().enumerate() {
            let n = node.nbr[d];
            class[d] = if n != NONE {
                if self.nodes[n as usize].is_leaf() {
                    0
                } else {
                    2
                }
            } else {
                let outside_x = (dx < 0 && node.ix == 0) || (dx > 0 && node.ix == last);
                let outside_y = (dy < 0 && node.iy == 0) || (dy > 0 && node.iy == last);
                if outside_x || outside_y { 0 } else { 1 }
            };
        }
        let (mut coarser, mut finer) = (0u8, 0u8);
        for (corner, dirs) in CORNER_DIRS.iter().enumerate() {
            let touching = class[dirs[0]] | class[dirs[1]] | class[dirs[2]];
            coarser |= (touching & 1) << corner;
            finer |= ((touching >> 1) & 1) << corner;
        }
        (coarser, finer)
    }

    /// Morph factors at the corners `SW, SE, NW, NE` of leaf `i` (see the crate README):
    /// `clamp((q_start - Q) * rcp_span, 0, 1)` with `rcp_span = 1 / (q_start - 1)`, where `Q` is
    /// the smallest `q` among the parent-depth nodes containing the corner; forced to 1 where a
    /// coarser leaf touches the corner and to 0 where a finer one does (and everywhere on the
    /// root). A function of the
    /// corner, the depth and the tree only, so every leaf sharing a corner gets the same value.
    #[inline]
    pub fn corner_morph(&self, i: u32, q_start: f32, rcp_span: f32) -> [f32; 4] {
        let node = &self.nodes[i as usize];
        if node.parent == NONE {
            return [0.0; 4];
        }
        let parent = &self.nodes[node.parent as usize];
        let slot = ((node.ix & 1) + 2 * (node.iy & 1)) as usize;
        let (coarser, finer) = self.corner_neighbourhood(i);
        let mut morph = [0.0; 4];
        for (corner, m) in morph.iter_mut().enumerate() {
            let bit = 1u8 << corner;
            if finer & bit != 0 {
                continue;
            }
            if coarser & bit != 0 {
                *m = 1.0;
                continue;
            }
            let (dirs, count) = PARENT_CORNER_DIRS[slot][corner];
            let mut q_min = parent.q;
            for &d in &dirs[..count] {
                let n = parent.nbr[d];
                if n != NONE {
                    q_min = q_min.min(self.nodes[n as usize].q);
                }
            }
            *m = ((q_start - q_min) * rcp_span).clamp(0.0, 1.0);
        }
        morph
    }
}

/// `PARENT_CORNER_DIRS[slot][corner]`: the directions, from the parent, of the other
/// parent-depth nodes containing that corner of the child at `slot` (none for the parent's
/// centre, one across an edge midpoint, three around a parent corner), and their count.
const PARENT_CORNER_DIRS: [[([usize; 3], usize); 4]; 4] = {
    let mut table = [[([0; 3], 0); 4]; 4];
    let mut slot = 0;
    while slot < 4 {
        let mut corner = 0;
        while corner < 4 {
            // The corner in the parent's frame, in child units: 0, 1 (middle) or 2.
            let px = (slot & 1) as i32 + (corner & 1) as i32;
            let py = (slot >> 1) as i32 + (corner >> 1) as i32;
            let (x_lo, x_hi) = if px == 0 {
                (-1, 0)
            } else if px == 2 {
                (0, 1)
            } else {
                (0, 0)
            };
            let (y_lo, y_hi) = if py == 0 {
                (-1, 0)
            } else if py == 2 {
                (0, 1)
            } else {
                (0, 0)
            };
            let mut oy = y_lo;
            while oy <= y_hi {
                let mut ox = x_lo;
                while ox <= x_hi {
                    if ox != 0 || oy != 0 {
                        let (dirs, count) = &mut table[slot][corner];
                        dirs[*count] = dir_index(ox, oy);
                        *count += 1;
                    }
                    ox += 1;
                }
                oy += 1;
            }
            corner += 1;
        }
        slot += 1;
    }
    table
};

/// The three directions around each corner `SW, SE, NW, NE` of a node.
const CORNER_DIRS: [[usize; 3]; 4] = [
    [dir_index(-1, -1), dir_index(0, -1), dir_index(-1, 0)],
    [dir_index(1, -1), dir_index(0, -1), dir_index(1, 0)],
    [dir_index(-1, 1), dir_index(0, 1), dir_index(-1, 0)],
    [dir_index(1, 1), dir_index(0, 1), dir_index(1, 0)],
];
