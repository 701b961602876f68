//! FCG queued whole with its stop test on the GPU, and reading what it did.

use super::*;

impl GpuFieldSolver {
    /// [`Self::fcg_relaxed`] queued whole, with its stop test on the GPU (`fcg_gate.wgsl`) and
    /// nothing read back: the local relaxation, the residual, the first direction unless the
    /// tolerance already holds, and `iterations` gated iterations of at most `max_iters` in all
    /// (more with [`Self::queue_more`]); with `iterations == None` the relaxation alone. The passes that run, and so the result, are those of
    /// [`Self::fcg_relaxed`]; [`Self::queued_report`] reads what happened. `relief_pass` records
    /// the pass that scales the limits by the problem's relief on the GPU (required when the
    /// assembly left the relief to the GPU; ignored otherwise).
    #[allow(clippy::too_many_arguments)]
    pub fn queue_fcg_relaxed(
        &mut self,
        max_iters: u32,
        tolerance: f32,
        threshold: f32,
        sweeps: usize,
        iterations: Option<u32>,
        report_to: Option<(&wgpu::Buffer, u64)>,
        relief_pass: Option<&dyn Fn(&mut wgpu::CommandEncoder)>,
    ) -> Result<(), GpuError> {
        self.require_problem()?;
        let on_gpu = match (self.relief_on_gpu, relief_pass) {
            (true, None) => return Err(relief_unknown()),
            (true, Some(pass)) => Some(pass),
            (false, _) => None,
        };
        // Normalised limits, scaled on the GPU by a relief computed there, or here.
        let to_rmax = if on_gpu.is_some() {
            1.0
        } else {
            self.rmax_per_residual()
        };
        let scalars = Scalars {
            relax_limit: threshold * to_rmax,
            stop_rmax: tolerance * to_rmax,
            iterations_left: max_iters,
            relief: if on_gpu.is_some() { 0.0 } else { self.relief },
            ..Scalars::default()
        };
        let ctx = self.ctx.clone();
        ctx.checked("multigrid.fcg.queued", || {
            self.ctx
                .queue
                .write_buffer(&self.bufs.scalars, 0, bytemuck::bytes_of(&scalars));
            self.ctx.count_up(std::mem::size_of::<Scalars>() as u64);
            let mut enc = self
                .ctx
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                    label: Some("multigrid.fcg.queued"),
                });
            if let Some(pass) = on_gpu {
                pass(&mut enc);
            }
            let steps = plan::fcg_queued(
                &self.shape,
                sweeps,
                iterations.unwrap_or(0),
                iterations.is_some(),
            );
            self.encode(&mut enc, &steps, "multigrid.fcg.queued");
            if let Some((dst, offset)) = report_to {
                enc.copy_buffer_to_buffer(&self.bufs.scalars, 0, dst, offset, STATUS_STAGING_BYTES);
            }
            self.ctx.submit([enc.finish()]);
            Ok(())
        })?;
        self.fcg_state = FcgState::Idle;
        self.queued = Some(Queued {
            sweeps,
            iterations: iterations.unwrap_or(0),
            start: iterations.is_some(),
            relax_counted: false,
            direction_counted: false,
            iterations_counted: 0,
            spikes_counted: [0; 2],
        });
        self.spike_seen = [0; 3];
        Ok(())
    }

    /// Queues `iterations` more gated iterations of the run [`Self::queue_fcg_relaxed`] queued
    /// (they do nothing once the gate has stopped it).
    pub fn queue_more(&mut self, iterations: u32) -> Result<(), GpuError> {
        self.queue_more_reporting(iterations, None).map(|_| ())
    }

    /// [`Self::queue_more`], the scalars also copied to `report_to` (buffer, byte offset) after
    /// them. Returns the work units the queued iterations count if they all run.
    pub(crate) fn queue_more_reporting(
        &mut self,
        iterations: u32,
        report_to: Option<(&wgpu::Buffer, u64)>,
    ) -> Result<f64, GpuError> {
        let Some(q) = self.queued.as_mut().filter(|q| q.start) else {
            return Err(GpuError::ProblemMismatch(
                "queue_more without a queued FCG start".into(),
            ));
        };
        let first = q.iterations == 0;
        let steps = plan::fcg_queued_iterations(&self.shape, first, iterations);
        q.iterations += iterations;
        let uncounted = (q.iterations_counted, q.iterations);
        if report_to.is_some() {
            // Only the residual is read from these reports: the bytes count as if all ran.
            q.iterations_counted = q.iterations;
            self.ctx
                .count_moved(&self.gate_iteration_bytes(uncounted.0, uncounted.1));
        }
        let wu = plan::work_units(&plan::gated_as_dispatches(&steps));
        let ctx = self.ctx.clone();
        ctx.checked("multigrid.fcg.queued", || {
            let mut enc = self
                .ctx
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                    label: Some("multigrid.fcg.queued"),
                });
            self.encode(&mut enc, &steps, "multigrid.fcg.queued");
            if let Some((dst, offset)) = report_to {
                enc.copy_buffer_to_buffer(&self.bufs.scalars, 0, dst, offset, STATUS_STAGING_BYTES);
            }
            self.ctx.submit([enc.finish()]);
            Ok(())
        })?;
        Ok(wu)
    }

    /// Normalised residual and iterations run of a copy of the scalar block (`report_to` of the
    /// queued runs), without touching the run's state (the editor's non-blocking reads).
    pub(crate) fn residual_of(&self, bytes: &[u8]) -> (f32, u32) {
        let w: [u32; 16] = words_of(bytes);
        (f32::from_bits(w[0]) * self.scale_of(w[15]), w[10])
    }

    /// The report of the queued run from a copy of its scalar block ([`Self::queue_fcg_relaxed`]'s
    /// `report_to`, [`QUEUED_REPORT_BYTES`] bytes).
    pub(crate) fn report_of(&mut self, bytes: &[u8]) -> Result<QueuedReport, GpuError> {
        self.report_from(report_words(bytes)?)
    }

    /// Copies the queued run's scalars to the staging buffer and maps it (the read completes at the
    /// next device poll: [`Self::queued_report`] after one wait, shared by every solver polled).
    pub(crate) fn request_report(&self) -> Result<(), GpuError> {
        if self.queued.is_none() {
            return Err(GpuError::ProblemMismatch(
                "no queued FCG run to report".into(),
            ));
        }
        let mut pending = self
            .pending
            .lock()
            .map_err(|_| GpuError::ProblemMismatch("status staging lock poisoned".into()))?;
        if pending.is_none() {
            *pending = Some(readback::request_map(&self.status, STATUS_STAGING_BYTES));
        }
        Ok(())
    }

    /// [`Self::queued_report`] if the report [`Self::request_report`] asked for has arrived (after a
    /// non-blocking poll of the device), else `None`: never waits.
    pub fn try_queued_report(&mut self) -> Result<Option<QueuedReport>, GpuError> {
        self.request_report()?;
        self.ctx
            .poll_nonblocking()
            .map_err(|e| GpuError::Readback {
                what: "multigrid.status".into(),
                message: e.to_string(),
            })?;
        let words = self.take_pending(false)?;
        Ok(match words {
            Some(w) => Some(self.report_from(w)?),
            None => None,
        })
    }

    /// The status words of a requested mapping (`wait`: blocking if not there yet), `None` when
    /// none was requested or (without `wait`) it has not arrived.
    pub(super) fn take_pending(&self, wait: bool) -> Result<Option<[u32; 32]>, GpuError> {
        let mut pending = self
            .pending
            .lock()
            .map_err(|_| GpuError::ProblemMismatch("status staging lock poisoned".into()))?;
        let Some(rx) = pending.as_ref() else {
            return Ok(None);
        };
        let Some(bytes) = readback::finish_map(
            &self.ctx,
            &self.status,
            STATUS_STAGING_BYTES,
            rx,
            wait,
            "multigrid.status",
        )?
        else {
            return Ok(None);
        };
        *pending = None;
        Ok(Some(words_of(&bytes)))
    }

    /// What the queued run did so far: its scalars after the last queued pass (one blocking wait
    /// unless [`Self::request_report`] was polled already). The run stays queued: more iterations
    /// may follow ([`Self::queue_more`]) unless the report says it stopped.
    pub fn queued_report(&mut self) -> Result<QueuedReport, GpuError> {
        let words = match self.take_pending(true)? {
            Some(w) => w,
            None => self.read_words::<32>()?,
        };
        self.report_from(words)
    }

    /// The run [`Self::queue_fcg_relaxed`] queued last (with the iterations queued so far).
    pub(crate) fn queued_run(&self) -> Option<Queued> {
        self.queued
    }

    /// The report of an earlier run `q` (one a later run replaced) from a copy of its scalar
    /// block: counts the bytes its passes moved, and leaves the current run's state alone.
    pub(crate) fn earlier_report(&self, bytes: &[u8], q: Queued) -> Result<QueuedReport, GpuError> {
        Ok(self.run_report(report_words(bytes)?, q).0)
    }

    /// The report of the queued run from its status words.
    pub(super) fn report_from(&mut self, words: [u32; 32]) -> Result<QueuedReport, GpuError> {
        let Some(q) = self.queued else {
            return Err(GpuError::ProblemMismatch(
                "no queued FCG run to report".into(),
            ));
        };
        self.learn_relief(words[15]);
        let (report, state, counted) = self.run_report(words, q);
        self.queued = Some(counted);
        self.fcg_state = state;
        // FCG iterations driven by the CPU may follow: theirs are the relaxations beyond these.
        self.spike_seen = [
            words[SPIKE_WORDS + SPIKE_CELLS],
            words[SPIKE_WORDS + SPIKE_GROUPS],
            words[SPIKE_WORDS + SPIKE_RUNS],
        ];
        Ok(report)
    }

    /// Bytes of gated iterations `from..to` of a run (the first iteration's passes differ).
    fn gate_iteration_bytes(&self, from: u32, to: u32) -> Vec<(Kernel, u64)> {
        (from..to)
            .flat_map(|i| self.gate.bytes[if i == 0 { 1 } else { 2 }].iter().copied())
            .collect()
    }

    /// What run `q` did by its status words `words`, the FCG state it leaves, and `q` with what
    /// is now counted: counts the bytes of its relaxation and gated passes not counted already.
    fn run_report(&self, words: [u32; 32], q: Queued) -> (QueuedReport, FcgState, Queued) {
        let rmax = f32::from_bits(words[0]);
        let status = words[1];
        let stop_rmax = f32::from_bits(words[7]);
        let cells = words[9] as usize;
        let iterations = words[10];
        let left = words[11];
        let rmax_start = f32::from_bits(words[12]);
        let scale = self.scale_of(words[15]);
        if !q.relax_counted {
            self.ctx
                .count_moved(&self.relax_bytes(words[14], q.sweeps, false));
        }
        // The first direction ran when the first gate let FCG start (it zeroes `left` otherwise).
        let direction = q.start && (iterations > 0 || left > 0);
        let n2 = self.n * self.n;
        let relaxed = if cells * 4 > n2 {
            0.0
        } else {
            (cells * q.sweeps) as f64 / n2 as f64
        };
        let mut wu = relaxed;
        let mut counted = Queued {
            relax_counted: true,
            ..q
        };
        if direction {
            wu += plan::work_units(&self.plans.fcg_first_direction);
            if !q.direction_counted {
                self.ctx.count_moved(&self.gate.bytes[0]);
                counted.direction_counted = true;
            }
        }
        if iterations > 0 {
            wu += plan::work_units(&self.plans.fcg_first)
                + (iterations - 1) as f64 * plan::work_units(&self.plans.fcg_next);
        }
        if iterations > q.iterations_counted {
            self.ctx
                .count_moved(&self.gate_iteration_bytes(q.iterations_counted, iterations));
            counted.iterations_counted = iterations;
        }
        // The stop-test relaxations after the iterations (`plan::spike_relaxation`).
        wu += self.spike_work_units(words[SPIKE_WORDS + SPIKE_CELLS]);
        let spikes = [
            words[SPIKE_WORDS + SPIKE_RUNS],
            words[SPIKE_WORDS + SPIKE_GROUPS],
        ];
        if spikes != q.spikes_counted {
            let [runs, groups] =
                std::array::from_fn(|k| spikes[k].saturating_sub(q.spikes_counted[k]));
            self.ctx.count_moved(&self.spike_bytes(runs, groups));
            counted.spikes_counted = spikes;
        }
        let state = match (iterations, direction) {
            (0, false) => FcgState::Idle,
            (0, true) => FcgState::Started,
            _ => FcgState::Iterating,
        };
        let residual = rmax * scale;
        let report = QueuedReport {
            stats: CycleStats {
                work_units: wu,
                residual,
            },
            iterations,
            residual_start: if direction {
                rmax_start * scale
            } else {
                residual
            },
            started: direction,
            stopped: rmax <= stop_rmax
                || (q.start && (status != 0 || left == 0 || iterations < q.iterations)),
        };
        (report, state, counted)
    }
}

/// The status words of a copy of a run's scalar block ([`QUEUED_REPORT_BYTES`] bytes at least).
fn report_words(bytes: &[u8]) -> Result<[u32; 32], GpuError> {
    if (bytes.len() as u64) < STATUS_STAGING_BYTES {
        return Err(GpuError::ProblemMismatch(format!(
            "{} bytes for a {STATUS_STAGING_BYTES}-byte FCG report",
            bytes.len()
        )));
    }
    Ok(words_of(bytes))
}
