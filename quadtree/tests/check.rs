//! `max_neighbour_level_diff` on hand-made patch sets.

use terrasketch_quadtree::{Patch, max_neighbour_level_diff};

fn patch(u: f32, v: f32, size: f32, level: u32) -> Patch {
    Patch {
        uv_origin: [u, v],
        uv_size: size,
        origin_m: [u, v],
        size_m: [size; 2],
        level,
        mip_level: level,
        morph: [0.0; 4],
        min_z: 0.0,
        max_z: 0.0,
    }
}

#[test]
fn measures_edge_neighbours_only() {
    assert_eq!(max_neighbour_level_diff(&[]), 0);
    // West half: one 1/2 patch (level 2). East half: 1/8 patches (level 0) along its edge.
    let mut patches = vec![patch(0.0, 0.0, 0.5, 2)];
    for j in 0..4 {
        patches.push(patch(0.5, j as f32 * 0.125, 0.125, 0));
    }
    assert_eq!(max_neighbour_level_diff(&patches), 2);
    // Replace the fine column by 1/4 patches (level 1): difference 1.
    let patches = vec![
        patch(0.0, 0.0, 0.5, 2),
        patch(0.5, 0.0, 0.25, 1),
        patch(0.5, 0.25, 0.25, 1),
    ];
    assert_eq!(max_neighbour_level_diff(&patches), 1);
    // Horizontal edges count too.
    let patches = vec![patch(0.0, 0.0, 0.5, 3), patch(0.0, 0.5, 0.0625, 0)];
    assert_eq!(max_neighbour_level_diff(&patches), 3);
    // Touching at a corner only does not count.
    let patches = vec![patch(0.0, 0.0, 0.5, 3), patch(0.5, 0.5, 0.0625, 0)];
    assert_eq!(max_neighbour_level_diff(&patches), 0);
}
