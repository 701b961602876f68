//! One frame: script events, fly movement, solver step within the budget, uploads of the changed mip
//! rows, quadtree selection, drawing (terrain, strokes, interface), screenshot and frame log.

use std::time::Instant;

use glam::{Vec2, Vec3};
use terrasketch_sketch::{StrokeKind, to_json};

use super::render::{LineVertex, globals};
use super::session::{FrameRecord, digest, event_name};
use super::state::Editor;
use super::tools::stroke_screen;
use super::ui;

impl Editor {
    /// Runs one frame: the script's events, the solver's step, uploads, the quadtree's selection,
    /// drawing, the frame log.
    pub fn frame(&mut self) {
        if self.done || self.device_was_lost() {
            return;
        }
        let t0 = Instant::now();
        let dt = self.last_frame.elapsed().as_secs_f32().min(0.1);
        self.last_frame = t0;
        let Some(names) = self.play_script() else {
            self.done = true;
            return;
        };
        self.view.fly_step(dt);
        if self.doc.live_edit_pending() && !self.gfx.egui_ctx.egui_is_using_pointer() {
            self.commit_attributes();
        }
        // The realism pass's result (if it ended) and which terrain is shown.
        self.poll_refine();
        self.sync_refined();
        let solver_ms = self.step_terrain();
        let mut bytes_up = self.upload_terrain();
        // Probes given in pixels become world points on the first frame with a terrain.
        self.place_pixel_probes();
        let (patches, scene_bytes) = self.prepare_scene();
        bytes_up += scene_bytes;
        // Probes (replay log): on the GPU, four texels each are read back.
        let probe_heights_m = self.probe_heights();
        let (up, down) = self.update_status(patches, bytes_up);
        bytes_up += up;
        self.draw_frame();
        if let Some(msg) = self.autosave.tick(&self.doc.sketch, self.doc.dirty) {
            self.error(msg);
        }
        let ms = t0.elapsed().as_secs_f64() * 1e3;
        self.status.frame_ms = ms;
        self.log_frame(
            (ms, solver_ms),
            patches,
            (bytes_up, down),
            names,
            probe_heights_m,
        );
        self.errors.clear();
        self.warnings.clear();
        self.frame_no += 1;
    }

    /// True (and the editor ends, keeping the work in the recovery file) once the device is lost:
    /// nothing can be drawn any more.
    fn device_was_lost(&mut self) -> bool {
        let Some(why) = self.gfx.gpu.take_lost() else {
            return false;
        };
        self.device_lost = true;
        let kept = match self.autosave.save_now(&self.doc.sketch) {
            Ok(p) => format!("the sketch was saved to the recovery file {}", p.display()),
            Err(e) => format!("the sketch could not be saved for recovery: {e}"),
        };
        self.result = Err(anyhow::anyhow!("the GPU device was lost ({why}); {kept}"));
        self.done = true;
        true
    }

    /// Applies this frame's replay events; returns their names, or None when the script has ended.
    fn play_script(&mut self) -> Option<Vec<String>> {
        let mut names = Vec::new();
        let Some(r) = self.replay.as_mut() else {
            return Some(names);
        };
        let script = r.player.next_frame(
            self.view.pointer.to_array(),
            self.terrain.settled(),
            self.refine.running(),
        );
        if script.finished {
            return None;
        }
        for e in script.events {
            names.push(event_name(&e));
            self.replay_event(e);
        }
        Some(names)
    }

    /// The solver's step within the budget; returns its wall time, ms.
    fn step_terrain(&mut self) -> f64 {
        self.terrain.set_pointer_held(self.view.left_down);
        self.terrain
            .set_detail(self.view.options.detail, self.doc.sketch.seed);
        let t_solver = Instant::now();
        self.terrain.step(&self.doc.sketch, self.budget);
        let solver_ms = t_solver.elapsed().as_secs_f64() * 1e3;
        if let Some(why) = self.terrain.fallback.take() {
            self.error(why);
        }
        // The renderer reads the GPU solver's texture, or its own one the CPU solver's rows go to.
        if self.gfx.scene.external_heightmap() != self.terrain.gpu_texture().is_some() {
            self.gfx
                .scene
                .use_heightmap(&self.gfx.gpu.device, self.terrain.gpu_texture());
        }
        self.status.backend = self.terrain.backend_name().to_string();
        solver_ms
    }

    /// Only the changed rows of the ready mips go up (CPU solver or refined layer), the constraint
    /// overlay's changed rows, the detail; returns bytes sent.
    fn upload_terrain(&mut self) -> u64 {
        let mut bytes_up = 0u64;
        if let Some(k0) = self
            .terrain
            .finest_ready()
            .filter(|_| !self.terrain.display_held())
        {
            for k in k0 as usize..self.terrain.grid.mip_levels() {
                if let Some(rows) = self.terrain.take_changed_rows(k) {
                    bytes_up += self.gfx.scene.upload_rows(
                        &self.gfx.gpu.queue,
                        k as u32,
                        self.terrain.mip(k),
                        rows,
                    );
                }
            }
        }
        if self.view.options.constraints
            && let Some(rows) = self.overlay_rows.take()
        {
            let w = self.terrain.constraint_weights(&self.doc.sketch);
            bytes_up += self
                .gfx
                .scene
                .upload_constraint_rows(&self.gfx.gpu.queue, w, rows);
        }
        bytes_up += self
            .terrain
            .upload_detail(&self.gfx.scene, &self.gfx.gpu.queue);
        self.terrain
            .run_detail_gpu(self.gfx.scene.amplitude_texture());
        bytes_up
    }

    /// The quadtree's selection, the stroke lines and the uniforms; returns patches and bytes sent.
    fn prepare_scene(&mut self) -> (usize, u64) {
        let proj = self.projection();
        let mut patches = 0;
        if let Some(pyr) = self.terrain.shown_pyramid() {
            let finest = self.terrain.finest_ready();
            match self
                .gfx
                .select_patches(pyr, &proj, finest, self.view.options.pixel_budget)
            {
                Ok(n) => patches = n,
                Err(e) => self.errors.push(format!("{e}")),
            }
        }
        let lines = if self.view.options.strokes {
            self.stroke_lines(&proj)
        } else {
            Vec::new()
        };
        let z = self.terrain.z_range();
        let g = globals(
            proj.clip_from_world(),
            proj.eye_m,
            [
                self.doc.sketch.extent_m[0] as f32,
                self.doc.sketch.extent_m[1] as f32,
            ],
            self.gfx.scene.side,
            self.gfx.scene.leaf_cells(),
            z,
            self.view.options.flags() & if self.terrain.detail_shown() { !0 } else { !16 },
            self.doc.sketch.seed,
        );
        let pyramid_ready = self.terrain.shown_pyramid().is_some();
        let patch_list: &[_] = if pyramid_ready {
            &self.gfx.selection.patches
        } else {
            &[]
        };
        let bytes = self.gfx.scene.prepare(
            &self.gfx.gpu.device,
            &self.gfx.gpu.queue,
            &g,
            patch_list,
            &lines,
        );
        (patches, bytes)
    }

    /// The status line's figures; returns the solver's device traffic this frame (up, down).
    fn update_status(&mut self, patches: usize, bytes_up: u64) -> (u64, u64) {
        let counters = self.terrain.take_counters();
        let (up, down) = (counters.bytes_up, counters.bytes_read_back);
        self.status.gpu_counts = counters;
        self.status.finest_level = self.terrain.finest_ready();
        self.status.residual = self.terrain.residual();
        self.status.work_units = self.terrain.frame_work_units;
        self.status.converged = self.terrain.converged();
        self.status.patches = patches;
        self.status.bytes_up = bytes_up + up;
        self.status.bytes_down = down;
        self.status.title = self.doc.title();
        self.status.undo = (self.doc.undo_depth(), self.doc.redo_depth());
        self.status.fly = self.view.camera.fly;
        self.status.refine_running = self.refine.job.is_some().then(|| {
            (
                self.refine.status.progress,
                self.refine.status.stage.clone(),
            )
        });
        self.status.refined = self.terrain.refined_shown();
        (up, down)
    }

    fn probe_heights(&mut self) -> Vec<Option<[f32; 2]>> {
        let Some(r) = self.replay.as_ref().filter(|r| r.log.is_some()) else {
            return Vec::new();
        };
        match self.terrain.probe_heights(&r.probes_m) {
            Ok(h) => h,
            Err(e) => {
                let n = r.probes_m.len();
                self.error(format!("cannot read the probe heights: {e:#}"));
                vec![None; n]
            }
        }
    }

    fn place_pixel_probes(&mut self) {
        // Pixels are placed once the UI has run (the view is centred beside the side panel).
        if self.frame_no == 0 {
            return;
        }
        let Some(r) = self.replay.as_ref() else {
            return;
        };
        if r.probes_px.is_empty() {
            return;
        }
        let Some(field) = self.terrain.field() else {
            return;
        };
        let proj = self.projection();
        let pts: Vec<[f64; 2]> = r
            .probes_px
            .iter()
            .map(|p| {
                let hit = field.raycast(&proj.ray(Vec2::from(*p)));
                hit.map(|h| [h.x as f64, h.y as f64])
                    .unwrap_or([f64::NAN, f64::NAN])
            })
            .collect();
        if let Some(r) = self.replay.as_mut() {
            r.probes_m.extend(pts);
            r.probes_px.clear();
        }
    }

    fn stroke_lines(&self, proj: &super::camera::Projection) -> Vec<LineVertex> {
        let mut out = Vec::new();
        let lift = 0.002 * self.view.camera.distance_m;
        for (i, s) in self.doc.sketch.strokes.iter().enumerate() {
            let selected = self.doc.selected == Some(i);
            let colour = match (selected, s.kind) {
                (true, _) => [1.0, 0.95, 0.2, 1.0],
                (false, StrokeKind::Plateau) => [0.25, 0.55, 1.0, 1.0],
                (false, StrokeKind::Ridge) => [0.9, 0.25, 0.15, 1.0],
                (false, StrokeKind::Valley) => [0.95, 0.45, 0.1, 1.0],
            };
            let p = |q: &[f64; 3]| [q[0] as f32, q[1] as f32, q[2] as f32 + lift];
            for w in super::tools::stroke_curve_points(&self.doc.sketch, i).windows(2) {
                out.push(LineVertex {
                    position_m: p(&w[0]),
                    colour,
                });
                out.push(LineVertex {
                    position_m: p(&w[1]),
                    colour,
                });
            }
            // Handles: small 3D crosses at both ends, sized to stay ~8 px on screen.
            for end in [s.points.first(), s.points.last()].into_iter().flatten() {
                let c = Vec3::from(p(end));
                let d = (c - proj.eye_m).length();
                let r = d * 8.0 / proj.viewport_px.y.max(1.0);
                let hc = [1.0, 1.0, 1.0, 1.0];
                for axis in [Vec3::X, Vec3::Y, Vec3::Z] {
                    out.push(LineVertex {
                        position_m: (c - axis * r).to_array(),
                        colour: hc,
                    });
                    out.push(LineVertex {
                        position_m: (c + axis * r).to_array(),
                        colour: hc,
                    });
                }
            }
        }
        out
    }

    fn draw_frame(&mut self) {
        let raw = self.gfx.egui_state.take_egui_input(&self.gfx.window);
        let mut actions = Vec::new();
        let tool = self.tool;
        let (ui_state, view, sketch, selected, status) = (
            &mut self.ui,
            &mut self.view.options,
            &self.doc.sketch,
            self.doc.selected,
            &self.status,
        );
        let mut free_left_pt = 0.0f32;
        let mut full = self.gfx.egui_ctx.run_ui(raw, |root| {
            actions = ui::show(root, ui_state, tool, view, sketch, selected, status);
            free_left_pt = root.available_rect_before_wrap().min.x;
        });
        self.view.panel_px = (free_left_pt * full.pixels_per_point).max(0.0);
        self.gfx
            .egui_state
            .handle_platform_output(&self.gfx.window, full.platform_output.clone());
        for a in actions {
            self.act(a);
        }
        let ppp = full.pixels_per_point;
        let jobs = self.gfx.egui_ctx.tessellate(full.shapes, ppp);
        // Texture updates are applied every frame, drawn or not (egui expects each delta once).
        for (id, deltas) in full.textures_delta.set.drain() {
            for d in &deltas {
                self.gfx.egui_renderer.update_texture(
                    &self.gfx.gpu.device,
                    &self.gfx.gpu.queue,
                    id,
                    d,
                );
            }
        }
        if self.gfx.gpu.drawable() {
            let screen = egui_wgpu::ScreenDescriptor {
                size_in_pixels: [self.gfx.gpu.config.width, self.gfx.gpu.config.height],
                pixels_per_point: ppp,
            };
            let shot = self.replay.as_mut().and_then(|r| r.screenshot.take());
            if let Some(frame) = self.gfx.gpu.acquire() {
                let view = frame
                    .texture
                    .create_view(&wgpu::TextureViewDescriptor::default());
                self.gfx.encode(&view, &jobs, &screen);
                self.gfx.gpu.queue.present(frame);
            }
            if let Some(name) = shot {
                self.screenshot(&name, &jobs, &screen);
            }
        }
        for id in full.textures_delta.free.drain() {
            self.gfx.egui_renderer.free_texture(&id);
        }
    }

    fn screenshot(
        &mut self,
        name: &str,
        jobs: &[egui::ClippedPrimitive],
        screen: &egui_wgpu::ScreenDescriptor,
    ) {
        let Some(dir) = self.replay.as_ref().and_then(|r| r.screenshots.clone()) else {
            return;
        };
        let tex = self.gfx.gpu.offscreen();
        let view = tex.create_view(&wgpu::TextureViewDescriptor::default());
        self.gfx.encode(&view, jobs, screen);
        if let Err(e) = self.gfx.gpu.save_png(&tex, &dir.join(name)) {
            self.error(format!("{e:#}"));
        }
    }

    fn log_frame(
        &mut self,
        (ms, solver_ms): (f64, f64),
        patches: usize,
        (bytes_up, bytes_down): (u64, u64),
        names: Vec<String>,
        probe_heights_m: Vec<Option<[f32; 2]>>,
    ) {
        let proj = self.projection();
        let Some(r) = self.replay.as_mut() else {
            return;
        };
        if r.log.is_none() {
            return;
        }
        // The lag is the solver's: the diffusion shown against the converged diffusion.
        let diffusion: Vec<Option<f32>> = probe_heights_m.iter().map(|h| h.map(|h| h[0])).collect();
        let lag_m = r
            .lag
            .as_mut()
            .and_then(|l| l.lag_m(&self.doc.sketch, &r.probes_m, &diffusion));
        let probe_heights_m: Vec<Option<f32>> = probe_heights_m
            .iter()
            .map(|h| h.map(|h| h[0] + h[1]))
            .collect();
        let r = &*r;
        let handles_px = self
            .doc
            .sketch
            .strokes
            .iter()
            .map(|s| {
                let pts = stroke_screen(&proj, s);
                [
                    pts.first().copied().flatten().map(|v| v.to_array()),
                    pts.last().copied().flatten().map(|v| v.to_array()),
                ]
            })
            .collect();
        let rec = FrameRecord {
            frame: self.frame_no,
            ms,
            tool: self.tool.name(),
            solver_finest_level: self.terrain.finest_ready(),
            solver_residual: self.terrain.residual(),
            work_units: self.terrain.frame_work_units,
            solver_vcycles: self.terrain.last.vcycles,
            gpu_dispatches: self.status.gpu_counts.dispatches,
            gpu_submits: self.status.gpu_counts.submits,
            gpu_blocking_waits: self.status.gpu_counts.blocking_waits,
            gpu_bytes_moved_estimate: self.status.gpu_counts.bytes_moved_estimate,
            gpu_paper_model_ms: self
                .status
                .gpu_counts
                .paper_model_ms(&terrasketch_multigrid::gpu::MID_RANGE_GPU),
            solver_ms,
            lag_m,
            converged: self.terrain.converged(),
            settled: self.terrain.settled(),
            patches,
            bytes_up,
            bytes_down,
            strokes: self.doc.sketch.strokes.len(),
            probe_heights_m,
            probe_points_m: r.probes_m.clone(),
            pointer_down: self.view.left_down,
            mark: r.mark.clone(),
            events: names,
            errors: self.errors.clone(),
            handles_px,
            sketch_digest: digest(&to_json(&self.doc.sketch)),
            dirty: self.doc.dirty,
            undo_depth: self.doc.undo_depth(),
            compare_max_abs_m: r.compare,
            surface_px: [self.gfx.gpu.config.width, self.gfx.gpu.config.height],
            panel_px: self.view.panel_px,
            backend: self.terrain.backend_name(),
            recovery_offered: self.ui.recovery_offer.is_some(),
            refine: self.refine.status.clone(),
            refined_shown: self.terrain.refined_shown(),
            refined_origin: self.refine.origin,
            warnings: self.warnings.clone(),
            notice: self.ui.notice.clone(),
        };
        if let Some(r) = self.replay.as_mut() {
            r.compare = None;
            if let Some(log) = r.log.as_mut()
                && let Err(e) = log.write(&rec)
            {
                self.result = Err(e);
                self.done = true;
            }
        }
    }
}
