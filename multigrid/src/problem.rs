//! One scalar diffusion problem on level 0, as both backends take it (see `ALGORITHM.md`).

/// Level-0 input of one diffusion solve: constraint weights and values, and prescribed edge differences.
///
/// All arrays are `n * n`, row 0 = south, index `j * n + i`. `d_east` / `d_north` may be empty
/// (no prescribed differences: pure diffusion).
#[derive(Debug, Clone, Default)]
pub struct FieldProblem {
    /// Cells per side.
    pub n: usize,
    /// Anisotropy weight of east/west edges (`dy / dx`).
    pub ax: f32,
    /// Anisotropy weight of north/south edges (`dx / dy`).
    pub ay: f32,
    /// Constraint weight `w` in [0, 1]; 1 = hard (Dirichlet), (0, 1) = soft.
    pub weight: Vec<f32>,
    /// Constrained value `E` (meaningful where `weight > 0`).
    pub value: Vec<f32>,
    /// Wanted `h(i+1, j) - h(i, j)` across each cell's east edge (empty = none).
    pub d_east: Vec<f32>,
    /// Wanted `h(i, j+1) - h(i, j)` across each cell's north edge (empty = none).
    pub d_north: Vec<f32>,
}

/// Weight at or above which a cell is hard (exactly 1 after rasterisation).
pub const HARD_WEIGHT: f32 = 1.0;
/// Largest soft weight used in `sigma = (2 ax + 2 ay) w / (1 - w)`.
pub const MAX_SOFT_WEIGHT: f32 = 0.999;

/// Diagonal penalty of a soft cell, 0 for unconstrained cells. Hard cells are handled separately.
#[inline]
pub fn soft_sigma(weight: f32, ax: f32, ay: f32) -> f32 {
    if weight <= 0.0 {
        0.0
    } else {
        let w = weight.min(MAX_SOFT_WEIGHT);
        (2.0 * ax + 2.0 * ay) * w / (1.0 - w)
    }
}

/// True if the cell is a hard (Dirichlet) constraint.
#[inline]
pub fn is_hard(weight: f32) -> bool {
    weight >= HARD_WEIGHT
}

impl FieldProblem {
    /// A pure diffusion problem (no edge differences) on an `n x n` grid.
    pub fn diffusion(
        n: usize,
        [ax, ay]: [f32; 2],
        weight: Vec<f32>,
        value: Vec<f32>,
    ) -> FieldProblem {
        FieldProblem {
            n,
            ax,
            ay,
            weight,
            value,
            ..Default::default()
        }
    }

    /// Relief of the constrained values: `max E - min E` over cells with weight > 0, at least 1.
    pub fn relief(&self) -> f32 {
        let mut lo = f32::INFINITY;
        let mut hi = f32::NEG_INFINITY;
        for (w, e) in self.weight.iter().zip(&self.value) {
            if *w > 0.0 {
                lo = lo.min(*e);
                hi = hi.max(*e);
            }
        }
        if hi > lo { (hi - lo).max(1.0) } else { 1.0 }
    }
}
