//! A solve in pieces: [`GpuSolver::begin`], the editor's queued take, more iterations and
//! polling what the device delivered.

use super::*;

impl GpuSolver {
    /// Takes `sketch`: rasterises it on the GPU (only the stroke geometry goes up), solves the
    /// gradient field and roughness (cold, or warm from their last solutions), assembles the height
    /// problem with its edge differences (cold: `h = 0` then FMG; warm: keeps `h`), relaxes the
    /// heights locally where the residual is large and starts FCG. The heights then need
    /// [`Self::iterate`] until [`Self::residual`] meets the tolerance, and [`Self::publish`] to
    /// show. One round trip: the four queued runs' reports (256 bytes); another take only when a
    /// field needed more iterations than queued.
    pub fn begin(&mut self, sketch: &Sketch, cold: bool) -> Result<BeginReport, GpuError> {
        let (r, wu, field_wu) = loop {
            // FCG starts whatever the residual (a stop at 0): the caller iterates to its own
            // tolerance.
            let (field_wu, height_wu) =
                self.prepare(sketch, cold, Some((0, 0.0, self.params.max_vcycles)))?;
            let r = self.read_take(cold)?;
            if r.fields_done {
                break (r.heights, height_wu, field_wu + r.field_wu);
            }
        };
        self.residual = r.stats.residual;
        self.started = r.started;
        Ok(BeginReport {
            field_work_units: field_wu,
            work_units: wu + r.stats.work_units,
            residual: self.residual,
        })
    }

    /// Queues a take: rasterisation, field solves, height assembly (cold: and FMG), and unless
    /// `heights` is `None` the heights' local relaxation, FCG
    /// start and `heights.0` gated iterations to the tolerance `heights.1`, at most `heights.2` in
    /// all, every FCG run stopped
    /// on the GPU and
    /// its report copied for [`Self::read_take`]. Returns the work units known now (fields' FMG,
    /// heights' FMG); the FCG runs' come with their reports.
    pub(super) fn prepare(
        &mut self,
        sketch: &Sketch,
        cold: bool,
        heights: Option<(u32, f32, u32)>,
    ) -> Result<(f64, f64), GpuError> {
        let grid = self.grid;
        let n = grid.n;
        let [ax, ay] = grid.axis_weights();
        self.started = false;
        self.take_serial += 1;
        let elevation = self.raster.run(sketch, &grid)?;
        self.claim_reports()?;
        let mut field_wu = 0.0;
        let mut wu = 0.0;
        let mut fields = None;
        if !elevation {
            // Empty sketch: every cell hard at the base elevation (the diffusion problem is singular).
            let base = sketch.base_elevation_m as f32;
            let p = FieldProblem {
                n,
                ax,
                ay,
                weight: vec![1.0; n * n],
                value: vec![base; n * n],
                ..Default::default()
            };
            self.heights.upload_problem(&p)?;
            wu += self.heights.fmg()?;
        } else {
            let (w, runs) = self.solve_fields(!cold)?;
            field_wu = w;
            fields = Some(runs);
            // The assembly computes the edge differences from `gx`, `gy` and the band weight.
            self.heights.assemble_on_gpu(None, cold, true, &|_| {})?;
            if cold {
                wu += self.heights.fmg()?;
            }
        }
        if let Some((k, tolerance, cap)) = heights {
            // Local relaxation before FCG, as the CPU: after FMG at its largest residuals; warm at
            // the residuals an edit leaves (the CPU seeds warm starts by the changed constraints,
            // which the GPU does not track).
            let threshold = if cold {
                FMG_SEED_RESIDUAL
            } else {
                WARM_SEED_RESIDUAL
            };
            let raster = &self.raster;
            let scale =
                |enc: &mut wgpu::CommandEncoder| raster.encode_relief(enc, ReliefOf::Heights);
            self.heights.queue_fcg_relaxed(
                cap,
                tolerance,
                threshold,
                SWEEPS,
                Some(k),
                Some((
                    &self.reports[self.newest],
                    HEIGHTS as u64 * QUEUED_REPORT_BYTES,
                )),
                Some(&scale),
            )?;
        }
        self.takes[self.newest] = Some(TakeRuns {
            cold,
            fields,
            heights: heights.and_then(|_| self.heights.queued_run()),
        });
        Ok((field_wu, wu))
    }

    /// The editor's take, without waiting for its reports: as [`Self::begin`] (FCG started
    /// whatever the residual), but the field and height reports are only requested; [`Self::poll`]
    /// reads them once the device delivers them. No wait, unless the device is still on the take
    /// before the last one (whose reports buffer this take reuses), or every stroke lies outside
    /// the map (the rasteriser's value ranges then say whether any elevation constraint exists).
    /// Returns the work units known now (FMG's).
    pub fn take_queued(&mut self, sketch: &Sketch, cold: bool) -> Result<BeginReport, GpuError> {
        let (field_wu, wu) = self.prepare(sketch, cold, Some((0, 0.0, EDITOR_MAX_ITERATIONS)))?;
        let rx = readback::request_map(&self.reports[self.newest], REPORTS_BYTES);
        *self
            .take_pending
            .lock()
            .map_err(|_| GpuError::ProblemMismatch("reports lock poisoned".into()))? =
            Some((rx, cold));
        self.residual = f32::INFINITY;
        self.started = true;
        Ok(BeginReport {
            field_work_units: field_wu,
            work_units: wu,
            residual: self.residual,
        })
    }

    /// Turns to the other reports buffer for a new take. The last take's reports are read if they
    /// arrived (a non-blocking poll), else their mapping is dropped once it completes (the take
    /// they describe is being replaced); the buffer turned to, two takes old, must be unmapped
    /// first: a wait only if the device has not finished that take yet.
    pub(super) fn claim_reports(&mut self) -> Result<(), GpuError> {
        let last = self
            .take_pending
            .lock()
            .map_err(|_| GpuError::ProblemMismatch("reports lock poisoned".into()))?
            .is_some();
        if last {
            self.poll()?;
        }
        self.settle_replaced(true)?;
        let pending = self
            .take_pending
            .lock()
            .map_err(|_| GpuError::ProblemMismatch("reports lock poisoned".into()))?
            .take();
        self.replaced_pending = pending.map(|(rx, _)| rx);
        self.newest = 1 - self.newest;
        Ok(())
    }

    /// Reads a replaced take's reports (in the buffer the newest take does not use) if they
    /// arrived, or after a blocking wait with `wait`, and unmaps that buffer.
    fn settle_replaced(&mut self, wait: bool) -> Result<(), GpuError> {
        let replaced = 1 - self.newest;
        if let Some(rx) = self.replaced_pending.as_ref()
            && let Some(bytes) = readback::finish_map(
                &self.ctx,
                &self.reports[replaced],
                REPORTS_BYTES,
                rx,
                wait,
                "solver reports",
            )?
        {
            self.replaced_pending = None;
            if let Some(take) = self.takes[replaced] {
                self.note_replaced_take(&bytes, take)?;
            }
        }
        Ok(())
    }

    /// Queues `k` more FCG iterations of the heights after [`Self::take_queued`], nothing read
    /// back (their residual comes with a later [`Self::poll`]). Returns the work units they count.
    pub fn queue_iterations(&mut self, k: u32) -> Result<f64, GpuError> {
        if !self.started {
            return Ok(0.0);
        }
        let free = self.iteration_reports.iter().position(|r| r.1.is_none());
        let report_to = free.map(|i| (&self.iteration_reports[i].0, 0));
        let wu = self.heights.queue_more_reporting(k, report_to)?;
        if let Some(i) = free {
            let buffer = &self.iteration_reports[i].0;
            self.iteration_reports[i].1 = Some((
                readback::request_map(buffer, QUEUED_REPORT_BYTES),
                self.take_serial,
            ));
        }
        Ok(wu)
    }

    /// What the device has delivered since the last poll (a non-blocking poll): the take's
    /// reports and the newest residual of the heights. Never waits.
    pub fn poll(&mut self) -> Result<LiveStatus, GpuError> {
        self.ctx
            .poll_nonblocking()
            .map_err(|e| GpuError::Readback {
                what: "solver reports".into(),
                message: e.to_string(),
            })?;
        let mut status = LiveStatus::default();
        self.settle_replaced(false)?;
        let pending = self
            .take_pending
            .lock()
            .map_err(|_| GpuError::ProblemMismatch("reports lock poisoned".into()))?
            .take();
        if let Some((rx, cold)) = pending {
            match readback::finish_map(
                &self.ctx,
                &self.reports[self.newest],
                REPORTS_BYTES,
                &rx,
                false,
                "solver reports",
            )? {
                Some(bytes) => {
                    let r = self.take_reports(&bytes, cold)?;
                    status.retake = !r.fields_done;
                    status.late_field_work_units = r.field_wu;
                    status.late_work_units = r.field_wu + r.heights.stats.work_units;
                    status.residual = Some(r.heights.stats.residual);
                }
                None => {
                    *self
                        .take_pending
                        .lock()
                        .map_err(|_| GpuError::ProblemMismatch("reports lock poisoned".into()))? =
                        Some((rx, cold));
                }
            }
        }
        // The newest arrived iteration report of this take wins (most iterations run); those of
        // a replaced take are unmapped and ignored.
        let mut newest: Option<(u32, f32)> = None;
        for i in 0..self.iteration_reports.len() {
            let Some((rx, serial)) = self.iteration_reports[i].1.as_ref() else {
                continue;
            };
            let current = *serial == self.take_serial;
            let buffer = &self.iteration_reports[i].0;
            if let Some(bytes) = readback::finish_map(
                &self.ctx,
                buffer,
                QUEUED_REPORT_BYTES,
                rx,
                false,
                "iteration report",
            )? {
                self.iteration_reports[i].1 = None;
                let (residual, iterations) = self.heights.residual_of(&bytes);
                if current && newest.is_none_or(|(it, _)| iterations >= it) {
                    newest = Some((iterations, residual));
                }
            }
        }
        if let Some((_, residual)) = newest {
            status.residual = Some(residual);
        }
        if let Some(r) = status.residual {
            self.residual = r;
        }
        Ok(status)
    }
}
