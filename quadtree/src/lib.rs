//! View- and height-dependent quadtree LOD selection for terrasketch, in the CDLOD style, on the
//! CPU and without GPU types (depends on `glam` and `thiserror` only).
//!
//! # How it works
//!
//! - **Bounds.** A [`MinMaxPyramid`] holds per-cell min/max heights for levels of at most 64x64
//!   cells (the solver reads a few KB back). A quadtree node at depth `d` (root 0) maps to one
//!   cell of the level with side `2^d`, so its box is exact; nodes finer than the finest stored
//!   level inherit their ancestor cell's bounds.
//! - **Refinement** (the paper's rule). Each node's box (footprint x `[min_z, max_z]`) is
//!   projected: its 8 corners go to clip space. If all corners lie outside one of the six clip
//!   planes the node is culled. Otherwise the corners' screen bounding rectangle, clipped to the
//!   viewport, is measured; while its larger side exceeds [`LodSettings::pixel_budget`] (or the
//!   box reaches behind the camera plane) the node is split into four, down to the finest level
//!   allowed by [`LodSettings::levels`] and by the solver's finest ready mip. A tall box projects
//!   taller and sits closer to a camera above it, so mountains refine more than flat ground.
//! - **Storage.** Nodes live in one flat `Vec` reused across frames (children consecutive), each
//!   with links to its 8 same-depth neighbours, maintained in both directions when a node is
//!   split. No allocation after warm-up.
//! - **Balance.** The pixel rule alone can put a large leaf next to much smaller ones. A second
//!   pass visits internal nodes from the deepest depth up and makes each of their 8 same-depth
//!   neighbours exist, splitting leaves (culled ones too) as needed. Then any two touching leaves
//!   differ by at most one level, along edges *and* at corners: a leaf at depth `d` has an
//!   internal parent whose 8 neighbours exist at depth `d - 1`, so nothing touching it is
//!   shallower than `d - 1`; and a touching leaf deeper than `d + 1` would have an internal
//!   parent whose required neighbours would include our leaf's children.
//! - **Morph data.** Each patch gets a morph factor toward the next coarser grid at its four
//!   corners; the vertex shader interpolates it bilinearly (contract: the crate README). It
//!   follows the same metric as the refinement: with `q` = projected size / budget per node, a
//!   level exists while its parent's `q > 1`, so a corner morphs from 0 to 1 as the smallest `q`
//!   of the parent-depth nodes containing it falls from [`morph_start_q`] to 1 (CDLOD's "morph
//!   over the far end of the range", with the range measured in projected size instead of
//!   distance, since the shader cannot project boxes). Crack-freedom does not depend on that
//!   value: a corner touched by a coarser leaf is forced to 1 and one touched by a finer leaf to
//!   0 (corner balance makes the two exclusive), and the value is a function of the corner, the
//!   level and the tree only. Hence along a seam between levels `L` and `L + 1` the fine side
//!   is fully morphed and the coarse side not at all, and same-level neighbours agree exactly.
//! - **Checks.** [`max_neighbour_level_diff`] measures balance from the patches alone;
//!   [`bench_lod`] times [`select`] over [`bench_camera_path`].
#![warn(missing_docs)]

mod bench;
mod camera;
mod check;
mod error;
mod pyramid;
mod select;
mod settings;
mod tree;

pub use bench::{BENCH_FOV_Y_RAD, BENCH_VIEWPORT_PX, LodBenchReport, bench_camera_path, bench_lod};
pub use camera::Camera;
pub use check::max_neighbour_level_diff;
pub use error::QuadtreeError;
pub use pyramid::MinMaxPyramid;
pub use select::{Patch, SelectStats, Selection, morph_start_q, select};
pub use settings::LodSettings;
