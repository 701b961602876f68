//! Grid sizes, levels and the limits every backend checks before allocating.

use crate::SolverError;

/// Smallest supported heightmap side, cells.
pub const MIN_SIDE: usize = 64;
/// Largest supported heightmap side, cells (wgpu's common maximum 2D texture size).
pub const MAX_SIDE: usize = 16384;
/// Side of the coarsest multigrid level, solved exactly.
pub const COARSEST_SIDE: usize = 8;

/// The finest grid: `n x n` cells over an extent in metres. Row 0 is the south edge.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Grid {
    /// Cells per side (a power of two in `MIN_SIDE..=MAX_SIDE`).
    pub n: usize,
    /// Width (east) and height (north) of the terrain, metres.
    pub extent_m: [f64; 2],
}

impl Grid {
    /// Checks the size and extent; refuses bad or huge sizes before anything is allocated.
    pub fn new(n: usize, extent_m: [f64; 2]) -> Result<Grid, SolverError> {
        if !n.is_power_of_two() || !(MIN_SIDE..=MAX_SIDE).contains(&n) {
            return Err(SolverError::BadSize { size: n });
        }
        if !extent_m.iter().all(|e| e.is_finite() && *e > 0.0) {
            return Err(SolverError::BadExtent { extent_m });
        }
        Ok(Grid { n, extent_m })
    }

    /// Cell size in metres, `[dx, dy]`.
    pub fn cell_size_m(&self) -> [f64; 2] {
        [
            self.extent_m[0] / self.n as f64,
            self.extent_m[1] / self.n as f64,
        ]
    }

    /// Anisotropy weights `[ax, ay] = [dy/dx, dx/dy]` of the 5-point operator (1, 1 on square cells).
    pub fn axis_weights(&self) -> [f32; 2] {
        let [dx, dy] = self.cell_size_m();
        [(dy / dx) as f32, (dx / dy) as f32]
    }

    /// Number of multigrid levels, level 0 (n) down to the coarsest (`COARSEST_SIDE`).
    pub fn solve_levels(&self) -> usize {
        (self.n / COARSEST_SIDE).trailing_zeros() as usize + 1
    }

    /// Number of mip levels of the heightmap texture (n down to 1x1).
    pub fn mip_levels(&self) -> usize {
        self.n.trailing_zeros() as usize + 1
    }

    /// Side of level `k`.
    pub fn side(&self, level: usize) -> usize {
        self.n >> level
    }

    /// Cells on level 0.
    pub fn cells(&self) -> usize {
        self.n * self.n
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn refuses_bad_sizes_and_extents() {
        assert!(Grid::new(100, [1.0, 1.0]).is_err());
        assert!(Grid::new(32, [1.0, 1.0]).is_err());
        assert!(Grid::new(32768, [1.0, 1.0]).is_err());
        assert!(Grid::new(0, [1.0, 1.0]).is_err());
        assert!(Grid::new(64, [0.0, 1.0]).is_err());
        assert!(Grid::new(64, [f64::NAN, 1.0]).is_err());
        assert!(Grid::new(64, [1.0, -3.0]).is_err());
    }

    #[test]
    fn levels() {
        let g = Grid::new(1024, [20480.0, 10240.0]).unwrap();
        assert_eq!(g.solve_levels(), 8); // 1024 .. 8
        assert_eq!(g.mip_levels(), 11);
        assert_eq!(g.cell_size_m(), [20.0, 10.0]);
        assert_eq!(g.axis_weights(), [0.5, 2.0]);
        let g = Grid::new(64, [1.0, 1.0]).unwrap();
        assert_eq!(g.solve_levels(), 4);
    }
}
