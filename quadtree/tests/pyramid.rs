//! Min/max pyramid: validation and exactness of the bounds.

mod common;

use common::{Lcg, grid};
use terrasketch_quadtree::{MinMaxPyramid, QuadtreeError};

fn level(side: usize, value: [f32; 2]) -> (usize, Vec<[f32; 2]>) {
    (side, vec![value; side * side])
}

#[test]
fn from_levels_accepts_a_consistent_chain() {
    let pyramid = MinMaxPyramid::from_levels(vec![
        level(4, [1.0, 2.0]),
        level(2, [1.0, 2.0]),
        level(1, [1.0, 2.0]),
    ])
    .unwrap();
    assert_eq!(pyramid.finest_side(), 4);
    assert_eq!(pyramid.total_bounds(), [1.0, 2.0]);
}

#[test]
fn from_levels_rejects_each_kind_of_bad_input() {
    use QuadtreeError::*;
    let ok = [1.0, 2.0];
    assert_eq!(MinMaxPyramid::from_levels(vec![]), Err(EmptyPyramid));
    assert_eq!(
        MinMaxPyramid::from_levels(vec![level(3, ok), level(1, ok)]),
        Err(SideNotPowerOfTwo { level: 0, side: 3 })
    );
    assert_eq!(
        MinMaxPyramid::from_levels(vec![level(4, ok), level(1, ok)]),
        Err(SidesDoNotHalve {
            level: 1,
            side: 1,
            expected: 2
        })
    );
    assert_eq!(
        MinMaxPyramid::from_levels(vec![level(4, ok), level(2, ok)]),
        Err(CoarsestNotOneByOne { side: 2 })
    );
    assert_eq!(
        MinMaxPyramid::from_levels(vec![(2, vec![ok; 3]), level(1, ok)]),
        Err(WrongCellCount {
            level: 0,
            expected: 4,
            got: 3
        })
    );
    let mut nan = level(2, ok);
    nan.1[2] = [f32::NAN, 1.0];
    assert_eq!(
        MinMaxPyramid::from_levels(vec![nan, level(1, ok)]),
        Err(NonFinite { level: 0, cell: 2 })
    );
    let mut inf = level(1, ok);
    inf.1[0] = [0.0, f32::INFINITY];
    assert_eq!(
        MinMaxPyramid::from_levels(vec![level(2, ok), inf]),
        Err(NonFinite { level: 1, cell: 0 })
    );
    assert_eq!(
        MinMaxPyramid::from_levels(vec![level(2, [3.0, 1.0]), level(1, ok)]),
        Err(MinAboveMax {
            level: 0,
            cell: 0,
            min: 3.0,
            max: 1.0
        })
    );
    // The coarse cell claims [1, 2] but one child reaches 5.
    let mut fine = level(2, ok);
    fine.1[3] = [1.0, 5.0];
    assert_eq!(
        MinMaxPyramid::from_levels(vec![fine, level(1, ok)]),
        Err(NotNested { level: 1, cell: 0 })
    );
}

#[test]
fn from_heights_rejects_bad_grids() {
    use QuadtreeError::*;
    assert_eq!(
        MinMaxPyramid::from_heights(6, &[0.0; 36], 4),
        Err(SideNotPowerOfTwo { level: 0, side: 6 })
    );
    assert_eq!(
        MinMaxPyramid::from_heights(4, &[0.0; 16], 3),
        Err(SideNotPowerOfTwo { level: 0, side: 3 })
    );
    assert_eq!(
        MinMaxPyramid::from_heights(4, &[0.0; 15], 4),
        Err(WrongCellCount {
            level: 0,
            expected: 16,
            got: 15
        })
    );
    let mut heights = vec![0.0; 16];
    heights[5] = f32::NAN;
    assert_eq!(
        MinMaxPyramid::from_heights(4, &heights, 4),
        Err(NonFinite { level: 0, cell: 5 })
    );
}

/// Brute-force min/max of the grid cells that overlap the square with positive area.
fn brute(heights: &[f32], side: usize, x0: f32, y0: f32, size: f32) -> [f32; 2] {
    let (x1, y1) = ((x0 + size).min(1.0), (y0 + size).min(1.0));
    let mut out = [f32::INFINITY, f32::NEG_INFINITY];
    for j in 0..side {
        for i in 0..side {
            let (cx0, cy0) = (i as f32 / side as f32, j as f32 / side as f32);
            let (cx1, cy1) = ((i + 1) as f32 / side as f32, (j + 1) as f32 / side as f32);
            if cx0 < x1 && cx1 > x0 && cy0 < y1 && cy1 > y0 {
                let h = heights[j * side + i];
                out = [out[0].min(h), out[1].max(h)];
            }
        }
    }
    out
}

#[test]
fn bounds_are_exact_for_aligned_nodes_and_inherited_below_the_finest_level() {
    let side = 128;
    let mut rng = Lcg(7);
    let heights: Vec<f32> = (0..side * side)
        .map(|_| rng.range(-500.0, 2500.0))
        .collect();
    let pyramid = MinMaxPyramid::from_heights(side, &heights, 32).unwrap();
    assert_eq!(pyramid.finest_side(), 32);
    let brute_total = brute(&heights, side, 0.0, 0.0, 1.0);
    assert_eq!(pyramid.total_bounds(), brute_total);
    for depth in 0..=7u32 {
        let n = 1u32 << depth;
        let size = 1.0 / n as f32;
        for iy in 0..n {
            for ix in 0..n {
                let (x0, y0) = (ix as f32 * size, iy as f32 * size);
                let got = pyramid.bounds(x0, y0, size);
                assert_eq!(
                    got,
                    pyramid.node_bounds(depth, ix, iy),
                    "depth {depth} node ({ix}, {iy})"
                );
                if depth <= 5 {
                    assert_eq!(
                        got,
                        brute(&heights, side, x0, y0, size),
                        "depth {depth} node ({ix}, {iy})"
                    );
                } else {
                    // Finer than the 32x32 level: the ancestor cell at depth 5, a superset.
                    let shift = depth - 5;
                    let ancestor = pyramid.node_bounds(5, ix >> shift, iy >> shift);
                    assert_eq!(got, ancestor);
                    let exact = brute(&heights, side, x0, y0, size);
                    assert!(got[0] <= exact[0] && got[1] >= exact[1]);
                }
            }
        }
    }
}

#[test]
fn bounds_of_unaligned_squares_contain_the_true_range() {
    let side = 64;
    let heights = grid(side, |u, v| 1000.0 * (u * 9.0).sin() * (v * 7.0).cos());
    let pyramid = MinMaxPyramid::from_heights(side, &heights, 16).unwrap();
    let mut rng = Lcg(11);
    for _ in 0..500 {
        let size = rng.range(0.001, 0.6);
        let (x0, y0) = (rng.range(0.0, 1.0 - size), rng.range(0.0, 1.0 - size));
        let got = pyramid.bounds(x0, y0, size);
        let exact = brute(&heights, side, x0, y0, size);
        assert!(
            got[0] <= exact[0] && got[1] >= exact[1],
            "square ({x0}, {y0}, {size}): {got:?} vs {exact:?}"
        );
        // Never looser than the whole terrain.
        let total = pyramid.total_bounds();
        assert!(got[0] >= total[0] && got[1] <= total[1]);
    }
}

#[test]
fn from_heights_keeps_all_levels_when_the_grid_is_small() {
    let heights = grid(8, |u, v| u * 10.0 + v);
    let pyramid = MinMaxPyramid::from_heights(8, &heights, 64).unwrap();
    assert_eq!(pyramid.finest_side(), 8);
    for j in 0..8u32 {
        for i in 0..8u32 {
            let h = heights[(j * 8 + i) as usize];
            assert_eq!(pyramid.node_bounds(3, i, j), [h, h]);
        }
    }
}
