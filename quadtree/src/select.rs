//! The public selection: settings + camera + pyramid in, patches with morph data out.

use crate::tree::{Frame, MAX_DEPTH, Tree};
use crate::{Camera, LodSettings, MinMaxPyramid, QuadtreeError};

/// One drawable patch: a `leaf_cells x leaf_cells` grid over a quadtree leaf, displaced from one
/// heightmap mip and morphed toward the next coarser grid (formula: the crate README).
///
/// `uv_*` are exact dyadic fractions of the extent (`ix / 2^depth`); compute vertex positions
/// from them so neighbouring patches produce bit-identical shared vertices.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Patch {
    /// South-west corner as a fraction of the extent, `[u (east), v (north)]`.
    pub uv_origin: [f32; 2],
    /// Side as a fraction of the extent (`2^-depth`).
    pub uv_size: f32,
    /// South-west corner in metres (`uv_origin * extent_m`).
    pub origin_m: [f32; 2],
    /// Size in metres `[x, y]` (`uv_size * extent_m`).
    pub size_m: [f32; 2],
    /// LOD level, 0 = finest; the root is `LodSettings::levels() - 1`.
    pub level: u32,
    /// Heightmap mip the grid samples: `max(level + mip_offset, finest_ready_mip)`, at most the
    /// 1x1 mip. Morphing blends toward `mip_level + 1`.
    pub mip_level: u32,
    /// Morph factor toward the next coarser grid at the corners `[SW, SE, NW, NE]`, in
    /// `[0, 1]`; the shader interpolates it bilinearly over the patch (README). Exactly 1 at
    /// corners touched by a coarser patch, exactly 0 at corners touched by a finer one and on
    /// the root; equal for all same-level patches sharing a corner.
    pub morph: [f32; 4],
    /// Lowest height in the patch's footprint (metres).
    pub min_z: f32,
    /// Highest height in the patch's footprint (metres).
    pub max_z: f32,
}

/// Output of [`select`], owned by the caller and reused frame after frame: after the first few
/// frames no call allocates.
#[derive(Debug, Default, Clone)]
pub struct Selection {
    /// The patches to draw, in no particular order.
    pub patches: Vec<Patch>,
    tree: Tree,
}

impl Selection {
    /// An empty selection.
    pub fn new() -> Self {
        Self::default()
    }

    /// Leaves of the last selection that were culled (outside the view frustum), as
    /// `(uv_origin, uv_size)`. Together with the patches they tile the whole extent exactly
    /// once. For tests and debug views; walks the node storage.
    pub fn culled_leaves(&self) -> impl Iterator<Item = ([f32; 2], f32)> + '_ {
        self.tree
            .nodes
            .iter()
            .filter(|n| n.is_leaf() && n.is_culled())
            .map(|n| {
                let size = 1.0 / (1u64 << n.depth) as f32;
                ([n.ix as f32 * size, n.iy as f32 * size], size)
            })
    }
}

/// What one [`select`] call did.
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq)]
pub struct SelectStats {
    /// Nodes created and evaluated (root included).
    pub nodes_visited: u32,
    /// Leaves dropped because their box is outside the view frustum.
    pub culled: u32,
    /// Patches emitted.
    pub patches: u32,
    /// Leaves split by the balancing pass only (not by the pixel budget).
    pub balance_splits: u32,
    /// Finest level allowed this frame (from `finest_ready_mip`).
    pub finest_allowed_level: u32,
}

/// Selects the patches to draw for `camera`.
///
/// Refines from the root while a node's projected box exceeds `settings.pixel_budget`, never
/// below the level whose mip is `finest_ready_mip`; culls boxes outside the frustum; splits
/// extra leaves so touching patches differ by at most one level; writes the patches with their
/// morph data into `out` (cleared first). Errors only on invalid settings or camera.
pub fn select(
    pyramid: &MinMaxPyramid,
    settings: &LodSettings,
    camera: &Camera,
    finest_ready_mip: u32,
    out: &mut Selection,
) -> Result<SelectStats, QuadtreeError> {
    settings.validate()?;
    camera.validate()?;
    let levels = settings.levels();
    let max_depth = levels - 1;
    let finest_allowed_level = settings.finest_allowed_level(finest_ready_mip);
    let mut node_size_m = [[0.0; 2]; MAX_DEPTH + 1];
    for (depth, size) in node_size_m.iter_mut().enumerate().take(levels as usize) {
        let scale = 1.0 / (1u64 << depth) as f32;
        *size = [settings.extent_m[0] * scale, settings.extent_m[1] * scale];
    }
    let frame = Frame {
        pyramid,
        clip_from_world: camera.clip_from_world(),
        ndc_to_budget: [
            camera.viewport_px[0] * 0.5 / settings.pixel_budget,
            camera.viewport_px[1] * 0.5 / settings.pixel_budget,
        ],
        node_size_m,
        split_depth_limit: max_depth - finest_allowed_level,
    };
    let counts = out.tree.build(&frame, max_depth);

    out.patches.clear();
    let mut culled = 0;
    let (offset, coarsest_mip) = (settings.mip_offset(), settings.coarsest_mip());
    let q_start = morph_start_q(settings);
    let rcp_span = 1.0 / (q_start - 1.0);
    for (i, node) in out.tree.nodes.iter().enumerate() {
        if !node.is_leaf() {
            continue;
        }
        if node.is_culled() {
            culled += 1;
            continue;
        }
        let level = max_depth - node.depth as u32;
        let uv_size = 1.0 / (1u64 << node.depth) as f32;
        let uv_origin = [node.ix as f32 * uv_size, node.iy as f32 * uv_size];
        out.patches.push(Patch {
            uv_origin,
            uv_size,
            origin_m: [
                uv_origin[0] * settings.extent_m[0],
                uv_origin[1] * settings.extent_m[1],
            ],
            size_m: frame.node_size_m[node.depth as usize],
            level,
            mip_level: (level + offset).max(finest_ready_mip).min(coarsest_mip),
            morph: out.tree.corner_morph(i as u32, q_start, rcp_span),
            min_z: node.z[0],
            max_z: node.z[1],
        });
    }
    Ok(SelectStats {
        nodes_visited: counts.nodes,
        culled,
        patches: out.patches.len() as u32,
        balance_splits: counts.balance_splits,
        finest_allowed_level,
    })
}

/// The parent projected size (over budget) at which a patch starts morphing toward its parent,
/// `2 / (1 + morph_start_ratio)`.
///
/// A level exists while its parent's projected size `q` exceeds 1, and `q` halves per level
/// (it goes as `1 / distance` for a node facing the camera), so a level spans about `q` in
/// `(1, 2]`, distances `[R, 2R]`. CDLOD morphs over the far end of the distance range, from
/// `R + ratio * R` to `2R`; in `q` that is from `2 / (1 + ratio)` down to 1.
pub fn morph_start_q(settings: &LodSettings) -> f32 {
    2.0 / (1.0 + settings.morph_start_ratio)
}
