//! Row-parallel helpers for in-place colour sweeps.

/// A raw pointer that may be shared between rayon tasks.
///
/// Used only for colour-ordered Gauss-Seidel sweeps, where the cells written in one colour pass are
/// never read or written by another task of the same pass (see the SAFETY notes at each use).
#[derive(Clone, Copy)]
pub(crate) struct SharedMut(pub *mut f32);

// SAFETY: callers guarantee disjoint writes and no reads of cells being written in the same pass.
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
        unsafe { *self.0.add(idx) }
    }

    /// Writes cell `idx`.
    ///
    /// # Safety
    /// `idx` is in bounds, only this task writes it during this pass, and nobody reads it in the pass.
    #[inline(always)]
    pub unsafe fn set(self, idx: usize, value: f32) {
        unsafe { *self.0.add(idx) = value }
    }
}

/// Below this many cells a level is processed on the calling thread (rayon overhead dominates).
pub(crate) const PARALLEL_MIN_CELLS: usize = 128 * 128;

/// Rows per rayon task on large levels.
pub(crate) const ROWS_PER_TASK: usize = 8;
