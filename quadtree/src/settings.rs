//! LOD settings and the level/mip/size arithmetic derived from them.

use crate::QuadtreeError;

/// What the selection refines and how far.
///
/// Levels count from the finest patches: level 0 patches have `leaf_cells` grid cells per side,
/// each the size of one heightmap cell of mip `mip_offset()` (mip 0 when the tree is as deep as
/// the heightmap allows). The root (level `levels() - 1`) covers the whole extent.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LodSettings {
    /// Heightmap side `n` (cells per side of mip 0); a power of two, 64..=16384 in the product.
    pub heightmap_side: usize,
    /// Terrain extent `[x (east), y (north)]` in metres.
    pub extent_m: [f32; 2],
    /// Grid cells per patch side (the instanced grid is `leaf_cells x leaf_cells` quads); a
    /// power of two, at least 2 and at most `heightmap_side`.
    pub leaf_cells: usize,
    /// A node is split while the larger side of its projected screen rectangle exceeds this
    /// many pixels. 128 px with 32 cells per patch gives grid cells of at most 4 px.
    pub pixel_budget: f32,
    /// Upper bound on the number of quadtree levels; the tree never goes deeper than mip 0
    /// allows (`log2(heightmap_side / leaf_cells) + 1` levels).
    pub max_levels: u32,
    /// Where, within a level's LOD range, morphing toward the next coarser level starts: 0
    /// morphs over the whole range, 0.7 over its far 30 % (as CDLOD; measured as a distance for
    /// a node facing the camera, applied to the projected size, see
    /// [`morph_start_q`](crate::morph_start_q)). In `[0, 1)`.
    pub morph_start_ratio: f32,
}

impl LodSettings {
    /// Defaults: 32 cells per patch, 128 px budget, as many levels as the heightmap allows,
    /// morph over the last 30 % of each range.
    pub fn new(heightmap_side: usize, extent_m: [f32; 2]) -> Self {
        Self {
            heightmap_side,
            extent_m,
            leaf_cells: 32,
            pixel_budget: 128.0,
            max_levels: 32,
            morph_start_ratio: 0.7,
        }
    }

    /// Checks every field against its documented range.
    pub fn validate(&self) -> Result<(), QuadtreeError> {
        let bad =
            |field, value: String, rule| Err(QuadtreeError::InvalidSettings { field, value, rule });
        let n = self.heightmap_side;
        if !n.is_power_of_two() || !(2..=(1 << 20)).contains(&n) {
            return bad(
                "heightmap_side",
                n.to_string(),
                "a power of two in 2..=2^20",
            );
        }
        if !self.extent_m.iter().all(|e| e.is_finite() && *e > 0.0) {
            return bad(
                "extent_m",
                format!("{:?}", self.extent_m),
                "both sides finite and > 0",
            );
        }
        if !self.leaf_cells.is_power_of_two() || self.leaf_cells < 2 || self.leaf_cells > n {
            return bad(
                "leaf_cells",
                self.leaf_cells.to_string(),
                "a power of two in 2..=heightmap_side",
            );
        }
        if !(self.pixel_budget.is_finite() && self.pixel_budget >= 1.0) {
            return bad(
                "pixel_budget",
                self.pixel_budget.to_string(),
                "finite and >= 1 px",
            );
        }
        if self.max_levels == 0 {
            return bad("max_levels", self.max_levels.to_string(), ">= 1");
        }
        if !(0.0..1.0).contains(&self.morph_start_ratio) {
            return bad(
                "morph_start_ratio",
                self.morph_start_ratio.to_string(),
                "in [0, 1)",
            );
        }
        Ok(())
    }

    /// Number of quadtree levels actually used: `min(max_levels, log2(n / leaf_cells) + 1)`.
    pub fn levels(&self) -> u32 {
        let possible = (self.heightmap_side / self.leaf_cells).trailing_zeros() + 1;
        self.max_levels.min(possible)
    }

    /// Mip sampled by level-0 patches: 0 unless `max_levels` cut the tree short. A level-`L`
    /// patch samples mip `L + mip_offset()` (or the finest ready mip if that is coarser).
    pub fn mip_offset(&self) -> u32 {
        (self.heightmap_side / self.leaf_cells).trailing_zeros() + 1 - self.levels()
    }

    /// Index of the coarsest heightmap mip (1x1): `log2(heightmap_side)`.
    pub fn coarsest_mip(&self) -> u32 {
        self.heightmap_side.trailing_zeros()
    }

    /// Finest level the selection may use when mips finer than `finest_ready_mip` are not
    /// solved yet: `clamp(finest_ready_mip - mip_offset(), 0, levels() - 1)`.
    pub fn finest_allowed_level(&self, finest_ready_mip: u32) -> u32 {
        finest_ready_mip
            .saturating_sub(self.mip_offset())
            .min(self.levels() - 1)
    }

    /// Size `[x, y]` in metres of a node at `level`.
    pub fn node_size_m(&self, level: u32) -> [f32; 2] {
        let depth = self.levels() - 1 - level.min(self.levels() - 1);
        let scale = 1.0 / (1u64 << depth) as f32;
        [self.extent_m[0] * scale, self.extent_m[1] * scale]
    }
}
