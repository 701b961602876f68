//! Exact solve on the coarsest level: Gaussian elimination with partial pivoting over the active
//! cells, factored once per assembly (the operator does not change between cycles) so that each
//! solve is two triangular sweeps with no allocation.

/// LU factors (with the row swaps of partial pivoting) of the active part of a 9-point operator.
pub(crate) struct Lu {
    /// Active cells, in unknown order.
    active: Vec<usize>,
    /// Unknowns.
    m: usize,
    /// Row-major `m x m`: `U` on and above the diagonal, the elimination factors below it.
    a: Vec<f64>,
    /// Per column: the pivot row swapped in, or `usize::MAX` if the column was skipped (singular).
    piv: Vec<usize>,
    /// The elimination factors column by column (`l[col * m + r]`, `r > col`), contiguous for the
    /// forward sweep.
    l: Vec<f64>,
    /// Per column of `l`: one past its last non-zero row; per row of `U`: one past its last non-zero
    /// column (the operator is banded, so both sweeps skip the zero tails).
    l_end: Vec<usize>,
    u_end: Vec<usize>,
}

impl Lu {
    /// Factors the operator given by the stencils `st` of a level of side `n`.
    pub fn new(n: usize, st: &[[f32; 9]]) -> Lu {
        let active: Vec<usize> = (0..n * n).filter(|&c| st[c][4] != 0.0).collect();
        let m = active.len();
        let mut pos = vec![usize::MAX; n * n];
        for (k, &c) in active.iter().enumerate() {
            pos[c] = k;
        }
        let mut a = vec![0.0f64; m * m];
        for (r, &c) in active.iter().enumerate() {
            let (i, j) = (c % n, c / n);
            for oy in 0..3 {
                for ox in 0..3 {
                    let (x, y) = (i + ox, j + oy);
                    if x < 1 || y < 1 || x > n || y > n {
                        continue;
                    }
                    let nb = (y - 1) * n + (x - 1);
                    if pos[nb] != usize::MAX {
                        a[r * m + pos[nb]] += st[c][oy * 3 + ox] as f64;
                    }
                }
            }
        }
        let mut piv = vec![usize::MAX; m];
        for col in 0..m {
            let p = (col..m)
                .max_by(|&p, &q| a[p * m + col].abs().total_cmp(&a[q * m + col].abs()))
                .unwrap_or(col);
            if a[p * m + col].abs() < 1e-30 {
                continue; // singular direction: leave it at 0
            }
            piv[col] = p;
            if p != col {
                // Columns left of `col` hold the factors of earlier steps, which stay with their
                // positions (the solve replays the swaps and eliminations in order).
                for k in col..m {
                    a.swap(p * m + k, col * m + k);
                }
            }
            let d = a[col * m + col];
            for r in col + 1..m {
                let factor = a[r * m + col] / d;
                if factor != 0.0 {
                    for k in col + 1..m {
                        a[r * m + k] -= factor * a[col * m + k];
                    }
                }
                a[r * m + col] = factor;
            }
        }
        let mut l = vec![0.0f64; m * m];
        let (mut l_end, mut u_end) = (vec![0; m], vec![0; m]);
        for col in 0..m {
            for r in col + 1..m {
                l[col * m + r] = a[r * m + col];
                if a[r * m + col] != 0.0 {
                    l_end[col] = r + 1;
                }
            }
            u_end[col] = (col + 1..m)
                .rev()
                .find(|&k| a[col * m + k] != 0.0)
                .map_or(col + 1, |k| k + 1);
        }
        Lu {
            active,
            m,
            a,
            piv,
            l,
            l_end,
            u_end,
        }
    }

    /// Solves for the right-hand side `f` (all cells of the level) into `u` (active cells only;
    /// the others are left untouched).
    pub fn solve(&self, f: &[f32], u: &mut [f32]) {
        let m = self.m;
        if m == 0 {
            return;
        }
        let mut b = [0.0f64; 64];
        let mut heap;
        let b: &mut [f64] = if m <= 64 {
            &mut b[..m]
        } else {
            heap = vec![0.0f64; m];
            &mut heap
        };
        for (r, &c) in self.active.iter().enumerate() {
            b[r] = f[c] as f64;
        }
        let a = &self.a;
        for col in 0..m {
            let p = self.piv[col];
            if p == usize::MAX {
                continue;
            }
            if p != col {
                b.swap(p, col);
            }
            let bc = b[col];
            let end = self.l_end[col].max(col + 1);
            for (br, f) in b[col + 1..end]
                .iter_mut()
                .zip(&self.l[col * m + col + 1..col * m + end])
            {
                *br -= f * bc;
            }
        }
        for r in (0..m).rev() {
            let end = self.u_end[r];
            let (row, x) = (&a[r * m + r + 1..r * m + end], &b[r + 1..end]);
            let mut s = [0.0f64; 4];
            let (rc, xc) = (row.chunks_exact(4), x.chunks_exact(4));
            for (p, q) in rc.remainder().iter().zip(xc.remainder()) {
                s[0] += p * q;
            }
            for (p, q) in rc.zip(xc) {
                for k in 0..4 {
                    s[k] += p[k] * q[k];
                }
            }
            let s = b[r] - ((s[0] + s[1]) + (s[2] + s[3]));
            let d = a[r * m + r];
            b[r] = if d.abs() < 1e-30 { 0.0 } else { s / d };
        }
        for (k, &c) in self.active.iter().enumerate() {
            u[c] = b[k] as f32;
        }
    }
}
