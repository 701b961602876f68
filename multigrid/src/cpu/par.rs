//! Parallel helpers: row blocks, a shared pointer for in-place sweeps, per-thread scratch rows.

use std::cell::RefCell;
use std::ops::Range;

use rayon::prelude::*;

/// A raw pointer that may be shared between rayon tasks.
///
/// Used for in-place Gauss-Seidel sweeps and row pipelines, where the rows written by one task are
/// never read or written by another task during the same pass (see the SAFETY notes at each use).
#[derive(Clone, Copy)]
pub(crate) struct SharedMut(pub *mut f32);

// SAFETY: callers guarantee disjoint writes and no reads of cells another task writes in the same pass.
unsafe impl Send for SharedMut {}
// SAFETY: as above.
unsafe impl Sync for SharedMut {}

impl SharedMut {
    /// Reads cell `idx`.
    ///
    /// # Safety
    /// `idx` is in bounds and no other task writes it during this pass.
    #[inline(always)]
    pub unsafe fn get(self, idx: usize) -> f32 {
        // SAFETY: forwarded to the caller (in bounds, no concurrent writer).
        unsafe { *self.0.add(idx) }
    }

    /// Writes cell `idx`.
    ///
    /// # Safety
    /// `idx` is in bounds, only this task writes it during this pass, and no other task reads it.
    #[inline(always)]
    pub unsafe fn set(self, idx: usize, value: f32) {
        // SAFETY: forwarded to the caller (in bounds, exclusive to this task).
        unsafe { *self.0.add(idx) = value }
    }

    /// The cells `start .. start + len` as a shared slice.
    ///
    /// # Safety
    /// In bounds, and nobody writes these cells while the slice lives.
    #[inline(always)]
    pub unsafe fn slice<'a>(self, start: usize, len: usize) -> &'a [f32] {
        // SAFETY: forwarded to the caller (in bounds, no concurrent writer while the slice lives).
        unsafe { std::slice::from_raw_parts(self.0.add(start), len) }
    }

    /// The cells `start .. start + len` as a mutable slice.
    ///
    /// # Safety
    /// In bounds, and nobody else reads or writes these cells while the slice lives.
    #[inline(always)]
    #[allow(clippy::mut_from_ref)]
    pub unsafe fn slice_mut<'a>(self, start: usize, len: usize) -> &'a mut [f32] {
        // SAFETY: forwarded to the caller (in bounds, exclusive while the slice lives).
        unsafe { std::slice::from_raw_parts_mut(self.0.add(start), len) }
    }
}

/// Runs `f` on a thread of rayon's pool (at once if this already is one).
///
/// A parallel pass started from a thread outside the pool hands its blocks to the pool and puts the
/// caller to sleep until they are done: one wake-up of a sleeping worker and one of the caller per
/// pass, hundreds per solve. Started from a worker, the passes' blocks are shared with the other
/// workers by work stealing and the caller takes part.
pub(crate) fn on_worker<R: Send>(f: impl FnOnce() -> R + Send) -> R {
    if rayon::current_thread_index().is_some() {
        f()
    } else {
        rayon::scope(|_| f())
    }
}

/// Below this many cells a level is processed on the calling thread (rayon overhead dominates).
pub(crate) const PARALLEL_MIN_CELLS: usize = 128 * 128;

/// Fewest rows in one parallel block (halo work and scheduling stay small next to the block's work).
const MIN_BLOCK_ROWS: usize = 16;

/// Number of row blocks for a pass over `rows` rows of `cols` cells: 1 on small levels.
pub(crate) fn block_count(rows: usize, cols: usize) -> usize {
    if rows * cols < PARALLEL_MIN_CELLS {
        1
    } else {
        (2 * rayon::current_num_threads())
            .min(rows / MIN_BLOCK_ROWS)
            .max(1)
    }
}

/// Rows of block `b` of `count` over `rows` rows; boundaries are multiples of `align`
/// (`rows` must be a multiple of `align`).
#[inline]
pub(crate) fn block_rows(b: usize, count: usize, rows: usize, align: usize) -> Range<usize> {
    let units = rows / align;
    (b * units / count) * align..((b + 1) * units / count) * align
}

/// Runs `f(block index, rows)` on every block (`count` from `block_count`), in parallel if several.
pub(crate) fn for_blocks(
    rows: usize,
    count: usize,
    align: usize,
    f: impl Fn(usize, Range<usize>) + Sync,
) {
    if count == 1 {
        f(0, 0..rows);
    } else {
        (0..count)
            .into_par_iter()
            .for_each(|b| f(b, block_rows(b, count, rows, align)));
    }
}

/// Like `for_blocks`, reducing the blocks' results with `op`.
pub(crate) fn map_blocks<T>(
    rows: usize,
    count: usize,
    align: usize,
    f: impl Fn(usize, Range<usize>) -> T + Sync,
    identity: T,
    op: impl Fn(T, T) -> T + Sync + Send,
) -> T
where
    T: Copy + Send + Sync,
{
    if count == 1 {
        op(identity, f(0, 0..rows))
    } else {
        (0..count)
            .into_par_iter()
            .map(|b| f(b, block_rows(b, count, rows, align)))
            .reduce(|| identity, op)
    }
}

/// Copies of the rows within `halo` rows of each interior block boundary, taken before an in-place
/// pass so that a block can read its neighbours' old rows while they are being overwritten.
pub(crate) struct Halo {
    rows: Vec<f32>,
    n: usize,
    halo: usize,
    count: usize,
    total: usize,
    align: usize,
}

impl Halo {
    /// Snapshots `a` (rows of `n` cells, `total` rows) around the boundaries of `count` blocks.
    pub fn take(
        a: &[f32],
        n: usize,
        total: usize,
        count: usize,
        align: usize,
        halo: usize,
    ) -> Halo {
        let mut rows = vec![0.0f32; count.saturating_sub(1) * 2 * halo * n];
        for b in 1..count {
            let x = block_rows(b, count, total, align).start;
            for k in 0..2 * halo {
                let j = (x + k) as isize - halo as isize;
                if j >= 0 && (j as usize) < total {
                    let dst = ((b - 1) * 2 * halo + k) * n;
                    rows[dst..dst + n].copy_from_slice(&a[j as usize * n..(j as usize + 1) * n]);
                }
            }
        }
        Halo {
            rows,
            n,
            halo,
            count,
            total,
            align,
        }
    }

    /// The saved copy of row `j`, which must lie within `halo` rows of a boundary of block `b`
    /// and outside the block.
    pub fn row(&self, b: usize, j: usize) -> &[f32] {
        let own = block_rows(b, self.count, self.total, self.align);
        let (boundary, x) = if j < own.start {
            (b, own.start)
        } else {
            (b + 1, own.end)
        };
        let k = j + self.halo - x;
        let src = ((boundary - 1) * 2 * self.halo + k) * self.n;
        &self.rows[src..src + self.n]
    }
}

thread_local! {
    static SCRATCH: RefCell<Vec<f32>> = const { RefCell::new(Vec::new()) };
}

/// Runs `f` with a per-thread scratch buffer of `len` floats (contents unspecified).
/// `f` must not call `with_scratch` again nor start parallel work.
pub(crate) fn with_scratch<R>(len: usize, f: impl FnOnce(&mut [f32]) -> R) -> R {
    SCRATCH.with(|s| {
        let mut s = s.borrow_mut();
        if s.len() < len {
            s.resize(len, 0.0);
        }
        f(&mut s[..len])
    })
}

/// A row of zeros at least as long as the largest level side, for missing neighbour rows.
pub(crate) static ZEROS: [f32; crate::grid::MAX_SIDE + 2] = [0.0; crate::grid::MAX_SIDE + 2];

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn on_worker_runs_on_a_pool_thread_and_returns_the_result() {
        assert!(
            rayon::current_thread_index().is_none(),
            "tests run outside the pool"
        );
        let (inside, sum) = on_worker(|| {
            let inside = rayon::current_thread_index().is_some();
            // Nested parallel work from the worker still completes (work stealing, no deadlock).
            let sum: u64 = (0..10_000u64).into_par_iter().sum();
            (inside, sum)
        });
        assert!(inside, "the closure did not run on a rayon worker");
        assert_eq!(sum, 10_000 * 9_999 / 2);
        // Already on a worker: runs at once, on the same thread.
        let same = on_worker(|| {
            let me = rayon::current_thread_index();
            on_worker(rayon::current_thread_index) == me
        });
        assert!(same);
    }
}
