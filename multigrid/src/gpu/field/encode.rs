//! Recording plans into command buffers: clears, copies and the dispatches of each pass.

use super::*;

impl GpuFieldSolver {
    pub(super) fn submit(&self, steps: &[Step], label: &str) {
        self.submit_all(&[steps], label);
    }

    /// Encodes `plans` one after the other into one command buffer and submits it.
    pub(super) fn submit_all(&self, plans: &[&[Step]], label: &str) {
        let mut enc = self
            .ctx
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some(label) });
        for steps in plans {
            self.encode(&mut enc, steps, label);
        }
        self.ctx.submit([enc.finish()]);
    }

    /// Records `op`, from the gate's table for the gate passes.
    pub(super) fn dispatch(&self, pass: &mut wgpu::ComputePass<'_>, op: &Op) {
        match op {
            Op::Gate { .. } | Op::SpikeGate => self.gate.table.dispatch(&self.pipelines, pass, op),
            _ => self.table.dispatch(&self.pipelines, pass, op),
        }
    }

    /// Encodes a plan: runs of dispatches share one compute pass; clears and copies go between passes.
    pub(super) fn encode(&self, enc: &mut wgpu::CommandEncoder, steps: &[Step], label: &str) {
        let mut i = 0;
        while i < steps.len() {
            match steps[i] {
                Step::ClearU { level } => {
                    self.bufs.u[level - 1].clear(enc);
                    i += 1;
                }
                Step::ClearZ => {
                    self.bufs.z.clear(enc);
                    i += 1;
                }
                Step::CopyStatus => {
                    enc.copy_buffer_to_buffer(&self.bufs.scalars, 0, &self.status, 0, STATUS_BYTES);
                    i += 1;
                }
                // Runs of dispatches, gated or not, share one compute pass.
                Step::Dispatch(_) | Step::Gated(_) => {
                    let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                        label: Some(label),
                        timestamp_writes: None,
                    });
                    while let Some(Step::Gated(op) | Step::Dispatch(op)) = steps.get(i) {
                        match steps[i] {
                            Step::Gated(_) if !matches!(op, Op::Gate { .. } | Op::SpikeGate) => {
                                self.table.dispatch_indirect(
                                    &self.pipelines,
                                    &mut pass,
                                    op,
                                    &self.gate.args,
                                    self.gate.offset(*op, self.n),
                                )
                            }
                            // Over the windows' box only (`relax_mask` mode 2 wrote its size).
                            Step::Dispatch(
                                Op::RelaxTiles { .. } | Op::SpikeRelax { .. } | Op::SpikeUpdate,
                            ) => self.table.dispatch_indirect(
                                &self.pipelines,
                                &mut pass,
                                op,
                                &self.bufs.relax_box,
                                RELAX_ARGS_OFFSET,
                            ),
                            _ => self.dispatch(&mut pass, op),
                        }
                        i += 1;
                    }
                }
                Step::CopyScalars => {
                    enc.copy_buffer_to_buffer(
                        &self.bufs.scalars,
                        0,
                        &self.status,
                        0,
                        STATUS_STAGING_BYTES,
                    );
                    i += 1;
                }
                Step::CopySpike => {
                    enc.copy_buffer_to_buffer(
                        &self.bufs.scalars,
                        4 * (SPIKE_WORDS + SPIKE_CELLS) as u64,
                        &self.status,
                        STATUS_BYTES,
                        12,
                    );
                    i += 1;
                }
                Step::CopyRelaxCells => {
                    enc.copy_buffer_to_buffer(
                        &self.bufs.scalars,
                        RELAX_CELLS_OFFSET,
                        &self.status,
                        STATUS_BYTES,
                        4,
                    );
                    enc.copy_buffer_to_buffer(
                        &self.bufs.scalars,
                        RELAX_GROUPS_OFFSET,
                        &self.status,
                        STATUS_BYTES + 4,
                        4,
                    );
                    i += 1;
                }
            }
        }
    }
}
