//! Errors: a pyramid or settings value the quadtree refuses to work with.

/// Why a [`MinMaxPyramid`](crate::MinMaxPyramid), a height grid or [`LodSettings`](crate::LodSettings)
/// was refused. Each variant names the level or field at fault.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum QuadtreeError {
    /// `from_levels` was given no level at all.
    #[error("the min/max pyramid has no level")]
    EmptyPyramid,
    /// A side length is zero or not a power of two.
    #[error("side {side} (level {level}) is not a power of two >= 1")]
    SideNotPowerOfTwo {
        /// Pyramid level (0 = finest stored), or 0 for a height grid.
        level: usize,
        /// The side length found.
        side: usize,
    },
    /// Level `level` does not have half the side of level `level - 1`.
    #[error("level {level} has side {side}, expected {expected} (half of the level below)")]
    SidesDoNotHalve {
        /// Pyramid level (0 = finest stored).
        level: usize,
        /// The side length found.
        side: usize,
        /// Half the side of the previous level.
        expected: usize,
    },
    /// The coarsest level is not 1x1.
    #[error("the coarsest level has side {side}, expected 1")]
    CoarsestNotOneByOne {
        /// Side of the last level given.
        side: usize,
    },
    /// A level (or height grid) does not hold side * side values.
    #[error("level {level} holds {got} cells, expected {expected}")]
    WrongCellCount {
        /// Pyramid level (0 = finest stored), or 0 for a height grid.
        level: usize,
        /// side * side.
        expected: usize,
        /// Number of values given.
        got: usize,
    },
    /// A height or bound is NaN or infinite.
    #[error("level {level}, cell {cell}: value is not finite")]
    NonFinite {
        /// Pyramid level (0 = finest stored), or 0 for a height grid.
        level: usize,
        /// Linear cell index `row * side + column`, row 0 south.
        cell: usize,
    },
    /// A cell's minimum is above its maximum.
    #[error("level {level}, cell {cell}: min {min} > max {max}")]
    MinAboveMax {
        /// Pyramid level (0 = finest stored).
        level: usize,
        /// Linear cell index.
        cell: usize,
        /// The cell's minimum.
        min: f32,
        /// The cell's maximum.
        max: f32,
    },
    /// A coarse cell is not exactly the min/max of its four children: the producer has a bug, and
    /// node boxes built from it would not be exact.
    #[error("level {level}, cell {cell}: bounds are not the min/max of the four finer cells")]
    NotNested {
        /// Pyramid level of the coarse cell.
        level: usize,
        /// Linear cell index of the coarse cell.
        cell: usize,
    },
    /// An [`LodSettings`](crate::LodSettings) field is out of range.
    #[error("invalid LOD settings: {field} = {value} ({rule})")]
    InvalidSettings {
        /// Field name, e.g. `leaf_cells`.
        field: &'static str,
        /// The offending value, formatted.
        value: String,
        /// The rule it breaks.
        rule: &'static str,
    },
    /// The camera has a non-finite matrix, position or viewport, or a viewport side below 1 px.
    #[error("invalid camera: {0}")]
    InvalidCamera(&'static str),
}
