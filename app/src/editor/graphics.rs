//! The editor's GPU side: the window and its device (`gpu`), the scene renderer (`render`), egui's
//! state and renderer, and the quadtree's LOD selection that feeds the renderer. What is drawn
//! comes from the document and the terrain; this type only owns the long-lived GPU objects and
//! encodes a frame.

use std::sync::Arc;

use anyhow::Result;
use terrasketch_quadtree::{Camera, LodSettings, MinMaxPyramid, Selection, select};
use winit::window::Window;

use super::camera::Projection;
use super::gpu::Gpu;
use super::render::SceneRenderer;

/// Sky colour behind the terrain.
const CLEAR: wgpu::Color = wgpu::Color {
    r: 0.62,
    g: 0.74,
    b: 0.86,
    a: 1.0,
};

/// The window, its device, the renderers and the LOD selection.
pub struct Graphics {
    /// The window drawn to.
    pub window: Arc<Window>,
    /// Device, queue, surface.
    pub gpu: Gpu,
    /// Terrain and stroke renderer.
    pub scene: SceneRenderer,
    /// egui's context and its window glue and renderer.
    pub egui_ctx: egui::Context,
    pub egui_state: egui_winit::State,
    pub egui_renderer: egui_wgpu::Renderer,
    /// The patches the quadtree selected last.
    pub selection: Selection,
    /// The quadtree's settings (leaf size, extent, pixel budget); the renderer's patch mesh takes
    /// its leaf size from here.
    pub settings: LodSettings,
}

impl Graphics {
    /// The renderers for a heightmap of side `size` over `extent_m` on `gpu`; `heightmap`: the GPU
    /// solver's texture when it runs the terrain (else the renderer makes its own).
    pub fn new(
        window: Arc<Window>,
        gpu: Gpu,
        size: usize,
        extent_m: [f64; 2],
        heightmap: Option<&wgpu::Texture>,
    ) -> Graphics {
        let settings = LodSettings::new(size, [extent_m[0] as f32, extent_m[1] as f32]);
        let scene = SceneRenderer::new(
            &gpu.device,
            gpu.config.format,
            size as u32,
            settings.leaf_cells as u32,
            heightmap,
        );
        let egui_ctx = egui::Context::default();
        let max_tex = gpu.device.limits().max_texture_dimension_2d as usize;
        let egui_state = egui_winit::State::new(
            egui_ctx.clone(),
            egui::ViewportId::ROOT,
            &window,
            Some(window.scale_factor() as f32),
            None,
            Some(max_tex),
        );
        let egui_renderer = egui_wgpu::Renderer::new(
            &gpu.device,
            gpu.config.format,
            egui_wgpu::RendererOptions::default(),
        );
        Graphics {
            window,
            gpu,
            scene,
            egui_ctx,
            egui_state,
            egui_renderer,
            selection: Selection::new(),
            settings,
        }
    }

    /// The surface's size in pixels (0 while minimised).
    pub fn surface_px(&self) -> [u32; 2] {
        [self.gpu.config.width, self.gpu.config.height]
    }

    /// A new sketch extent: the quadtree measures distances in it.
    pub fn set_extent(&mut self, extent_m: [f64; 2]) {
        self.settings.extent_m = [extent_m[0] as f32, extent_m[1] as f32];
    }

    /// Selects the patches to draw from `pyramid` seen through `proj`, no finer than mip `finest`;
    /// returns how many (an error clears the selection).
    pub fn select_patches(
        &mut self,
        pyramid: &MinMaxPyramid,
        proj: &Projection,
        finest: Option<u32>,
        pixel_budget: f32,
    ) -> Result<usize> {
        self.settings.pixel_budget = pixel_budget;
        let cam = Camera::from_matrices(
            proj.view_from_world,
            proj.clip_from_view,
            proj.viewport_px.to_array(),
        );
        let finest = finest.unwrap_or(self.settings.coarsest_mip());
        match select(pyramid, &self.settings, &cam, finest, &mut self.selection) {
            Ok(_) => Ok(self.selection.patches.len()),
            Err(e) => {
                self.selection.patches.clear();
                Err(anyhow::anyhow!("LOD selection failed: {e}"))
            }
        }
    }

    /// Encodes and submits one frame to `target`: the scene, then egui's `jobs` over it.
    pub fn encode(
        &mut self,
        target: &wgpu::TextureView,
        jobs: &[egui::ClippedPrimitive],
        screen: &egui_wgpu::ScreenDescriptor,
    ) {
        let Some(depth) = self.gpu.depth.as_ref() else {
            return;
        };
        let mut enc = self
            .gpu
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("editor.frame"),
            });
        let extra = self.egui_renderer.update_buffers(
            &self.gpu.device,
            &self.gpu.queue,
            &mut enc,
            jobs,
            screen,
        );
        {
            let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("editor.scene"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: target,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(CLEAR),
                        store: wgpu::StoreOp::Store,
                    },
                    depth_slice: None,
                })],
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view: depth,
                    depth_ops: Some(wgpu::Operations {
                        load: wgpu::LoadOp::Clear(1.0),
                        store: wgpu::StoreOp::Discard,
                    }),
                    stencil_ops: None,
                }),
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            self.scene.draw(&mut pass);
        }
        {
            let pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("editor.ui"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: target,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Load,
                        store: wgpu::StoreOp::Store,
                    },
                    depth_slice: None,
                })],
                depth_stencil_attachment: None,
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            self.egui_renderer
                .render(&mut pass.forget_lifetime(), jobs, screen);
        }
        self.gpu
            .queue
            .submit(extra.into_iter().chain([enc.finish()]));
    }
}
