//! Reading a solver's levels, right-hand sides and stencils back.

use super::*;

impl GpuFieldSolver {
    /// The level-0 solution `h` (row 0 = south).
    pub fn read_solution(&self) -> Result<Vec<f32>, GpuError> {
        self.read_level(0)
    }

    /// Level-k unknowns (k = 0: `h`; k >= 1: `u_k`), row 0 = south.
    pub fn read_level(&self, k: usize) -> Result<Vec<f32>, GpuError> {
        if let (0, HStore::Texture { texture, .. }) = (k, &self.bufs.h) {
            return self.ctx.checked("multigrid.read_level", || {
                readback::read_texture_r32(&self.ctx, texture, 0, self.n as u32, "h")
            });
        }
        let (buf, first) = match (k, self.bufs.h.buffer()) {
            (0, Some(h)) => (&h.buffer, h.first_f32()),
            (k, _) if k >= 1 && k < self.levels() => {
                (&self.bufs.u[k - 1].buffer, self.bufs.u[k - 1].first_f32())
            }
            _ => {
                return Err(GpuError::BadLevel {
                    level: k,
                    levels: self.levels(),
                });
            }
        };
        let side = (self.n >> k) as u64;
        self.ctx.checked("multigrid.read_level", || {
            readback::read_f32(&self.ctx, buf, first, side * side, "level unknowns")
        })
    }

    /// Level-k right-hand side (k = 0: `f`; k >= 1: `f_k` as last used by a cycle or FMG).
    pub fn read_rhs(&self, k: usize) -> Result<Vec<f32>, GpuError> {
        let (buf, first) = match k {
            0 => (&self.bufs.f.buffer, self.bufs.f.first_f32()),
            k if k < self.levels() => {
                (&self.bufs.fc[k - 1].buffer, self.bufs.fc[k - 1].first_f32())
            }
            _ => {
                return Err(GpuError::BadLevel {
                    level: k,
                    levels: self.levels(),
                });
            }
        };
        let side = (self.n >> k) as u64;
        self.ctx.checked("multigrid.read_rhs", || {
            readback::read_f32(&self.ctx, buf, first, side * side, "right-hand side")
        })
    }

    /// The level-0 diagonal (0 on hard cells) as assembled on the GPU.
    pub fn read_diag(&self) -> Result<Vec<f32>, GpuError> {
        let cells = (self.n * self.n) as u64;
        self.ctx.checked("multigrid.read_diag", || {
            readback::read_f32(
                &self.ctx,
                &self.bufs.diag.buffer,
                self.bufs.diag.first_f32(),
                cells,
                "diag",
            )
        })
    }

    /// The Galerkin stencils of level `k >= 1`, `c[(oy + 1) * 3 + (ox + 1)]`: for `k >= 2` decoded
    /// from the records the GPU keeps ([`unpack_stencils`]); level 1's, which nothing stores, as the
    /// level-1 passes compute them from the level-0 diagonal (`stencils_level1.wgsl` writes them
    /// out; all zero for an inactive cell; an error if the centre-only activity test the
    /// prolongation uses disagrees with the full evaluation somewhere).
    pub fn read_stencils(&self, k: usize) -> Result<Vec<[f32; 9]>, GpuError> {
        if k == 0 || k >= self.levels() {
            return Err(GpuError::BadLevel {
                level: k,
                levels: self.levels(),
            });
        }
        if k == 1 {
            return self.read_level1_stencils();
        }
        let side = (self.n >> k) as u64;
        let bytes = self.ctx.checked("multigrid.read_stencils", || {
            readback::read_bytes(
                &self.ctx,
                &self.bufs.stencil[k - 2],
                0,
                side * side * STENCIL_BYTES,
                "stencils",
            )
        })?;
        let words: Vec<u32> = bytes
            .chunks_exact(4)
            .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect();
        Ok(unpack_stencils(&words))
    }

    pub(super) fn read_level1_stencils(&self) -> Result<Vec<[f32; 9]>, GpuError> {
        let side = self.n / 2;
        let values = (10 * side * side) as u64;
        let ctx = &self.ctx;
        let flat = ctx.checked("multigrid.read_stencils.l1", || {
            let out = ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("multigrid.stencils_level1"),
                size: 4 * values,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            });
            let pipelines = Pipelines::new(ctx, &[Kernel::StencilsLevel1]);
            let spec = PassSpec {
                key: (),
                kernel: Kernel::StencilsLevel1,
                params: Params {
                    n: side as u32,
                    ax: self.ax,
                    ay: self.ay,
                    threshold: INACTIVE_REL * (2.0 * self.ax + 2.0 * self.ay),
                    ..Params::default()
                },
                resources: vec![Res::Slice(&self.bufs.diag), Res::Buffer(&out)],
                workgroups: plan::groups_2d(side, side),
                label: "multigrid.stencils_level1".into(),
            };
            let table = PassTable::new(ctx, &pipelines, "multigrid.stencils_level1", vec![spec]);
            let mut enc = ctx
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                    label: Some("multigrid.stencils_level1"),
                });
            {
                let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some("multigrid.stencils_level1"),
                    timestamp_writes: None,
                });
                table.dispatch(&pipelines, &mut pass, &());
            }
            ctx.submit([enc.finish()]);
            readback::read_f32(ctx, &out, 0, values, "level-1 stencils")
        })?;
        if let Some(cell) = flat
            .chunks_exact(10)
            .position(|c| (c[4] != 0.0) != (c[9] != 0.0))
        {
            return Err(GpuError::ProblemMismatch(format!(
                "level-1 cell {cell}: the centre-only activity test disagrees with the stencil"
            )));
        }
        Ok(flat
            .chunks_exact(10)
            .map(|c| std::array::from_fn(|k| c[k]))
            .collect())
    }
}

/// The 9-point stencils `c[(oy + 1) * 3 + (ox + 1)]` from the records of
/// `shaders/shared/stencil.wgsl` (`STENCIL_WORDS` words per cell), decoded as the passes decode
/// them: the off-centre coefficients are 16-bit snorm (`unpack2x16snorm`) times the cell's scale,
/// the centre is the row sum minus them.
pub fn unpack_stencils(words: &[u32]) -> Vec<[f32; 9]> {
    words
        .chunks_exact(STENCIL_WORDS)
        .map(|w| {
            let scale = f32::from_bits(w[5]);
            let pair = |x: u32| [x as u16, (x >> 16) as u16].map(|h| snorm(h) * scale);
            let ([c0, c1], [c2, c3]) = (pair(w[0]), pair(w[1]));
            let ([c5, c6], [c7, c8]) = (pair(w[2]), pair(w[3]));
            let off = ((c0 + c1) + (c2 + c3)) + ((c5 + c6) + (c7 + c8));
            [c0, c1, c2, c3, f32::from_bits(w[4]) - off, c5, c6, c7, c8]
        })
        .collect()
}

/// `unpack2x16snorm` of one half: `max(v / 32767, -1)` for the 16 bits `v` as a signed integer.
pub(super) fn snorm(v: u16) -> f32 {
    (f32::from(v as i16) / 32767.0).max(-1.0)
}
