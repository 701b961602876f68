//! The window's GPU: instance, surface, adapter, device; surface (re)configuration that survives zero
//! sizes and lost surfaces; depth buffer; reading a frame back for screenshots.

use std::path::Path;
use std::sync::Arc;

use anyhow::{Context, Result, anyhow, bail};
use terrasketch_multigrid::gpu::GpuContext;
use winit::window::Window;

use super::render::DEPTH_FORMAT;

/// Device, queue and the window's surface.
pub struct Gpu {
    instance: wgpu::Instance,
    /// The surface (recreated if lost).
    pub surface: wgpu::Surface<'static>,
    /// The device.
    pub device: wgpu::Device,
    /// Its queue.
    pub queue: wgpu::Queue,
    /// Surface configuration (width/height 0 while minimised: not configured then).
    pub config: wgpu::SurfaceConfiguration,
    /// Depth buffer view (matches the configured size).
    pub depth: Option<wgpu::TextureView>,
    /// "name (backend, type)" of the adapter.
    pub adapter_name: String,
    /// The adapter.
    pub adapter_info: wgpu::AdapterInfo,
    /// The device has the limits the GPU solver needs.
    pub solver_ok: bool,
    /// Set by the device-lost callback.
    lost: Arc<std::sync::Mutex<Option<String>>>,
    window: Arc<Window>,
}

/// Describes an adapter for messages.
fn describe(info: &wgpu::AdapterInfo) -> String {
    format!("{} ({:?}, {:?})", info.name, info.backend, info.device_type)
}

/// The adapter wgpu picks for `surface` ($WGPU_ADAPTER_NAME and $WGPU_BACKEND respected); a
/// missing one is an error that lists what wgpu saw.
fn open_adapter(
    instance: &wgpu::Instance,
    surface: &wgpu::Surface<'static>,
) -> Result<wgpu::Adapter> {
    let seen: Vec<String> = pollster::block_on(instance.enumerate_adapters(wgpu::Backends::all()))
        .iter()
        .map(|a| describe(&a.get_info()))
        .collect();
    if let Ok(wanted) = std::env::var("WGPU_ADAPTER_NAME")
        && !seen
            .iter()
            .any(|s| s.to_lowercase().contains(&wanted.to_lowercase()))
    {
        bail!("no GPU adapter matches WGPU_ADAPTER_NAME={wanted:?}; adapters seen: {seen:?}");
    }
    let adapter = pollster::block_on(wgpu::util::initialize_adapter_from_env_or_default(instance, Some(surface)))
            .map_err(|_| {
                anyhow!(
                    "no GPU adapter can draw to this window (adapters seen: {seen:?}). The editor needs a GPU \
                     or a software Vulkan driver (Debian/Ubuntu: `apt install mesa-vulkan-drivers`); the \
                     command line (`terrasketch solve`) works without one"
                )
            })?;
    Ok(adapter)
}

/// The device and queue, with the GPU solver's limits when the adapter can give them (the third
/// value says so), else the window's downlevel limits (the CPU solver then runs the terrain).
fn open_device(
    adapter: &wgpu::Adapter,
    info: &wgpu::AdapterInfo,
) -> Result<(wgpu::Device, wgpu::Queue, bool)> {
    // The solver's limits (large storage bindings) on top of what the window needs; an adapter
    // that cannot give them still draws, with the CPU solver.
    let solver_limits =
        GpuContext::required_limits(&adapter.limits()).using_resolution(adapter.limits());
    let request = |limits: wgpu::Limits| {
        pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("editor.device"),
            required_features: wgpu::Features::empty(),
            required_limits: limits,
            experimental_features: wgpu::ExperimentalFeatures::disabled(),
            memory_hints: wgpu::MemoryHints::Performance,
            trace: wgpu::Trace::Off,
        }))
    };
    let (device, queue, solver_ok) = match request(solver_limits) {
        Ok((d, q)) => (d, q, true),
        Err(e) => {
            eprintln!(
                "terrasketch: warning: {} cannot give the GPU solver its limits ({e}); using the CPU solver",
                describe(info)
            );
            let (d, q) =
                request(wgpu::Limits::downlevel_defaults().using_resolution(adapter.limits()))
                    .with_context(|| format!("cannot open the GPU device on {}", describe(info)))?;
            (d, q, false)
        }
    };
    Ok((device, queue, solver_ok))
}

/// The surface's configuration: an 8-bit BGRA or RGBA format when offered, FIFO presentation.
fn surface_config(
    surface: &wgpu::Surface<'static>,
    adapter: &wgpu::Adapter,
    info: &wgpu::AdapterInfo,
    size: winit::dpi::PhysicalSize<u32>,
) -> Result<wgpu::SurfaceConfiguration> {
    let caps = surface.get_capabilities(adapter);
    let format = caps
        .formats
        .iter()
        .copied()
        .find(|f| {
            matches!(
                f,
                wgpu::TextureFormat::Bgra8Unorm | wgpu::TextureFormat::Rgba8Unorm
            )
        })
        .or_else(|| caps.formats.first().copied())
        .ok_or_else(|| {
            anyhow!(
                "the window surface supports no format on {}",
                describe(info)
            )
        })?;
    let config = wgpu::SurfaceConfiguration {
        usage: wgpu::TextureUsages::RENDER_ATTACHMENT,
        format,
        width: size.width,
        height: size.height,
        present_mode: if caps.present_modes.contains(&wgpu::PresentMode::Fifo) {
            wgpu::PresentMode::Fifo
        } else {
            caps.present_modes
                .first()
                .copied()
                .unwrap_or(wgpu::PresentMode::Fifo)
        },
        desired_maximum_frame_latency: 2,
        alpha_mode: caps
            .alpha_modes
            .first()
            .copied()
            .unwrap_or(wgpu::CompositeAlphaMode::Auto),
        view_formats: vec![],
        color_space: Default::default(),
    };
    Ok(config)
}

impl Gpu {
    /// Opens the GPU for `window`. A missing adapter is an error that lists what wgpu saw.
    pub fn new(
        window: Arc<Window>,
        display: Box<dyn wgpu::wgt::WgpuHasDisplayHandle>,
    ) -> Result<Gpu> {
        let instance = wgpu::Instance::new(
            wgpu::InstanceDescriptor::new_with_display_handle_from_env(display),
        );
        let surface = instance
            .create_surface(window.clone())
            .context("cannot create a drawing surface for the window")?;
        let adapter = open_adapter(&instance, &surface)?;
        let info = adapter.get_info();
        let (device, queue, solver_ok) = open_device(&adapter, &info)?;
        let lost = Arc::new(std::sync::Mutex::new(None));
        let sink = lost.clone();
        device.set_device_lost_callback(move |reason, msg| {
            if let Ok(mut l) = sink.lock() {
                l.get_or_insert(format!("{reason:?}: {msg}"));
            }
        });
        // A validation error is a bug in the editor: report it, never abort the user's session on it.
        device.on_uncaptured_error(Arc::new(|e: wgpu::Error| {
            eprintln!("terrasketch: GPU error: {e}")
        }));
        let size = window.inner_size();
        let config = surface_config(&surface, &adapter, &info, size)?;
        let mut gpu = Gpu {
            instance,
            surface,
            device,
            queue,
            config,
            depth: None,
            adapter_name: describe(&info),
            adapter_info: info.clone(),
            solver_ok,
            lost,
            window,
        };
        gpu.resize(size.width, size.height);
        Ok(gpu)
    }

    /// Why the device was lost, once (None while it works).
    pub fn take_lost(&self) -> Option<String> {
        self.lost.lock().ok().and_then(|mut l| l.take())
    }

    /// The window's device as a solver context (None when it lacks the solver's limits).
    pub fn solver_context(&self) -> Option<GpuContext> {
        self.solver_ok.then(|| {
            GpuContext::from_parts(
                self.device.clone(),
                self.queue.clone(),
                self.adapter_info.clone(),
            )
        })
    }

    /// Reconfigures for a new size; a zero size (minimised) leaves the surface unconfigured.
    pub fn resize(&mut self, width: u32, height: u32) {
        self.config.width = width;
        self.config.height = height;
        if width == 0 || height == 0 {
            self.depth = None;
            return;
        }
        let max = self.device.limits().max_texture_dimension_2d;
        self.config.width = width.min(max);
        self.config.height = height.min(max);
        self.surface.configure(&self.device, &self.config);
        self.depth = Some(self.depth_view(self.config.width, self.config.height));
    }

    fn depth_view(&self, width: u32, height: u32) -> wgpu::TextureView {
        self.device
            .create_texture(&wgpu::TextureDescriptor {
                label: Some("editor.depth"),
                size: wgpu::Extent3d {
                    width,
                    height,
                    depth_or_array_layers: 1,
                },
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format: DEPTH_FORMAT,
                usage: wgpu::TextureUsages::RENDER_ATTACHMENT,
                view_formats: &[],
            })
            .create_view(&wgpu::TextureViewDescriptor::default())
    }

    /// True when there is something to draw to.
    pub fn drawable(&self) -> bool {
        self.config.width > 0 && self.config.height > 0 && self.depth.is_some()
    }

    /// The next frame, or `None` (skip this frame): outdated surfaces are reconfigured, lost ones
    /// recreated; neither is fatal.
    pub fn acquire(&mut self) -> Option<wgpu::SurfaceTexture> {
        if !self.drawable() {
            return None;
        }
        match self.surface.get_current_texture() {
            wgpu::CurrentSurfaceTexture::Success(t) => Some(t),
            wgpu::CurrentSurfaceTexture::Suboptimal(t) => {
                self.surface.configure(&self.device, &self.config);
                Some(t)
            }
            wgpu::CurrentSurfaceTexture::Outdated => {
                let size = self.window.inner_size();
                self.resize(size.width, size.height);
                None
            }
            wgpu::CurrentSurfaceTexture::Lost => {
                self.recreate_surface();
                None
            }
            _ => None,
        }
    }

    /// Recreates a lost surface.
    pub fn recreate_surface(&mut self) {
        match self.instance.create_surface(self.window.clone()) {
            Ok(s) => {
                self.surface = s;
                let size = self.window.inner_size();
                self.resize(size.width, size.height);
            }
            Err(e) => eprintln!("terrasketch: warning: cannot recreate the window surface: {e}"),
        }
    }

    /// An offscreen colour target of the surface's size and format, readable for screenshots.
    pub fn offscreen(&self) -> wgpu::Texture {
        self.device.create_texture(&wgpu::TextureDescriptor {
            label: Some("editor.screenshot"),
            size: wgpu::Extent3d {
                width: self.config.width.max(1),
                height: self.config.height.max(1),
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: self.config.format,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
            view_formats: &[],
        })
    }

    /// Reads `texture` back (rows padded to 256 bytes) and writes it as an RGBA PNG.
    pub fn save_png(&self, texture: &wgpu::Texture, path: &Path) -> Result<()> {
        let (w, h) = (texture.width(), texture.height());
        let unpadded = w * 4;
        let padded = unpadded.div_ceil(256) * 256;
        let buffer = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("editor.screenshot.readback"),
            size: (padded * h) as u64,
            usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
            mapped_at_creation: false,
        });
        let mut enc = self
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("editor.screenshot"),
            });
        enc.copy_texture_to_buffer(
            wgpu::TexelCopyTextureInfo {
                texture,
                mip_level: 0,
                origin: wgpu::Origin3d::ZERO,
                aspect: wgpu::TextureAspect::All,
            },
            wgpu::TexelCopyBufferInfo {
                buffer: &buffer,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(padded),
                    rows_per_image: Some(h),
                },
            },
            wgpu::Extent3d {
                width: w,
                height: h,
                depth_or_array_layers: 1,
            },
        );
        self.queue.submit([enc.finish()]);
        let (tx, rx) = std::sync::mpsc::channel();
        buffer.slice(..).map_async(wgpu::MapMode::Read, move |r| {
            let _ = tx.send(r);
        });
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| anyhow!("GPU wait failed: {e}"))?;
        rx.recv()
            .map_err(|_| anyhow!("screenshot read-back was cancelled"))?
            .map_err(|e| anyhow!("cannot map the screenshot: {e}"))?;
        let bgra = matches!(
            texture.format(),
            wgpu::TextureFormat::Bgra8Unorm | wgpu::TextureFormat::Bgra8UnormSrgb
        );
        let mut rgba = Vec::with_capacity((unpadded * h) as usize);
        {
            let view = buffer
                .slice(..)
                .get_mapped_range()
                .map_err(|e| anyhow!("cannot read the screenshot: {e:?}"))?;
            for row in 0..h {
                let line = &view[(row * padded) as usize..(row * padded + unpadded) as usize];
                for px in line.chunks_exact(4) {
                    if bgra {
                        rgba.extend_from_slice(&[px[2], px[1], px[0], 255]);
                    } else {
                        rgba.extend_from_slice(&[px[0], px[1], px[2], 255]);
                    }
                }
            }
        }
        buffer.unmap();
        let img = image::RgbaImage::from_raw(w, h, rgba)
            .ok_or_else(|| anyhow!("screenshot size mismatch"))?;
        img.save(path)
            .with_context(|| format!("cannot write screenshot {}", path.display()))?;
        Ok(())
    }
}
