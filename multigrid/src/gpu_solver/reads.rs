//! Reading the published heights, their mips and texels, and the fields' solutions back.

use super::*;

impl GpuSolver {
    /// Reads texels of mip `level` (`(x, y)` in texel coordinates of that level, row 0 = south): one
    /// 4-byte copy each (the editor's probes).
    pub fn read_texels(&self, level: u32, texels: &[[u32; 2]]) -> Result<Vec<f32>, GpuError> {
        Ok(self
            .read_texels_with(level, texels, None)?
            .into_iter()
            .next()
            .unwrap_or_default())
    }

    /// [`Self::read_texels`], and in the same read-back (one wait) the texels of `other`, another
    /// texture on this device (the editor's detail amplitude). Returns the heights' values, then
    /// `other`'s.
    pub fn read_texels_with(
        &self,
        level: u32,
        texels: &[[u32; 2]],
        other: Option<crate::gpu::TexelSet<'_>>,
    ) -> Result<Vec<Vec<f32>>, GpuError> {
        let side = (self.grid.n >> level) as u32;
        if level as usize >= self.mips.mip_count() {
            return Err(GpuError::BadLevel {
                level: level as usize,
                levels: self.mips.mip_count(),
            });
        }
        if let Some(t) = texels.iter().find(|t| t[0] >= side || t[1] >= side) {
            return Err(GpuError::ProblemMismatch(format!(
                "texel {t:?} outside mip {level} of side {side}"
            )));
        }
        let mut sets = vec![crate::gpu::TexelSet {
            texture: self.mips.texture(),
            level,
            texels,
        }];
        sets.extend(other);
        crate::gpu::read_texel_sets(&self.ctx, &sets)
    }

    /// Reads the level-0 heights back (row 0 = south).
    pub fn read_heights(&self) -> Result<Vec<f32>, GpuError> {
        self.heights.read_solution()
    }

    /// Relief of the height constraints.
    pub fn relief_m(&self) -> f32 {
        self.heights.relief()
    }

    /// Reads the min/max pyramid (a few KB).
    pub fn min_max(&self) -> Result<Vec<MinMaxLevel>, GpuError> {
        self.mips.read_min_max()
    }

    /// The heightmap texture (R32Float, full mip chain; mip 0 is the heights' `h`, see
    /// [`Self::publish`]).
    pub fn texture(&self) -> &wgpu::Texture {
        self.mips.texture()
    }

    /// Reads the two gradient components (level 1, the last solutions) back (tests).
    pub fn read_gradient(&self) -> Result<(Vec<f32>, Vec<f32>), GpuError> {
        let cells = (self.grid.n * self.grid.n / 4) as u64;
        self.ctx.checked("multigrid.read_gradient", || {
            Ok((
                crate::gpu::read_f32(&self.ctx, &self.gx, 0, cells, "gradient x")?,
                crate::gpu::read_f32(&self.ctx, &self.gy, 0, cells, "gradient y")?,
            ))
        })
    }

    /// The roughness's last solution (level 2, row 0 = south, f32) as `(buffer, byte offset, bytes)`,
    /// for passes that read it in place (the editor's detail amplitude).
    pub fn roughness_buffer(&self) -> Result<(wgpu::Buffer, u64, u64), GpuError> {
        let s = self.rough.h_buffer()?;
        Ok((s.buffer.clone(), s.offset, s.size))
    }

    /// Level `level` (1 ..= the coarsest mip) of the mips' constraint pyramid (per cell
    /// `vec2(count of hard level-0 cells, sum of their E)`, side n >> level) as `(buffer, byte
    /// offset, bytes)`: valid from [`Self::publish`] to the next [`Self::begin`] (it lives in the
    /// heights' `weight`). `None` for level 0 or a level past the chain.
    pub fn hard_counts(&self, level: u32) -> Option<(wgpu::Buffer, u64, u64)> {
        let n = self.grid.n;
        let k = (level as usize).checked_sub(1)?;
        let side = n.checked_shr(level).filter(|s| *s > 0)?;
        let start = *crate::gpu::mips::constraint_offsets(n).get(k)? as u64 * 8;
        let w = &self.heights.bufs.weight;
        Some((w.buffer.clone(), w.offset + start, (side * side * 8) as u64))
    }

    /// Reads the roughness (level 2, the last solution) back (tests).
    pub fn read_roughness(&self) -> Result<Vec<f32>, GpuError> {
        self.rough.read_solution()
    }

    /// Rasterises and assembles `sketch` as a warm [`Self::begin`] does, without starting FCG, and
    /// reads the level-0 height operator back: the diagonal (0 on hard cells) and the right-hand
    /// side `f`, into which the edge differences computed on the GPU enter (tests). `f` lives in
    /// FCG's `p` (`Buffers`), which FCG's start overwrites: the solver needs a [`Self::begin`]
    /// before it iterates again.
    pub fn read_height_operator(
        &mut self,
        sketch: &Sketch,
    ) -> Result<(Vec<f32>, Vec<f32>), GpuError> {
        self.prepare(sketch, false, None)?;
        Ok((self.heights.read_diag()?, self.heights.read_rhs(0)?))
    }

    /// Reads mip level `k` of the heightmap texture back (tests).
    pub fn read_mip(&self, k: usize) -> Result<Vec<f32>, GpuError> {
        self.mips.read_mip(k)
    }
}
