//! Long-lived GPU objects of the 3D view: the terrain pipeline (instanced patch grid displaced from an
//! R32Float heightmap with its full mip chain) and the line pipeline (strokes, handles), made in
//! `pipelines`; the textures and buffers they draw from, and the per-frame data uploads (counted in
//! `bytes_up`).

use std::ops::Range;

use bytemuck::{Pod, Zeroable};
use glam::{Mat4, Vec3};
use terrasketch_quadtree::Patch;

use super::pipelines;

/// Uniforms shared by the terrain and line passes. Keep in sync with `Globals` in
/// `shaders/render/terrain.wgsl` and `shaders/render/lines.wgsl`.
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub struct Globals {
    /// World to clip.
    pub clip_from_world: [[f32; 4]; 4],
    /// Eye position (w unused).
    pub eye_m: [f32; 4],
    /// Unit vector toward the light (w unused).
    pub light_dir: [f32; 4],
    /// Terrain extent, metres.
    pub extent_m: [f32; 2],
    /// Grid cells per patch side.
    pub leaf_cells: u32,
    /// Index of the 1x1 mip.
    pub coarsest_mip: u32,
    /// Lowest height (tint), metres.
    pub height_min_m: f32,
    /// Highest height (tint), metres.
    pub height_max_m: f32,
    /// Contour spacing, metres.
    pub contour_interval_m: f32,
    /// View options: bit 0 contours, 1 wireframe, 2 LOD colours, 3 constraint overlay, 4 detail.
    pub flags: u32,
    /// Mip 0 side.
    pub heightmap_side: u32,
    /// The sketch's 32-bit detail seed (`terrasketch_detail::seed32`).
    pub seed32: u32,
    /// Side of the detail amplitude map.
    pub amplitude_side: u32,
    /// Padding to 16 bytes.
    pub _pad: u32,
    /// The detail's Hurst exponent, reference wavelength (m) and billow mean |n|, and the
    /// heightmap's larger cell side (m): what the fragment shader's finer-than-a-cell octaves read.
    pub detail_shape: [f32; 4],
}
const _: () = assert!(std::mem::size_of::<Globals>() == 160);

/// One patch as the vertex shader reads it. Keep in sync with `PatchInstance` in `terrain.wgsl`.
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub struct PatchInstance {
    /// South-west corner, extent fractions.
    pub uv_origin: [f32; 2],
    /// Side, extent fraction.
    pub uv_size: f32,
    /// Mip sampled.
    pub mip_level: u32,
    /// Morph factors at SW, SE, NW, NE.
    pub morph: [f32; 4],
    /// Quadtree level (0 = finest).
    pub level: u32,
    /// Padding.
    pub _pad: [u32; 3],
}
const _: () = assert!(std::mem::size_of::<PatchInstance>() == 48);

impl From<&Patch> for PatchInstance {
    fn from(p: &Patch) -> Self {
        PatchInstance {
            uv_origin: p.uv_origin,
            uv_size: p.uv_size,
            mip_level: p.mip_level,
            morph: p.morph,
            level: p.level,
            _pad: [0; 3],
        }
    }
}

/// One line vertex.
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub struct LineVertex {
    /// World position, metres.
    pub position_m: [f32; 3],
    /// RGBA (already in the target's encoding).
    pub colour: [f32; 4],
}

/// Depth format of the 3D view.
pub const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

/// The 3D view's GPU state.
pub struct SceneRenderer {
    terrain_pipeline: wgpu::RenderPipeline,
    line_pipeline: wgpu::RenderPipeline,
    line_bind_group: wgpu::BindGroup,
    globals: wgpu::Buffer,
    /// The renderer's own heightmap (CPU solver), made on first use: the GPU solver's is drawn directly.
    heightmap: Option<wgpu::Texture>,
    constraints: wgpu::Texture,
    /// The detail's octave sums per mip (`terrasketch_detail`), made once per grid and seed.
    noise: wgpu::Texture,
    /// The detail amplitude (side `amplitude_side(side)`), from the CPU or written by the GPU
    /// engine's pass.
    amplitude: wgpu::Texture,
    layout: wgpu::BindGroupLayout,
    bind_group: wgpu::BindGroup,
    /// The bind group reads the GPU solver's texture instead of `heightmap`.
    external: bool,
    index_buffer: wgpu::Buffer,
    index_count: u32,
    instances: wgpu::Buffer,
    instance_capacity: usize,
    instance_count: u32,
    lines: wgpu::Buffer,
    line_capacity: usize,
    line_count: u32,
    /// Heightmap side.
    pub side: u32,
    leaf_cells: u32,
}

fn heightmap_texture(device: &wgpu::Device, side: u32, mips: u32, label: &str) -> wgpu::Texture {
    texture_with(device, side, mips, label, wgpu::TextureUsages::empty())
}

fn texture_with(
    device: &wgpu::Device,
    side: u32,
    mips: u32,
    label: &str,
    extra: wgpu::TextureUsages,
) -> wgpu::Texture {
    device.create_texture(&wgpu::TextureDescriptor {
        label: Some(label),
        size: wgpu::Extent3d {
            width: side,
            height: side,
            depth_or_array_layers: 1,
        },
        mip_level_count: mips,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: wgpu::TextureFormat::R32Float,
        usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST | extra,
        view_formats: &[],
    })
}

impl SceneRenderer {
    /// Builds pipelines and resources for a heightmap of side `side` and colour format `format`,
    /// drawing from `external` (the GPU solver's texture) or from its own texture (`None`).
    pub fn new(
        device: &wgpu::Device,
        format: wgpu::TextureFormat,
        side: u32,
        leaf_cells: u32,
        external: Option<&wgpu::Texture>,
    ) -> SceneRenderer {
        let (layout, line_layout) = pipelines::bind_group_layouts(device);
        let globals = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("editor.globals"),
            size: std::mem::size_of::<Globals>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mips = side.trailing_zeros() + 1;
        let constraints = heightmap_texture(device, side, 1, "editor.constraints");
        let noise = heightmap_texture(device, side, mips, "editor.detail_noise");
        let amplitude = texture_with(
            device,
            (terrasketch_detail::amplitude_side(side as usize) as u32).max(1),
            1,
            "editor.detail_amplitude",
            wgpu::TextureUsages::STORAGE_BINDING | wgpu::TextureUsages::COPY_SRC,
        );
        let detail = (&noise, &amplitude);
        let (heightmap, bind_group) = match external {
            Some(t) => (
                None,
                Self::make_bind_group(device, &layout, &globals, t, &constraints, detail),
            ),
            None => {
                let own = heightmap_texture(device, side, mips, "editor.heightmap");
                let bg =
                    Self::make_bind_group(device, &layout, &globals, &own, &constraints, detail);
                (Some(own), bg)
            }
        };
        let line_bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("editor.lines.bind"),
            layout: &line_layout,
            entries: &[wgpu::BindGroupEntry {
                binding: 0,
                resource: globals.as_entire_binding(),
            }],
        });
        let terrain_pipeline = pipelines::terrain_pipeline(device, &layout, format);
        let line_pipeline = pipelines::line_pipeline(device, &line_layout, format);
        let indices = pipelines::patch_indices(leaf_cells);
        let index_buffer = wgpu::util::DeviceExt::create_buffer_init(
            device,
            &wgpu::util::BufferInitDescriptor {
                label: Some("editor.patch_indices"),
                contents: bytemuck::cast_slice(&indices),
                usage: wgpu::BufferUsages::INDEX,
            },
        );
        let instance_capacity = 256;
        let instances = Self::buffer(
            device,
            "editor.patches",
            instance_capacity * 48,
            wgpu::BufferUsages::VERTEX,
        );
        let line_capacity = 4096;
        let lines = Self::buffer(
            device,
            "editor.lines",
            line_capacity * 28,
            wgpu::BufferUsages::VERTEX,
        );
        SceneRenderer {
            terrain_pipeline,
            line_pipeline,
            line_bind_group,
            globals,
            heightmap,
            constraints,
            noise,
            amplitude,
            layout,
            bind_group,
            external: external.is_some(),
            index_buffer,
            index_count: indices.len() as u32,
            instances,
            instance_capacity,
            instance_count: 0,
            lines,
            line_capacity,
            line_count: 0,
            side,
            leaf_cells,
        }
    }

    fn buffer(
        device: &wgpu::Device,
        label: &str,
        size: usize,
        usage: wgpu::BufferUsages,
    ) -> wgpu::Buffer {
        device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size: size as u64,
            usage: usage | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        })
    }

    fn make_bind_group(
        device: &wgpu::Device,
        layout: &wgpu::BindGroupLayout,
        globals: &wgpu::Buffer,
        heightmap: &wgpu::Texture,
        constraints: &wgpu::Texture,
        (noise, amplitude): (&wgpu::Texture, &wgpu::Texture),
    ) -> wgpu::BindGroup {
        let hv = heightmap.create_view(&wgpu::TextureViewDescriptor::default());
        let cv = constraints.create_view(&wgpu::TextureViewDescriptor::default());
        let nv = noise.create_view(&wgpu::TextureViewDescriptor::default());
        let av = amplitude.create_view(&wgpu::TextureViewDescriptor::default());
        device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("editor.terrain.bind"),
            layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: globals.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: wgpu::BindingResource::TextureView(&hv),
                },
                wgpu::BindGroupEntry {
                    binding: 2,
                    resource: wgpu::BindingResource::TextureView(&cv),
                },
                wgpu::BindGroupEntry {
                    binding: 3,
                    resource: wgpu::BindingResource::TextureView(&nv),
                },
                wgpu::BindGroupEntry {
                    binding: 4,
                    resource: wgpu::BindingResource::TextureView(&av),
                },
            ],
        })
    }

    /// Draws the terrain from `texture` (the GPU solver's R32Float mip chain of the same side, which it
    /// updates in place: nothing is uploaded), or from the renderer's own texture (`None`: the CPU
    /// solver's rows are uploaded into it).
    pub fn use_heightmap(&mut self, device: &wgpu::Device, texture: Option<&wgpu::Texture>) {
        let external = texture.is_some();
        if texture.is_none() && self.heightmap.is_none() {
            let mips = self.side.trailing_zeros() + 1;
            self.heightmap = Some(heightmap_texture(
                device,
                self.side,
                mips,
                "editor.heightmap",
            ));
        }
        let Some(tex) = texture.or(self.heightmap.as_ref()) else {
            return;
        };
        self.bind_group = Self::make_bind_group(
            device,
            &self.layout,
            &self.globals,
            tex,
            &self.constraints,
            (&self.noise, &self.amplitude),
        );
        self.external = external;
    }

    /// True when the terrain is drawn from the GPU solver's texture.
    pub fn external_heightmap(&self) -> bool {
        self.external
    }

    /// Writes rows `rows` of mip `level` (`data` is the whole level). Returns bytes sent.
    pub fn upload_rows(
        &self,
        queue: &wgpu::Queue,
        level: u32,
        data: &[f32],
        rows: Range<usize>,
    ) -> u64 {
        match &self.heightmap {
            Some(tex) => self.write_rows(queue, tex, level, data, rows),
            None => 0,
        }
    }

    /// Writes rows of the constraint overlay (level-0 elevation weights). Returns bytes sent.
    pub fn upload_constraint_rows(
        &self,
        queue: &wgpu::Queue,
        data: &[f32],
        rows: Range<usize>,
    ) -> u64 {
        self.write_rows(queue, &self.constraints, 0, data, rows)
    }

    /// Writes mip `level` of the detail's octave sums (`data` is the whole level). Returns bytes sent.
    pub fn upload_noise(&self, queue: &wgpu::Queue, level: u32, data: &[f32]) -> u64 {
        let side = (self.side >> level).max(1) as usize;
        self.write_rows(queue, &self.noise, level, data, 0..side)
    }

    /// Writes the detail amplitude (side `amplitude_side(side)`). Returns bytes sent.
    pub fn upload_amplitude(&self, queue: &wgpu::Queue, data: &[f32]) -> u64 {
        let side = terrasketch_detail::amplitude_side(self.side as usize).max(1);
        self.write_rows_of(queue, &self.amplitude, side, data, 0..side)
    }

    /// The amplitude texture (the GPU engine's pass writes it).
    pub fn amplitude_texture(&self) -> &wgpu::Texture {
        &self.amplitude
    }

    fn write_rows(
        &self,
        queue: &wgpu::Queue,
        tex: &wgpu::Texture,
        level: u32,
        data: &[f32],
        rows: Range<usize>,
    ) -> u64 {
        let side = (self.side >> level).max(1) as usize;
        self.write_level(queue, tex, level, side, data, rows)
    }

    fn write_rows_of(
        &self,
        queue: &wgpu::Queue,
        tex: &wgpu::Texture,
        side: usize,
        data: &[f32],
        rows: Range<usize>,
    ) -> u64 {
        self.write_level(queue, tex, 0, side, data, rows)
    }

    fn write_level(
        &self,
        queue: &wgpu::Queue,
        tex: &wgpu::Texture,
        level: u32,
        side: usize,
        data: &[f32],
        rows: Range<usize>,
    ) -> u64 {
        if rows.is_empty() || data.len() != side * side || rows.end > side {
            return 0;
        }
        let bytes: &[u8] = bytemuck::cast_slice(&data[rows.start * side..rows.end * side]);
        queue.write_texture(
            wgpu::TexelCopyTextureInfo {
                texture: tex,
                mip_level: level,
                origin: wgpu::Origin3d {
                    x: 0,
                    y: rows.start as u32,
                    z: 0,
                },
                aspect: wgpu::TextureAspect::All,
            },
            bytes,
            wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(side as u32 * 4),
                rows_per_image: None,
            },
            wgpu::Extent3d {
                width: side as u32,
                height: rows.len() as u32,
                depth_or_array_layers: 1,
            },
        );
        bytes.len() as u64
    }

    /// Uploads this frame's uniforms, patches and lines. Returns bytes sent.
    pub fn prepare(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        globals: &Globals,
        patches: &[Patch],
        lines: &[LineVertex],
    ) -> u64 {
        let mut bytes = 0u64;
        queue.write_buffer(&self.globals, 0, bytemuck::bytes_of(globals));
        bytes += std::mem::size_of::<Globals>() as u64;
        if patches.len() > self.instance_capacity {
            self.instance_capacity = patches.len().next_power_of_two();
            self.instances = Self::buffer(
                device,
                "editor.patches",
                self.instance_capacity * 48,
                wgpu::BufferUsages::VERTEX,
            );
        }
        let inst: Vec<PatchInstance> = patches.iter().map(PatchInstance::from).collect();
        if !inst.is_empty() {
            queue.write_buffer(&self.instances, 0, bytemuck::cast_slice(&inst));
            bytes += (inst.len() * 48) as u64;
        }
        self.instance_count = inst.len() as u32;
        if lines.len() > self.line_capacity {
            self.line_capacity = lines.len().next_power_of_two();
            self.lines = Self::buffer(
                device,
                "editor.lines",
                self.line_capacity * 28,
                wgpu::BufferUsages::VERTEX,
            );
        }
        if !lines.is_empty() {
            queue.write_buffer(&self.lines, 0, bytemuck::cast_slice(lines));
            bytes += std::mem::size_of_val(lines) as u64;
        }
        self.line_count = lines.len() as u32;
        bytes
    }

    /// Records the 3D view into `pass`.
    pub fn draw(&self, pass: &mut wgpu::RenderPass<'_>) {
        if self.instance_count > 0 {
            pass.set_pipeline(&self.terrain_pipeline);
            pass.set_bind_group(0, &self.bind_group, &[]);
            pass.set_vertex_buffer(0, self.instances.slice(..));
            pass.set_index_buffer(self.index_buffer.slice(..), wgpu::IndexFormat::Uint32);
            pass.draw_indexed(0..self.index_count, 0, 0..self.instance_count);
        }
        if self.line_count > 0 {
            pass.set_pipeline(&self.line_pipeline);
            pass.set_bind_group(0, &self.line_bind_group, &[]);
            pass.set_vertex_buffer(0, self.lines.slice(..));
            pass.draw(0..self.line_count, 0..1);
        }
    }

    /// Cells per patch side.
    pub fn leaf_cells(&self) -> u32 {
        self.leaf_cells
    }
}

/// Builds `Globals` for a frame.
#[allow(clippy::too_many_arguments)] // one per uniform group, as the shader reads them
pub fn globals(
    clip_from_world: Mat4,
    eye_m: Vec3,
    extent_m: [f32; 2],
    side: u32,
    leaf_cells: u32,
    z_range: [f32; 2],
    flags: u32,
    seed: u64,
) -> Globals {
    use terrasketch_detail::calibration::{BILLOW_MEAN, HURST, REFERENCE_WAVELENGTH_M};
    let cell_m = terrasketch_detail::cell_min_wavelength_m(
        side.max(1) as usize,
        [f64::from(extent_m[0]), f64::from(extent_m[1])],
    );
    let light = Vec3::new(-0.5, -0.4, 0.75).normalize();
    let relief = (z_range[1] - z_range[0]).max(1.0);
    let contour = 10f32.powf((relief / 10.0).log10().floor()).max(1.0);
    Globals {
        clip_from_world: clip_from_world.to_cols_array_2d(),
        eye_m: eye_m.extend(1.0).to_array(),
        light_dir: light.extend(0.0).to_array(),
        extent_m,
        leaf_cells,
        coarsest_mip: side.trailing_zeros(),
        height_min_m: z_range[0],
        height_max_m: z_range[1],
        contour_interval_m: contour,
        flags,
        heightmap_side: side,
        seed32: terrasketch_detail::seed32(seed),
        amplitude_side: terrasketch_detail::amplitude_side(side as usize) as u32,
        _pad: 0,
        detail_shape: [HURST, REFERENCE_WAVELENGTH_M, BILLOW_MEAN, cell_m],
    }
}
