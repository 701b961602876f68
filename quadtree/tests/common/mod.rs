//! Shared fixtures and independent checkers for the integration tests.
#![allow(dead_code)]

use std::collections::HashMap;

use glam::Vec3;
use terrasketch_quadtree::{Camera, LodSettings, MinMaxPyramid, Patch, Selection};

/// Test terrain: a 4096^2 heightmap over 8192 m, 32 cells per patch: 8 levels, 128x128 finest nodes.
pub const EXTENT_M: f32 = 8192.0;

pub fn settings() -> LodSettings {
    LodSettings::new(4096, [EXTENT_M; 2])
}

/// A deterministic linear congruential generator (Knuth's MMIX constants).
pub struct Lcg(pub u64);

impl Lcg {
    pub fn next_u32(&mut self) -> u32 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (self.0 >> 33) as u32
    }

    /// Uniform in `[lo, hi)`.
    pub fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * (self.next_u32() as f32 / (1u64 << 31) as f32)
    }
}

/// A `side x side` height grid (row 0 south) from `f(u, v)` at cell centres.
pub fn grid(side: usize, f: impl Fn(f32, f32) -> f32) -> Vec<f32> {
    (0..side * side)
        .map(|k| {
            f(
                ((k % side) as f32 + 0.5) / side as f32,
                ((k / side) as f32 + 0.5) / side as f32,
            )
        })
        .collect()
}

pub fn flat_pyramid() -> MinMaxPyramid {
    MinMaxPyramid::from_heights(64, &vec![0.0; 64 * 64], 64).unwrap()
}

/// Flat ground at 0 with a 3000 m cone of radius 0.1 (fractions) centred at `(cu, cv)`.
pub fn mountain_pyramid(cu: f32, cv: f32) -> MinMaxPyramid {
    let heights = grid(256, |u, v| {
        let r = ((u - cu).powi(2) + (v - cv).powi(2)).sqrt();
        (3000.0 * (1.0 - r / 0.1)).max(0.0)
    });
    MinMaxPyramid::from_heights(256, &heights, 64).unwrap()
}

/// Rolling hills up to ~800 m, for random-camera tests.
pub fn hills_pyramid() -> MinMaxPyramid {
    let heights = grid(256, |u, v| {
        400.0 + 300.0 * (u * 17.0).sin() * (v * 13.0).cos() + 100.0 * (u * 41.0 + v * 29.0).sin()
    });
    MinMaxPyramid::from_heights(256, &heights, 64).unwrap()
}

pub fn camera(position: Vec3, target: Vec3) -> Camera {
    Camera::look_at(
        position,
        target,
        60f32.to_radians(),
        [1920.0, 1080.0],
        0.5,
        100_000.0,
    )
}

/// Finest-node grid: for each of the `2^max_depth` squared cells, the index of the patch covering
/// it (`usize::MAX - 1` for a culled leaf, `usize::MAX` for nothing). Panics on double coverage.
pub struct CoverGrid {
    pub side: usize,
    pub owner: Vec<usize>,
}

pub const CULLED: usize = usize::MAX - 1;
pub const NOTHING: usize = usize::MAX;

impl CoverGrid {
    pub fn new(settings: &LodSettings, selection: &Selection) -> Self {
        let side = 1usize << (settings.levels() - 1);
        let mut owner = vec![NOTHING; side * side];
        let mut fill = |uv_origin: [f32; 2], uv_size: f32, id: usize| {
            let (i0, j0) = (
                (uv_origin[0] * side as f32) as usize,
                (uv_origin[1] * side as f32) as usize,
            );
            let n = (uv_size * side as f32) as usize;
            assert!(n >= 1, "leaf finer than the finest level");
            for j in j0..j0 + n {
                for i in i0..i0 + n {
                    assert_eq!(
                        owner[j * side + i],
                        NOTHING,
                        "cell ({i}, {j}) covered twice"
                    );
                    owner[j * side + i] = id;
                }
            }
        };
        for (k, p) in selection.patches.iter().enumerate() {
            fill(p.uv_origin, p.uv_size, k);
        }
        for (origin, size) in selection.culled_leaves() {
            fill(origin, size, CULLED);
        }
        Self { side, owner }
    }

    pub fn owner_at(&self, u: f32, v: f32) -> usize {
        let (i, j) = (
            (u * self.side as f32) as usize,
            (v * self.side as f32) as usize,
        );
        self.owner[j.min(self.side - 1) * self.side + i.min(self.side - 1)]
    }
}

/// Morph of `p` at the point `(u, v)` (fractions of the extent) on its boundary, with the
/// README's edge-exact bilinear form `a * (1 - t) + b * t`.
fn morph_at(p: &Patch, u: f32, v: f32) -> f32 {
    let (s, t) = (
        (u - p.uv_origin[0]) / p.uv_size,
        (v - p.uv_origin[1]) / p.uv_size,
    );
    let [sw, se, nw, ne] = p.morph;
    let south = sw * (1.0 - s) + se * s;
    let north = nw * (1.0 - s) + ne * s;
    south * (1.0 - t) + north * t
}

/// Checks, at every patch corner, the contract that makes the mesh watertight: every patch whose
/// boundary contains the point has a level within one of the others; same-level patches have
/// the same morph there; where levels L and L + 1 meet, the L patches have morph 1 and the L + 1
/// patches morph 0. Returns the number of shared points checked.
pub fn check_watertight(settings: &LodSettings, selection: &Selection, cover: &CoverGrid) -> usize {
    let side = cover.side;
    let mut corners: HashMap<(usize, usize), ()> = HashMap::new();
    for p in &selection.patches {
        let (i0, j0) = (
            (p.uv_origin[0] * side as f32) as usize,
            (p.uv_origin[1] * side as f32) as usize,
        );
        let n = (p.uv_size * side as f32) as usize;
        for (di, dj) in [(0, 0), (n, 0), (0, n), (n, n)] {
            corners.insert((i0 + di, j0 + dj), ());
        }
    }
    let mut shared = 0;
    for &(i, j) in corners.keys() {
        let mut touching: Vec<usize> = Vec::with_capacity(4);
        for (ci, cj) in [
            (i.wrapping_sub(1), j.wrapping_sub(1)),
            (i, j.wrapping_sub(1)),
            (i.wrapping_sub(1), j),
            (i, j),
        ] {
            if ci < side && cj < side {
                let o = cover.owner[cj * side + ci];
                if o < CULLED && !touching.contains(&o) {
                    touching.push(o);
                }
            }
        }
        if touching.len() < 2 {
            continue;
        }
        shared += 1;
        let (u, v) = (i as f32 / side as f32, j as f32 / side as f32);
        let entries: Vec<(u32, f32)> = touching
            .iter()
            .map(|&k| {
                (
                    selection.patches[k].level,
                    morph_at(&selection.patches[k], u, v),
                )
            })
            .collect();
        let lo = entries.iter().map(|e| e.0).min().unwrap();
        let hi = entries.iter().map(|e| e.0).max().unwrap();
        assert!(hi - lo <= 1, "levels {lo}..{hi} meet at ({u}, {v})");
        for a in &entries {
            for b in &entries {
                if a.0 == b.0 {
                    assert_eq!(
                        a.1, b.1,
                        "same-level patches disagree on morph at ({u}, {v}): {entries:?}"
                    );
                }
            }
            if hi > lo {
                let expected = if a.0 == lo { 1.0 } else { 0.0 };
                assert_eq!(
                    a.1, expected,
                    "level {lo}/{hi} seam at ({u}, {v}) not snapped: {entries:?}"
                );
            }
        }
    }
    let _ = settings;
    shared
}
