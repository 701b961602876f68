//! The scene renderer's pipelines: the bind group layouts, the terrain pipeline (instanced patches
//! of `shaders/render/terrain.wgsl`, depth tested) and the line pipeline (strokes and handles,
//! `shaders/render/lines.wgsl`), and the patch grid's triangles.

use super::render::{DEPTH_FORMAT, LineVertex, PatchInstance};

/// The terrain's bind group layout (globals, heightmap, constraints, noise, amplitude) and the
/// lines' (globals).
pub(super) fn bind_group_layouts(
    device: &wgpu::Device,
) -> (wgpu::BindGroupLayout, wgpu::BindGroupLayout) {
    let tex_entry = |binding| wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::VERTEX | wgpu::ShaderStages::FRAGMENT,
        ty: wgpu::BindingType::Texture {
            multisampled: false,
            sample_type: wgpu::TextureSampleType::Float { filterable: false },
            view_dimension: wgpu::TextureViewDimension::D2,
        },
        count: None,
    };
    let uniform_entry = wgpu::BindGroupLayoutEntry {
        binding: 0,
        visibility: wgpu::ShaderStages::VERTEX | wgpu::ShaderStages::FRAGMENT,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Uniform,
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    };
    let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("editor.terrain.layout"),
        entries: &[
            uniform_entry,
            tex_entry(1),
            tex_entry(2),
            tex_entry(3),
            tex_entry(4),
        ],
    });
    let line_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("editor.lines.layout"),
        entries: &[uniform_entry],
    });
    (layout, line_layout)
}

/// The terrain pipeline: instanced patches (`terrain.wgsl`), depth tested, alpha blended.
pub(super) fn terrain_pipeline(
    device: &wgpu::Device,
    layout: &wgpu::BindGroupLayout,
    format: wgpu::TextureFormat,
) -> wgpu::RenderPipeline {
    let terrain_module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("editor.terrain"),
        source: wgpu::ShaderSource::Wgsl(
            concat!(
                include_str!("../../../shaders/render/terrain.wgsl"),
                include_str!("../../../shaders/render/fine_detail.wgsl")
            )
            .into(),
        ),
    });
    let depth = Some(wgpu::DepthStencilState {
        format: DEPTH_FORMAT,
        depth_write_enabled: Some(true),
        depth_compare: Some(wgpu::CompareFunction::Less),
        stencil: wgpu::StencilState::default(),
        bias: wgpu::DepthBiasState::default(),
    });
    let terrain_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some("editor.terrain.pipeline_layout"),
        bind_group_layouts: &[Some(layout)],
        immediate_size: 0,
    });
    let instance_attrs = wgpu::vertex_attr_array![0 => Float32x2, 1 => Float32, 2 => Uint32, 3 => Float32x4, 4 => Uint32];
    let target = [Some(wgpu::ColorTargetState {
        format,
        blend: Some(wgpu::BlendState::ALPHA_BLENDING),
        write_mask: wgpu::ColorWrites::ALL,
    })];
    device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some("editor.terrain"),
        layout: Some(&terrain_layout),
        vertex: wgpu::VertexState {
            module: &terrain_module,
            entry_point: Some("vs_main"),
            buffers: &[Some(wgpu::VertexBufferLayout {
                array_stride: std::mem::size_of::<PatchInstance>() as u64,
                step_mode: wgpu::VertexStepMode::Instance,
                attributes: &instance_attrs,
            })],
            compilation_options: wgpu::PipelineCompilationOptions::default(),
        },
        primitive: wgpu::PrimitiveState {
            topology: wgpu::PrimitiveTopology::TriangleList,
            cull_mode: None,
            ..Default::default()
        },
        depth_stencil: depth,
        multisample: wgpu::MultisampleState::default(),
        fragment: Some(wgpu::FragmentState {
            module: &terrain_module,
            entry_point: Some("fs_main"),
            targets: &target,
            compilation_options: wgpu::PipelineCompilationOptions::default(),
        }),
        multiview_mask: None,
        cache: None,
    })
}

/// The line pipeline (strokes and handles, `lines.wgsl`).
pub(super) fn line_pipeline(
    device: &wgpu::Device,
    line_layout: &wgpu::BindGroupLayout,
    format: wgpu::TextureFormat,
) -> wgpu::RenderPipeline {
    let line_module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("editor.lines"),
        source: wgpu::ShaderSource::Wgsl(include_str!("../../../shaders/render/lines.wgsl").into()),
    });
    let target = [Some(wgpu::ColorTargetState {
        format,
        blend: Some(wgpu::BlendState::ALPHA_BLENDING),
        write_mask: wgpu::ColorWrites::ALL,
    })];
    let line_pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some("editor.lines.pipeline_layout"),
        bind_group_layouts: &[Some(line_layout)],
        immediate_size: 0,
    });
    let line_attrs = wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32x4];
    device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some("editor.lines"),
        layout: Some(&line_pipeline_layout),
        vertex: wgpu::VertexState {
            module: &line_module,
            entry_point: Some("vs_main"),
            buffers: &[Some(wgpu::VertexBufferLayout {
                array_stride: std::mem::size_of::<LineVertex>() as u64,
                step_mode: wgpu::VertexStepMode::Vertex,
                attributes: &line_attrs,
            })],
            compilation_options: wgpu::PipelineCompilationOptions::default(),
        },
        primitive: wgpu::PrimitiveState {
            topology: wgpu::PrimitiveTopology::LineList,
            ..Default::default()
        },
        // Strokes stay visible through the terrain (they are the things being edited).
        depth_stencil: Some(wgpu::DepthStencilState {
            format: DEPTH_FORMAT,
            depth_write_enabled: Some(false),
            depth_compare: Some(wgpu::CompareFunction::Always),
            stencil: wgpu::StencilState::default(),
            bias: wgpu::DepthBiasState::default(),
        }),
        multisample: wgpu::MultisampleState::default(),
        fragment: Some(wgpu::FragmentState {
            module: &line_module,
            entry_point: Some("fs_main"),
            targets: &target,
            compilation_options: wgpu::PipelineCompilationOptions::default(),
        }),
        multiview_mask: None,
        cache: None,
    })
}

/// The patch grid's triangles: `(n + 1)^2` vertices addressed by vertex_index, two triangles per
/// cell.
pub(super) fn patch_indices(n: u32) -> Vec<u32> {
    let mut indices: Vec<u32> = Vec::with_capacity((n * n * 6) as usize);
    for j in 0..n {
        for i in 0..n {
            let v = j * (n + 1) + i;
            indices.extend_from_slice(&[v, v + 1, v + n + 2, v, v + n + 2, v + n + 1]);
        }
    }
    indices
}
