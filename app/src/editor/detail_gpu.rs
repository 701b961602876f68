//! The GPU solver's detail amplitude (`shaders/render/detail_amplitude.wgsl`): computed on the
//! device from the solver's mip 2, roughness and constraint pyramid straight into the renderer's
//! amplitude texture, after each publish (nothing goes up or comes back).

use bytemuck::{Pod, Zeroable};
use terrasketch_detail::amplitude::{FADE_CELLS, ZERO_CELLS, law_gain};
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
    _pad: u32,
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

    /// Writes the amplitude of `solver`'s published state into `out` (R32Float, side n / 4, storage
    /// binding). Call right after a publish (the constraint pyramid is overwritten by the next
    /// rasterisation).
    pub fn run(&self, solver: &GpuSolver, out: &wgpu::Texture) -> Result<(), GpuError> {
        let ctx = solver.context();
        let grid = *solver.grid();
        let m = grid.n / 4;
        let (rough, rough_off, _) = solver.roughness_buffer()?;
        let (pyr, pyr_off, _) = solver.hard_counts_level2();
        let [dx, dy] = grid.cell_size_m();
        let params = Params {
            m: m as u32,
            rough_offset: (rough_off / 4) as u32,
            pyramid_offset: (pyr_off / 8) as u32,
            _pad: 0,
            cell_m: [4.0 * dx as f32, 4.0 * dy as f32],
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
                base_mip_level: 2,
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

    #[test]
    fn cpu_and_gpu_agree_on_the_detailed_terrain_and_hard_constraints_hold() {
        let mut sketch = example_sketch();
        sketch.seed = 11;
        let n = 256;
        let m = n / 4;
        let grid = Grid::new(n, sketch.extent_m).expect("grid");
        let ctx = GpuContext::new().expect("a GPU adapter (lavapipe here)");
        let mut gpu = GpuSolver::new(&ctx, grid, SolverParams::default()).expect("gpu solver");
        gpu.solve_sketch(&sketch).expect("gpu solve");
        let out = ctx.device.create_texture(&wgpu::TextureDescriptor {
            label: Some("test.amplitude"),
            size: wgpu::Extent3d {
                width: m as u32,
                height: m as u32,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: wgpu::TextureFormat::R32Float,
            usage: wgpu::TextureUsages::STORAGE_BINDING | wgpu::TextureUsages::COPY_SRC,
            view_formats: &[],
        });
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
