//! Local relaxation on level 0: red-black Gauss-Seidel sweeps over the cells near a few seed cells.
//!
//! Used where the error is concentrated in a few small places that global cycles reduce only at
//! their steady rate: after FMG, at the handful of spots where the coarse levels cannot represent
//! the solution (steep stroke crossings, plateau corners: the largest residuals), and on a warm
//! start, around the cells whose elevation constraint changed. A few sweeps there cost a few hundred
//! cells each (the classic local relaxation near singularities of Brandt's multigrid guide).

use rayon::prelude::*;

use super::Hierarchy;
use super::fast;

/// Chebyshev radius of the window around each seed.
pub(crate) const RADIUS: usize = 6;
/// Red-black sweeps over the windows.
pub(crate) const SWEEPS: usize = 10;
/// Normalised residual above which a cell seeds a window after FMG.
pub(crate) const FMG_SEED_RESIDUAL: f32 = 0.1;

/// The cells within `RADIUS` of any seed (ascending, without duplicates).
pub(crate) fn windows(n: usize, seeds: &[u32]) -> Vec<u32> {
    let side = 2 * RADIUS + 1;
    let each = |f: &mut dyn FnMut(usize)| {
        for &c in seeds {
            let (i, j) = (c as usize % n, c as usize / n);
            for y in j.saturating_sub(RADIUS)..(j + RADIUS + 1).min(n) {
                for x in i.saturating_sub(RADIUS)..(i + RADIUS + 1).min(n) {
                    f(y * n + x);
                }
            }
        }
    };
    if seeds.len() * side * side > n * n {
        // Many seeds: a mask of the level is smaller than the list of window cells.
        let mut mark = vec![false; n * n];
        each(&mut |k| mark[k] = true);
        (0..n * n).filter(|&k| mark[k]).map(|k| k as u32).collect()
    } else {
        let mut cells = Vec::with_capacity(seeds.len() * side * side);
        each(&mut |k| cells.push(k as u32));
        cells.sort_unstable();
        cells.dedup();
        cells
    }
}

impl Hierarchy {
    /// Local relaxation of `h` around `seeds` (level-0 indices): `SWEEPS` sweeps over `windows`,
    /// unless they cover more than a quarter of the level (then not local: the cycles do it
    /// better). Returns work units.
    pub(crate) fn relax_around(&self, h: &mut [f32], seeds: &[u32]) -> f64 {
        let n = self.n();
        if seeds.is_empty() || seeds.len() * 4 > n * n {
            return 0.0;
        }
        let cells = windows(n, seeds);
        if cells.len() * 4 > n * n {
            return 0.0;
        }
        self.relax_cells(h, &cells)
    }

    /// `SWEEPS` red-black Gauss-Seidel sweeps of `h` over `cells` (sorted level-0 indices; hard cells
    /// are skipped). Returns work units (cells swept / level-0 cells).
    pub(crate) fn relax_cells(&self, h: &mut [f32], cells: &[u32]) -> f64 {
        let l0 = &self.level0;
        let n = l0.n;
        for _ in 0..SWEEPS {
            for colour in 0..2 {
                for &c in cells {
                    let k = c as usize;
                    let (i, j) = (k % n, k / n);
                    let d = l0.diag[k];
                    if (i + j) & 1 != colour || d == 0.0 {
                        continue;
                    }
                    let mut s = 0.0;
                    if i > 0 {
                        s += l0.ax * h[k - 1];
                    }
                    if i + 1 < n {
                        s += l0.ax * h[k + 1];
                    }
                    if j > 0 {
                        s += l0.ay * h[k - n];
                    }
                    if j + 1 < n {
                        s += l0.ay * h[k + n];
                    }
                    h[k] = (l0.f[k] + s) / d;
                }
            }
        }
        (cells.len() * SWEEPS) as f64 / (n * n) as f64
    }

    /// The seeds of the local relaxation after FMG: the level-0 cells of `st.h` whose normalised
    /// residual exceeds `FMG_SEED_RESIDUAL` (ascending). `r` is scratch (resized to the level).
    pub fn fmg_seeds(&self, st: &super::FieldState, r: &mut Vec<f32>) -> Vec<u32> {
        self.large_residual_cells(&st.h, r, FMG_SEED_RESIDUAL)
    }

    /// Level-0 cells whose normalised residual exceeds `threshold` (ascending). `r` is scratch
    /// (resized to the level).
    pub(crate) fn large_residual_cells(
        &self,
        h: &[f32],
        r: &mut Vec<f32>,
        threshold: f32,
    ) -> Vec<u32> {
        let n = self.n();
        r.resize(n * n, 0.0);
        fast::initial_residual(&self.level0, h, r);
        let limit = threshold / self.residual_scale();
        r.par_chunks(n)
            .enumerate()
            .flat_map_iter(|(j, row)| {
                row.iter()
                    .enumerate()
                    .filter(move |(_, v)| v.abs() > limit)
                    .map(move |(i, _)| (j * n + i) as u32)
            })
            .collect()
    }
}
