//! Independent checks on a selection's output (used by tests and the benchmark, not per frame).

use crate::Patch;

/// Largest level difference between two patches that share an edge segment of positive length.
/// 0 for fewer than two patches.
///
/// Works on the exact `uv_origin` / `uv_size` of the patches (sort and sweep, O(n log n)); it
/// does not trust the tree, so it measures what [`select`](crate::select) guarantees.
pub fn max_neighbour_level_diff(patches: &[Patch]) -> u32 {
    let vertical = max_diff_across_lines(patches, 0);
    let horizontal = max_diff_across_lines(patches, 1);
    vertical.max(horizontal)
}

/// Edges perpendicular to `axis` (0: vertical lines `u = const`), swept line by line.
fn max_diff_across_lines(patches: &[Patch], axis: usize) -> u32 {
    /// `(line coordinate, side, start, end, level)`; side 0: the patch lies below the line
    /// (its far edge), side 1: above it (its near edge).
    type Edge = (f32, u8, f32, f32, u32);
    let other = 1 - axis;
    let mut edges: Vec<Edge> = Vec::with_capacity(patches.len() * 2);
    for p in patches {
        let (lo, start) = (p.uv_origin[axis], p.uv_origin[other]);
        let end = start + p.uv_size;
        edges.push((lo + p.uv_size, 0, start, end, p.level));
        edges.push((lo, 1, start, end, p.level));
    }
    edges.sort_unstable_by(|a, b| {
        a.0.total_cmp(&b.0)
            .then(a.1.cmp(&b.1))
            .then(a.2.total_cmp(&b.2))
    });
    let mut worst = 0;
    let mut group_start = 0;
    while group_start < edges.len() {
        let line = edges[group_start].0;
        let group_end = group_start
            + edges[group_start..]
                .iter()
                .take_while(|e| e.0 == line)
                .count();
        let group = &edges[group_start..group_end];
        let split = group.iter().take_while(|e| e.1 == 0).count();
        let (below, above) = group.split_at(split);
        let (mut i, mut j) = (0, 0);
        while i < below.len() && j < above.len() {
            let (a, b) = (below[i], above[j]);
            if a.2.max(b.2) < a.3.min(b.3) {
                worst = worst.max(a.4.abs_diff(b.4));
            }
            if a.3 <= b.3 {
                i += 1;
            } else {
                j += 1;
            }
        }
        group_start = group_end;
    }
    worst
}
