//! The GPU solver's detail amplitude (`shaders/render/detail_amplitude.wgsl`): computed on the
//! device from the solver's mip `AMPLITUDE_LEVEL`, roughness and constraint pyramid straight into
//! the renderer's amplitude texture, after each publish (nothing goes up or comes back).

use bytemuck::{Pod, Zeroable};
use terrasketch_detail::amplitude::{
    AMPLITUDE_LEVEL, FADE_CELLS, ZERO_CELLS, amplitude_side, law_gain,
};
use terrasketch_detail::calibration::{RMS_FLAT_M, RMS_PER_SLOPE_M, SLOPE_TAN_MAX};
use terrasketch_multigrid::gpu::GpuError;
use terrasketch_multigrid::gpu_solver::GpuSolver;

/// The pass's uniforms. Keep in sync with `Params` in `detail_amplitude.wgsl`.
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
struct Params {
    m: u32,
    rough_offset: u32,
    pyramid_offset: u32,
    rough_side: u32,
    cell_m: [f32; 2],
    rms_flat_m: f32,
    rms_per_slope_m: f32,
    slope_tan_max: f32,
    gain: f32,
    zero_cells: i32,
    fade_cells: i32,
}

/// The compute pipeline (made once per device).
pub struct AmplitudePass {
    pipeline: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
    params: wgpu::Buffer,
}

impl AmplitudePass {
    /// Builds the pipeline on `device`.
    pub fn new(device: &wgpu::Device) -> AmplitudePass {
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("editor.detail_amplitude"),
            source: wgpu::ShaderSource::Wgsl(
                include_str!("../../../shaders/render/detail_amplitude.wgsl").into(),
            ),
        });
        let entry = |binding, ty| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::COMPUTE,
            ty,
            count: None,
        };
        let storage = wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Storage { read_only: true },
            has_dynamic_offset: false,
            min_binding_size: None,
        };
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("editor.detail_amplitude.layout"),
            entries: &[
                entry(
                    0,
                    wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Uniform,
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                ),
                entry(
                    1,
                    wgpu::BindingType::Texture {
                        multisampled: false,
                        sample_type: wgpu::TextureSampleType::Float { filterable: false },
                        view_dimension: wgpu::TextureViewDimension::D2,
                    },
                ),
                entry(2, storage),
                entry(3, storage),
                entry(
                    4,
                    wgpu::BindingType::StorageTexture {
                        access: wgpu::StorageTextureAccess::WriteOnly,
                        format: wgpu::TextureFormat::R32Float,
                        view_dimension: wgpu::TextureViewDimension::D2,
                    },
                ),
            ],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("editor.detail_amplitude.pipeline_layout"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("editor.detail_amplitude"),
            layout: Some(&pipeline_layout),
            module: &module,
            entry_point: Some("main"),
            compilation_options: wgpu::PipelineCompilationOptions::default(),
            cache: None,
        });
        let params = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("editor.detail_amplitude.params"),
            size: std::mem::size_of::<Params>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        AmplitudePass {
            pipeline,
            layout,
            params,
        }
    }

    /// Writes the amplitude of `solver`'s published state into `out` (R32Float, side
    /// `amplitude_side(n)`, storage binding). Call right after a publish (the constraint pyramid is
    /// overwritten by the next rasterisation).
    pub fn run(&self, solver: &GpuSolver, out: &wgpu::Texture) -> Result<(), GpuError> {
        let ctx = solver.context();
        let grid = *solver.grid();
        let m = amplitude_side(grid.n);
        let (rough, rough_off, _) = solver.roughness_buffer()?;
        let (pyr, pyr_off, _) = solver.hard_counts(AMPLITUDE_LEVEL).ok_or_else(|| {
            GpuError::ProblemMismatch(format!(
                "no constraint pyramid level {AMPLITUDE_LEVEL} at {}^2",
                grid.n
            ))
        })?;
        let [dx, dy] = grid.cell_size_m();
        let block = f64::from(1u32 << AMPLITUDE_LEVEL);
        let params = Params {
            m: m as u32,
            rough_offset: (rough_off / 4) as u32,
            pyramid_offset: (pyr_off / 8) as u32,
            rough_side: (grid.n / 4) as u32,
            cell_m: [(block * dx) as f32, (block * dy) as f32],
            rms_flat_m: RMS_FLAT_M,
            rms_per_slope_m: RMS_PER_SLOPE_M,
            slope_tan_max: SLOPE_TAN_MAX,
            gain: law_gain(),
            zero_cells: ZERO_CELLS,
            fade_cells: FADE_CELLS,
        };
        ctx.checked("editor.detail_amplitude", || {
            ctx.queue
                .write_buffer(&self.params, 0, bytemuck::bytes_of(&params));
            let mip2 = solver.texture().create_view(&wgpu::TextureViewDescriptor {
                base_mip_level: AMPLITUDE_LEVEL,
                mip_level_count: Some(1),
                ..Default::default()
            });
            let out_view = out.create_view(&wgpu::TextureViewDescriptor::default());
            let bind = ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("editor.detail_amplitude.bind"),
                layout: &self.layout,
                entries: &[
                    wgpu::BindGroupEntry {
                        binding: 0,
                        resource: self.params.as_entire_binding(),
                    },
                    wgpu::BindGroupEntry {
                        binding: 1,
                        resource: wgpu::BindingResource::TextureView(&mip2),
                    },
                    wgpu::BindGroupEntry {
                        binding: 2,
                        resource: rough.as_entire_binding(),
                    },
                    wgpu::BindGroupEntry {
                        binding: 3,
                        resource: pyr.as_entire_binding(),
                    },
                    wgpu::BindGroupEntry {
                        binding: 4,
                        resource: wgpu::BindingResource::TextureView(&out_view),
                    },
                ],
            });
            let mut enc = ctx
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                    label: Some("editor.detail_amplitude"),
                });
            {
                let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some("editor.detail_amplitude"),
                    timestamp_writes: None,
                });
                pass.set_pipeline(&self.pipeline);
                pass.set_bind_group(0, &bind, &[]);
                let groups = (m as u32).div_ceil(8);
                pass.dispatch_workgroups(groups, groups, 1);
            }
            ctx.queue.submit([enc.finish()]);
            Ok(())
        })
    }
}

#[cfg(test)]
mod tests {
    //! CPU and GPU agree on the detailed terrain (the GPU solver's heights, roughness and
    //! constraint pyramid through this pass, against the CPU solver through
    //! `terrasketch_detail::amplitude_map`), and hard constraints hold on both.

    use terrasketch_detail::{detail_field, noise_mips, sample_bilinear};
    use terrasketch_multigrid::gpu::{GpuContext, read_texture_r32};
    use terrasketch_multigrid::gpu_solver::GpuSolver;
    use terrasketch_multigrid::{CpuSolver, Grid, SolverParams};
    use terrasketch_sketch::example_sketch;

    use super::AmplitudePass;

    /// A square R32Float texture a compute pass writes and a test reads back.
    pub(super) fn storage_r32(device: &wgpu::Device, side: u32, label: &str) -> wgpu::Texture {
        device.create_texture(&wgpu::TextureDescriptor {
            label: Some(label),
            size: wgpu::Extent3d {
                width: side,
                height: side,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: wgpu::TextureFormat::R32Float,
            usage: wgpu::TextureUsages::STORAGE_BINDING | wgpu::TextureUsages::COPY_SRC,
            view_formats: &[],
        })
    }

    #[test]
    fn cpu_and_gpu_agree_on_the_detailed_terrain_and_hard_constraints_hold() {
        let mut sketch = example_sketch();
        sketch.seed = 11;
        let n = 256;
        let m = terrasketch_detail::amplitude_side(n);
        let grid = Grid::new(n, sketch.extent_m).expect("grid");
        let ctx = GpuContext::new().expect("a GPU adapter (lavapipe here)");
        let mut gpu = GpuSolver::new(&ctx, grid, SolverParams::default()).expect("gpu solver");
        gpu.solve_sketch(&sketch).expect("gpu solve");
        let out = storage_r32(&ctx.device, m as u32, "test.amplitude");
        AmplitudePass::new(&ctx.device)
            .run(&gpu, &out)
            .expect("amplitude pass");
        let amp_gpu = read_texture_r32(&ctx, &out, 0, m as u32, "amplitude").unwrap();
        let h_gpu = gpu.read_heights().expect("heights");

        let mut cpu = CpuSolver::new(grid, SolverParams::default()).expect("cpu solver");
        cpu.set_sketch(&sketch);
        cpu.solve();
        let amp_cpu = crate::detail::amplitude_cpu(&mut cpu);
        let relief = cpu.relief_m();

        // The amplitude maps: same blocks zeroed, values within a small fraction of the largest.
        let top = amp_cpu.iter().fold(0.0f32, |a, b| a.max(*b));
        assert!(top > 10.0, "largest amplitude {top}");
        for (i, (a, b)) in amp_cpu.iter().zip(&amp_gpu).enumerate() {
            assert_eq!(*a == 0.0, *b == 0.0, "block {i}: cpu {a}, gpu {b}");
            assert!((a - b).abs() <= 2e-3 * top, "block {i}: cpu {a}, gpu {b}");
        }
        // The detailed heights, as exported (CPU) and as displayed from the GPU's fields at the
        // texel centres (amplitude x the level-0 octave sums the editor uploads).
        let mut cpu_heights = cpu.heights().to_vec();
        let d = detail_field(n, sketch.extent_m, &amp_cpu, sketch.seed);
        let noise = noise_mips(n, sketch.extent_m, sketch.seed);
        let (w, e) = (&cpu.constraints().elev_weight, cpu.elevation_values());
        let (mut worst, mut worst_hard, mut moved) = (0.0f32, 0.0f32, 0.0f64);
        for t in 0..n * n {
            cpu_heights[t] += d[t];
            let (i, j) = (t % n, t / n);
            let (u, v) = ((i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32);
            let a = sample_bilinear(&amp_gpu, m, u, v);
            let shown = h_gpu[t] + if a > 0.0 { a * noise[0][t] } else { 0.0 };
            worst = worst.max((shown - cpu_heights[t]).abs() / relief);
            moved += f64::from(d[t]).powi(2);
            if w[t] >= 1.0 {
                worst_hard = worst_hard
                    .max((shown - e[t]).abs() / relief)
                    .max((cpu_heights[t] - e[t]).abs() / relief);
            }
        }
        assert!((moved / (n * n) as f64).sqrt() > 2.0, "the detail is there");
        eprintln!("CPU-GPU: {worst:.2e} of the relief; hard texels: {worst_hard:.2e}");
        assert!(worst <= 1e-3, "CPU and GPU differ by {worst} of the relief");
        assert!(
            worst_hard <= 1e-3,
            "a hard texel moved by {worst_hard} of the relief"
        );
    }
}

#[cfg(test)]
mod fine_tests {
    //! The terrain shader's finer-than-a-cell octaves (`fine_detail.wgsl`) against their CPU twin
    //! (`terrasketch_detail::fine_octaves`): the same values, and an analytic gradient that is the
    //! CPU's central differences.

    use terrasketch_detail::calibration::{BILLOW_MEAN, HURST, REFERENCE_WAVELENGTH_M};
    use terrasketch_detail::{fine_octaves, seed32};
    use terrasketch_multigrid::gpu::{GpuContext, read_texture_r32};

    const SIDE: u32 = 64;
    const POINTS: usize = 1024;

    /// Runs `fine_detail` at `POINTS` points on the device: (value, d/dx, d/dy) each.
    fn gpu_fine(
        ctx: &GpuContext,
        pts: &[[f32; 2]],
        cell_m: f32,
        footprint_m: f32,
        seed: u32,
    ) -> Vec<[f32; 3]> {
        let src = format!(
            "{}\n{}",
            include_str!("../../../shaders/render/fine_detail.wgsl"),
            "@group(0) @binding(0) var<storage, read> pts: array<vec2<f32>>;
             @group(0) @binding(1) var out: texture_storage_2d<r32float, write>;
             override cell_m: f32; override footprint_m: f32; override seed: u32;
             override hurst: f32; override reference_m: f32; override billow_mean: f32;
             @compute @workgroup_size(64) fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
                 let p = gid.x;
                 if (p >= arrayLength(&pts)) { return; }
                 let d = fine_detail(pts[p], cell_m, footprint_m, seed, vec3<f32>(hurst, reference_m, billow_mean));
                 let x = i32(p % 64u);
                 let y = i32(p / 64u);
                 textureStore(out, vec2<i32>(x, y), vec4<f32>(d.x));
                 textureStore(out, vec2<i32>(x, y + 16), vec4<f32>(d.y));
                 textureStore(out, vec2<i32>(x, y + 32), vec4<f32>(d.z));
             }"
        );
        let device = &ctx.device;
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("test.fine_detail"),
            source: wgpu::ShaderSource::Wgsl(src.into()),
        });
        let constants = [
            ("cell_m", f64::from(cell_m)),
            ("footprint_m", f64::from(footprint_m)),
            ("seed", f64::from(seed)),
            ("hurst", f64::from(HURST)),
            ("reference_m", f64::from(REFERENCE_WAVELENGTH_M)),
            ("billow_mean", f64::from(BILLOW_MEAN)),
        ];
        let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("test.fine_detail"),
            layout: None,
            module: &module,
            entry_point: Some("main"),
            compilation_options: wgpu::PipelineCompilationOptions {
                constants: &constants,
                ..Default::default()
            },
            cache: None,
        });
        let flat: Vec<f32> = pts.iter().flatten().copied().collect();
        let buf = wgpu::util::DeviceExt::create_buffer_init(
            device,
            &wgpu::util::BufferInitDescriptor {
                label: Some("test.fine_detail.points"),
                contents: bytemuck::cast_slice(&flat),
                usage: wgpu::BufferUsages::STORAGE,
            },
        );
        let tex = super::tests::storage_r32(device, SIDE, "test.fine_detail.out");
        let view = tex.create_view(&wgpu::TextureViewDescriptor::default());
        let bind = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("test.fine_detail.bind"),
            layout: &pipeline.get_bind_group_layout(0),
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: buf.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: wgpu::BindingResource::TextureView(&view),
                },
            ],
        });
        let mut enc = device.create_command_encoder(&wgpu::CommandEncoderDescriptor::default());
        {
            let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor::default());
            pass.set_pipeline(&pipeline);
            pass.set_bind_group(0, &bind, &[]);
            pass.dispatch_workgroups((pts.len() as u32).div_ceil(64), 1, 1);
        }
        ctx.queue.submit([enc.finish()]);
        let t = read_texture_r32(ctx, &tex, 0, SIDE, "fine detail").expect("read back");
        (0..pts.len())
            .map(|p| {
                let (x, y) = (p % 64, p / 64);
                [t[y * 64 + x], t[(y + 16) * 64 + x], t[(y + 32) * 64 + x]]
            })
            .collect()
    }

    #[test]
    fn fine_detail_matches_its_cpu_twin_and_vanishes_when_far() {
        let ctx = GpuContext::new().expect("a GPU adapter (lavapipe here)");
        let seed = seed32(7);
        // 10 m cells seen at 0.25 m a pixel: the octaves of 16 m and 2 m in part, 8 m and 4 m.
        let (cell, footprint) = (10.0f32, 0.25f32);
        let octaves = fine_octaves(cell, footprint, seed);
        assert_eq!(octaves.count(), 4);
        let pts: Vec<[f32; 2]> = (0..POINTS)
            .map(|p| {
                let (i, j) = ((p % 32) as f32, (p / 32) as f32);
                [40.0 + 1.37 * i + 0.11 * j, 25.0 + 1.13 * j + 0.07 * i]
            })
            .collect();
        let gpu = gpu_fine(&ctx, &pts, cell, footprint, seed);
        let h = 2e-3f32;
        let (mut worst_value, mut grad_rms, mut grad_err) = (0.0f32, 0.0f64, Vec::new());
        let mut value_rms = 0.0f64;
        for (p, g) in pts.iter().zip(&gpu) {
            let v = octaves.eval(p[0], p[1]);
            let dx = (octaves.eval(p[0] + h, p[1]) - octaves.eval(p[0] - h, p[1])) / (2.0 * h);
            let dy = (octaves.eval(p[0], p[1] + h) - octaves.eval(p[0], p[1] - h)) / (2.0 * h);
            worst_value = worst_value.max((v - g[0]).abs());
            value_rms += f64::from(v * v);
            grad_rms += f64::from(dx * dx + dy * dy);
            grad_err.push(((dx - g[1]).powi(2) + (dy - g[2]).powi(2)).sqrt());
        }
        let value_rms = (value_rms / POINTS as f64).sqrt() as f32;
        let grad_rms = (grad_rms / POINTS as f64).sqrt() as f32;
        assert!(value_rms > 0.01, "the octaves are there: rms {value_rms}");
        assert!(
            worst_value <= 1e-3 * value_rms.max(1.0),
            "values differ by {worst_value} (rms {value_rms})"
        );
        // The billow's creases (|n| at n = 0) are kinks the central differences straddle at a few
        // points; elsewhere the analytic gradient is the differences'.
        grad_err.sort_by(f32::total_cmp);
        let p98 = grad_err[POINTS * 98 / 100];
        assert!(
            p98 <= 0.02 * grad_rms,
            "gradient error p98 {p98}, gradient rms {grad_rms}"
        );
        // Seen from afar (a pixel as large as a cell) nothing finer than the heightmap is shown.
        assert_eq!(fine_octaves(cell, cell, seed).count(), 0);
        let far = gpu_fine(&ctx, &pts[..64], cell, cell, seed);
        assert!(far.iter().all(|g| *g == [0.0; 3]), "far: {:?}", &far[..2]);
    }
}
