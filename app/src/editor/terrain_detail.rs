//! The procedural detail (`terrasketch_detail`) as the terrain shows it on the solver's heights:
//! octave sums per mip, the amplitude (on the CPU from the CPU solver, on the device for the GPU
//! solver), the quadtree's bounds widened by the detail's reach, and the detail in exports and
//! probes.

use terrasketch_multigrid::ConstraintMaps;
use terrasketch_quadtree::MinMaxPyramid;
use terrasketch_sketch::Sketch;

use anyhow::Result;

use super::heightfield::sample_bilinear;
use super::render::SceneRenderer;
use super::terrain::{Engine, Terrain};

/// The procedural detail (`terrasketch_detail`) as the editor shows it: the octave sums per mip
/// (made once per grid and seed) and the amplitude map, which follows every edit (the CPU
/// solver's roughness is solved incrementally in each frame that changed the heights).
#[derive(Default)]
pub(super) struct Detail {
    /// Shown (the view toggle).
    pub(super) on: bool,
    /// The sketch seed the noise belongs to.
    pub(super) seed: u64,
    /// Octave sums per mip (None until first needed, or after a seed change).
    pub(super) noise: Option<Vec<Vec<f32>>>,
    /// The noise in the renderer's texture is current.
    pub(super) noise_uploaded: bool,
    /// Amplitude (side `amplitude_side(n)`; empty before the first).
    pub(super) amp: Vec<f32>,
    /// The amplitude in the renderer's texture is current.
    pub(super) amp_uploaded: bool,
    /// The solver's min/max levels, kept to widen them by the detail.
    pub(super) base_levels: Vec<(usize, Vec<[f32; 2]>)>,
    /// The quadtree's bounds with the detail's reach added.
    pub(super) pyramid: Option<MinMaxPyramid>,
    /// GPU engine: the amplitude pass, the heights version it last ran for, and the bound of the
    /// amplitude it can write (the law at the steepest slope and the sketch's largest roughness:
    /// the amplitude stays on the device, so the bounds take this uniform reach).
    pub(super) gpu_pass: Option<super::detail_gpu::AmplitudePass>,
    /// The texture the pass writes (the renderer's; the probes read it).
    pub(super) gpu_texture: Option<wgpu::Texture>,
    pub(super) gpu_version: u64,
    pub(super) gpu_bound: Option<f32>,
}

impl Terrain {
    /// Shows the detail or not, for sketch seed `seed` (a new seed makes new octave sums).
    pub fn set_detail(&mut self, on: bool, seed: u64) {
        if seed != self.detail.seed {
            self.detail.seed = seed;
            self.detail.noise = None;
            self.detail.noise_uploaded = false;
        }
        if on && !self.detail.on {
            // The amplitude may be stale: recompute it at the next CPU step.
            self.detail.amp.clear();
        }
        self.detail.on = on;
    }

    /// True when the detail is shown (the toggle is on and no refined layer replaces it).
    pub fn detail_shown(&self) -> bool {
        self.detail.on && self.refined.is_none()
    }

    /// The CPU solver's detail amplitude from its current heights and roughness (the roughness solve
    /// is incremental: only the rows the edits changed are reassembled, then FCG from the last
    /// solution). Kept while the twin is shown on large grids (its grid is not the terrain's).
    pub(super) fn refresh_detail_cpu(&mut self) {
        let Engine::Cpu(c) = &mut self.engine else {
            return;
        };
        if c.showing_live || c.finest_ready().is_none_or(|k| k > 2) {
            return;
        }
        self.detail.amp = crate::detail::amplitude_cpu(&mut c.full.solver.solver);
        self.detail.amp_uploaded = false;
        self.rebuild_detail_pyramid();
    }

    /// The quadtree's bounds widened by the largest detail each cell can show.
    pub(super) fn rebuild_detail_pyramid(&mut self) {
        let m = terrasketch_detail::amplitude_side(self.grid.n);
        let sides: Vec<usize> = self.detail.base_levels.iter().map(|l| l.0).collect();
        let maxes = match self.detail.gpu_bound {
            Some(a) => sides.iter().map(|s| vec![a; s * s]).collect(),
            None if self.detail.amp.len() == m * m => {
                terrasketch_detail::max_pyramid(m, &self.detail.amp, &sides)
            }
            None => Vec::new(),
        };
        if self.detail.base_levels.is_empty() || maxes.is_empty() {
            self.detail.pyramid = None;
            return;
        }
        let reach = terrasketch_detail::fbm_bound(terrasketch_detail::cell_min_wavelength_m(
            self.grid.n,
            self.grid.extent_m,
        ));
        let levels = self
            .detail
            .base_levels
            .iter()
            .zip(&maxes)
            .map(|((side, cells), mx)| {
                let cells = cells
                    .iter()
                    .zip(mx)
                    .map(|(c, a)| [c[0] - a * reach, c[1] + a * reach])
                    .collect();
                (*side, cells)
            })
            .collect();
        self.detail.pyramid = MinMaxPyramid::from_levels(levels).ok();
    }

    /// GPU engine: writes the amplitude of the heights just published into `out` (the renderer's
    /// amplitude texture), once per heights version. A GPU error makes the CPU solver take over.
    pub fn run_detail_gpu(&mut self, out: &wgpu::Texture) {
        if !self.detail.on || self.detail.gpu_version == self.version {
            return;
        }
        let Engine::Gpu(g) = &self.engine else {
            return;
        };
        if !g.live.started() {
            return;
        }
        let solver = g.solver();
        let pass = self
            .detail
            .gpu_pass
            .get_or_insert_with(|| super::detail_gpu::AmplitudePass::new(&solver.context().device));
        if let Err(e) = pass.run(solver, out) {
            let why = format!("GPU detail failed ({e}); the CPU solver took over");
            self.fall_back_to_cpu(why);
            return;
        }
        self.detail.gpu_version = self.version;
        self.detail.gpu_texture = Some(out.clone());
    }

    /// Sends what the detail needs to the renderer: the octave sums once per grid and seed (made
    /// here the first time), the amplitude when it changed. Nothing while the detail is off.
    /// Returns bytes sent.
    pub fn upload_detail(&mut self, scene: &SceneRenderer, queue: &wgpu::Queue) -> u64 {
        if !self.detail.on {
            return 0;
        }
        let mut bytes = 0;
        if !self.detail.noise_uploaded {
            let noise = self.detail.noise.get_or_insert_with(|| {
                terrasketch_detail::noise_mips(self.grid.n, self.grid.extent_m, self.detail.seed)
            });
            for (k, level) in noise.iter().enumerate() {
                bytes += scene.upload_noise(queue, k as u32, level);
            }
            self.detail.noise_uploaded = true;
        }
        if !self.detail.amp_uploaded && !self.detail.amp.is_empty() {
            bytes += scene.upload_amplitude(queue, &self.detail.amp);
            self.detail.amp_uploaded = true;
        }
        bytes
    }

    /// The detail at world-fraction `(u, v)` on mip `k` as the vertex shader adds it (0 when not
    /// shown or not ready).
    pub(super) fn detail_at(&self, u: f32, v: f32, k: usize) -> f32 {
        let m = terrasketch_detail::amplitude_side(self.grid.n);
        let (Some(noise), true) = (
            self.detail.noise.as_ref().and_then(|n| n.get(k)),
            self.detail_shown() && self.detail.amp.len() == m * m,
        ) else {
            return 0.0;
        };
        let a = terrasketch_detail::sample_bilinear(&self.detail.amp, m, u, v);
        if a > 0.0 {
            a * sample_bilinear(noise, self.grid.side(k), u, v)
        } else {
            0.0
        }
    }

    /// layer, or the solver's heights with the detail when it is shown).
    pub fn export_heights(&mut self, sketch: &Sketch) -> Result<Vec<f32>> {
        let mut h = self.heights()?;
        if !self.detail_shown() {
            return Ok(h);
        }
        let amp = match &mut self.engine {
            Engine::Cpu(c) => crate::detail::amplitude_cpu(&mut c.full.solver.solver),
            Engine::Gpu(g) => {
                let s = g.solver();
                let weights = ConstraintMaps::rasterize(sketch, &self.grid).elev_weight;
                crate::detail::amplitude_from(
                    &self.grid,
                    &s.read_mip(terrasketch_detail::amplitude::AMPLITUDE_LEVEL as usize)?,
                    &s.read_roughness()?,
                    &weights,
                )
            }
        };
        terrasketch_detail::add_detail(&mut h, self.grid.n, self.grid.extent_m, &amp, sketch.seed);
        Ok(h)
    }

    /// The GPU engine's probes read the detail as drawn: the amplitude texture and mip `k`'s noise
    /// (None when the detail is not shown or not ready).
    pub(super) fn gpu_detail_for_probes(&self, k: usize) -> Option<(&wgpu::Texture, &[f32])> {
        let noise = self.detail.noise.as_ref().and_then(|n| n.get(k));
        match (self.detail_shown(), &self.detail.gpu_texture, noise) {
            (true, Some(tex), Some(noise)) => Some((tex, noise.as_slice())),
            _ => None,
        }
    }

    /// After a frame's step: on the GPU the amplitude's bound follows the sketch's roughness when
    /// the heights changed (`ran`); on the CPU the amplitude is solved again when the heights
    /// `changed` (or there is none yet).
    pub(super) fn detail_after_step(&mut self, sketch: &Sketch, ran: bool, changed: bool) {
        match self.engine {
            Engine::Gpu(_) if ran => {
                let rmax = sketch
                    .strokes
                    .iter()
                    .map(|s| s.roughness as f32)
                    .fold(0.0f32, f32::max);
                self.detail.gpu_bound = Some(terrasketch_detail::amplitude::amplitude_law(
                    terrasketch_detail::calibration::SLOPE_TAN_MAX,
                    rmax,
                ));
            }
            Engine::Gpu(_) => {}
            Engine::Cpu(_) => {
                if self.detail.on && (changed || self.detail.amp.is_empty()) {
                    self.refresh_detail_cpu();
                }
            }
        }
    }
}
