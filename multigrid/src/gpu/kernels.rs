//! Pipelines (one per `.wgsl` file, explicit layouts from [`Kernel::bindings`]) and pass tables: every
//! distinct (kernel, level, variant) a plan can name gets its parameter block in one uniform "arena" and
//! its bind group, both made once.

use std::collections::HashMap;
use std::hash::Hash;

use super::GpuContext;
use super::params::Params;
use super::shaders::{Binding, Kernel};
use super::slice::Slice;

/// Compute pipelines and their bind group layouts.
pub(crate) struct Pipelines {
    map: HashMap<Kernel, (wgpu::BindGroupLayout, wgpu::ComputePipeline)>,
}

impl Pipelines {
    /// Builds the pipelines of `kernels`.
    pub fn new(ctx: &GpuContext, kernels: &[Kernel]) -> Pipelines {
        let mut map = HashMap::new();
        for &k in kernels {
            let label = format!("multigrid.{}", k.name());
            let mut entries = vec![wgpu::BindGroupLayoutEntry {
                binding: 0,
                visibility: wgpu::ShaderStages::COMPUTE,
                ty: wgpu::BindingType::Buffer {
                    ty: wgpu::BufferBindingType::Uniform,
                    has_dynamic_offset: false,
                    min_binding_size: wgpu::BufferSize::new(std::mem::size_of::<Params>() as u64),
                },
                count: None,
            }];
            for (i, b) in k.bindings().iter().enumerate() {
                let ty = match b {
                    Binding::Read | Binding::ReadWrite => wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Storage {
                            read_only: *b == Binding::Read,
                        },
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                    Binding::Texture => wgpu::BindingType::Texture {
                        sample_type: wgpu::TextureSampleType::Float { filterable: false },
                        view_dimension: wgpu::TextureViewDimension::D2,
                        multisampled: false,
                    },
                    Binding::StorageTextureR32Write => wgpu::BindingType::StorageTexture {
                        access: wgpu::StorageTextureAccess::WriteOnly,
                        format: wgpu::TextureFormat::R32Float,
                        view_dimension: wgpu::TextureViewDimension::D2,
                    },
                    // R32Float read-write storage is core WebGPU (no feature needed).
                    Binding::StorageTextureR32ReadWrite => wgpu::BindingType::StorageTexture {
                        access: wgpu::StorageTextureAccess::ReadWrite,
                        format: wgpu::TextureFormat::R32Float,
                        view_dimension: wgpu::TextureViewDimension::D2,
                    },
                };
                entries.push(wgpu::BindGroupLayoutEntry {
                    binding: i as u32 + 1,
                    visibility: wgpu::ShaderStages::COMPUTE,
                    ty,
                    count: None,
                });
            }
            let bgl = ctx
                .device
                .create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                    label: Some(&label),
                    entries: &entries,
                });
            let layout = ctx
                .device
                .create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                    label: Some(&label),
                    bind_group_layouts: &[Some(&bgl)],
                    immediate_size: 0,
                });
            let module = ctx
                .device
                .create_shader_module(wgpu::ShaderModuleDescriptor {
                    label: Some(&label),
                    source: wgpu::ShaderSource::Wgsl(k.source().into()),
                });
            let pipeline = ctx
                .device
                .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                    label: Some(&label),
                    layout: Some(&layout),
                    module: &module,
                    entry_point: Some("main"),
                    compilation_options: Default::default(),
                    cache: None,
                });
            map.insert(k, (bgl, pipeline));
        }
        Pipelines { map }
    }

    fn get(&self, k: Kernel) -> &(wgpu::BindGroupLayout, wgpu::ComputePipeline) {
        self.map
            .get(&k)
            .unwrap_or_else(|| panic!("pipeline {} was not built", k.name()))
    }
}

/// A resource bound after the params block, in the order of [`Kernel::bindings`].
pub(crate) enum Res<'a> {
    /// A whole buffer.
    Buffer(&'a wgpu::Buffer),
    /// A range of a buffer (offset aligned to `min_storage_buffer_offset_alignment`).
    Slice(&'a Slice),
    /// A texture view.
    View(&'a wgpu::TextureView),
    /// A texture view the pass binds but does not access in its mode (counted as a stub buffer's
    /// 256 bytes by the byte estimate).
    UnreadView(&'a wgpu::TextureView),
    /// A range made for this pass (e.g. several levels' vectors as one).
    Owned(Slice),
}

impl<'a> From<&'a wgpu::Buffer> for Res<'a> {
    fn from(b: &'a wgpu::Buffer) -> Res<'a> {
        Res::Buffer(b)
    }
}

impl<'a> From<&'a Slice> for Res<'a> {
    fn from(s: &'a Slice) -> Res<'a> {
        Res::Slice(s)
    }
}

/// Everything about one pass but its encoding.
pub(crate) struct PassSpec<'a, K> {
    /// The key plans use.
    pub key: K,
    /// The kernel.
    pub kernel: Kernel,
    /// Its parameters.
    pub params: Params,
    /// Its resources (bindings 1..).
    pub resources: Vec<Res<'a>>,
    /// Workgroups to dispatch.
    pub workgroups: [u32; 3],
    /// Label, e.g. "multigrid.smooth_coarse.l3.c2".
    pub label: String,
}

struct Entry {
    kernel: Kernel,
    /// Estimated bytes the dispatch moves (`bytes_moved_estimate`).
    bytes_moved: u64,
    bind_group: wgpu::BindGroup,
    workgroups: [u32; 3],
    /// The dispatch's debug group (debug builds only).
    #[cfg_attr(not(debug_assertions), allow(dead_code))]
    label: String,
}

/// Threads of a workgroup in every kernel but the dot-product reductions and `fcg_update` (8 x 8).
const THREADS_PER_GROUP: u64 = 64;

/// Texels a pass's texture binding covers: one per thread, but `fcg_update`'s threads stride over
/// all `params.n^2` cells of its level.
fn texels_covered<K>(s: &PassSpec<'_, K>) -> u64 {
    if s.kernel.base().0 == Kernel::FcgUpdate {
        let n = s.params.n as u64;
        return n * n;
    }
    let [x, y, z] = s.workgroups;
    x as u64 * y as u64 * z as u64 * THREADS_PER_GROUP
}

/// What the byte estimate counts for a [`Res::UnreadView`]: as much as a stub buffer binding.
const UNREAD_VIEW_BYTES: u64 = 256;

/// Estimated bytes a pass moves, from its bindings: each bound buffer range once if read-only,
/// twice if read-write (read and written); each texture one texel per thread (twice if read-write).
/// An estimate for comparing plans, not a measurement: a red-black colour touches half of what it
/// binds, and caches may serve repeated reads.
fn bytes_moved_estimate<K>(s: &PassSpec<'_, K>) -> u64 {
    let texels = 4 * texels_covered(s);
    s.kernel
        .bindings()
        .iter()
        .zip(&s.resources)
        .map(|(b, r)| {
            let range = match r {
                Res::Buffer(buf) => buf.size(),
                Res::Slice(sl) => sl.size,
                Res::Owned(sl) => sl.size,
                Res::View(_) => texels,
                Res::UnreadView(_) => UNREAD_VIEW_BYTES,
            };
            match b {
                Binding::Read | Binding::Texture | Binding::StorageTextureR32Write => range,
                Binding::ReadWrite | Binding::StorageTextureR32ReadWrite => 2 * range,
            }
        })
        .sum()
}

/// A buffer range as a binding.
fn slice_binding(s: &Slice) -> wgpu::BindingResource<'_> {
    wgpu::BindingResource::Buffer(wgpu::BufferBinding {
        buffer: &s.buffer,
        offset: s.offset,
        size: wgpu::BufferSize::new(s.size),
    })
}

/// The bind groups and parameter blocks of a set of passes.
pub(crate) struct PassTable<K> {
    entries: HashMap<K, Entry>,
    dispatches: super::context::DispatchCounter,
    /// Bytes of the params arena.
    pub bytes: u64,
    _arena: wgpu::Buffer,
}

/// Stride of one params block in the arena.
pub(crate) fn params_stride(min_uniform_alignment: u32) -> u64 {
    let size = std::mem::size_of::<Params>() as u64;
    size.div_ceil(min_uniform_alignment as u64) * min_uniform_alignment as u64
}

impl<K: Hash + Eq + Clone + std::fmt::Debug> PassTable<K> {
    /// Writes every params block and makes every bind group. Panics (a bug) when a spec's resources do
    /// not match its kernel's bindings.
    pub fn new(
        ctx: &GpuContext,
        pipelines: &Pipelines,
        label: &str,
        specs: Vec<PassSpec<'_, K>>,
    ) -> PassTable<K> {
        let stride = params_stride(ctx.device.limits().min_uniform_buffer_offset_alignment);
        let bytes = stride * specs.len().max(1) as u64;
        let arena = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size: bytes,
            usage: wgpu::BufferUsages::UNIFORM,
            mapped_at_creation: true,
        });
        {
            let mut bytes = vec![0u8; bytes as usize];
            for (i, s) in specs.iter().enumerate() {
                let at = i * stride as usize;
                bytes[at..at + std::mem::size_of::<Params>()]
                    .copy_from_slice(bytemuck::bytes_of(&s.params));
            }
            let mut view = arena
                .slice(..)
                .get_mapped_range_mut()
                .expect("the params arena is mapped at creation");
            view.copy_from_slice(&bytes);
        }
        arena.unmap();
        let mut entries = HashMap::new();
        for (i, s) in specs.into_iter().enumerate() {
            assert_eq!(
                s.resources.len(),
                s.kernel.bindings().len(),
                "pass {:?}: {} resources for {} bindings",
                s.key,
                s.resources.len(),
                s.kernel.bindings().len()
            );
            let mut bind = vec![wgpu::BindGroupEntry {
                binding: 0,
                resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                    buffer: &arena,
                    offset: i as u64 * stride,
                    size: wgpu::BufferSize::new(std::mem::size_of::<Params>() as u64),
                }),
            }];
            for (b, r) in s.resources.iter().enumerate() {
                let resource = match r {
                    Res::Buffer(buf) => buf.as_entire_binding(),
                    Res::Slice(s) => slice_binding(s),
                    Res::Owned(s) => slice_binding(s),
                    Res::View(v) | Res::UnreadView(v) => wgpu::BindingResource::TextureView(v),
                };
                bind.push(wgpu::BindGroupEntry {
                    binding: b as u32 + 1,
                    resource,
                });
            }
            let bind_group = ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some(&s.label),
                layout: &pipelines.get(s.kernel).0,
                entries: &bind,
            });
            let bytes_moved = bytes_moved_estimate(&s);
            let old = entries.insert(
                s.key.clone(),
                Entry {
                    kernel: s.kernel,
                    bytes_moved,
                    bind_group,
                    workgroups: s.workgroups,
                    label: s.label,
                },
            );
            assert!(old.is_none(), "pass {:?} specified twice", s.key);
        }
        PassTable {
            entries,
            dispatches: ctx.dispatch_counter(),
            bytes,
            _arena: arena,
        }
    }

    /// Records the dispatch of pass `key` into `pass`.
    pub fn dispatch(&self, pipelines: &Pipelines, pass: &mut wgpu::ComputePass<'_>, key: &K) {
        self.record(pipelines, pass, key, None);
    }

    /// Records pass `key` with its workgroup counts read from `args` at `offset` (written on the GPU
    /// by a gate). Counted as a dispatch; its bytes are counted when it is known to have run
    /// ([`Self::bytes_moved`]).
    pub fn dispatch_indirect(
        &self,
        pipelines: &Pipelines,
        pass: &mut wgpu::ComputePass<'_>,
        key: &K,
        args: &wgpu::Buffer,
        offset: u64,
    ) {
        self.record(pipelines, pass, key, Some((args, offset)));
    }

    /// Pipeline, bind group and dispatch of pass `key`: its own workgroup counts, or those at
    /// `indirect`.
    fn record(
        &self,
        pipelines: &Pipelines,
        pass: &mut wgpu::ComputePass<'_>,
        key: &K,
        indirect: Option<(&wgpu::Buffer, u64)>,
    ) {
        let e = self
            .entries
            .get(key)
            .unwrap_or_else(|| panic!("pass {key:?} is not in the table"));
        // Debug groups name each dispatch in GPU captures; release builds record none (each is two
        // more commands per dispatch for the driver).
        #[cfg(debug_assertions)]
        pass.push_debug_group(&e.label);
        pass.set_pipeline(&pipelines.get(e.kernel).1);
        pass.set_bind_group(0, &e.bind_group, &[]);
        match indirect {
            Some((args, offset)) => {
                pass.dispatch_workgroups_indirect(args, offset);
                self.dispatches.count(e.kernel, 0);
            }
            None => {
                let [x, y, z] = e.workgroups;
                pass.dispatch_workgroups(x, y, z);
                self.dispatches.count(e.kernel, e.bytes_moved);
            }
        }
        #[cfg(debug_assertions)]
        pass.pop_debug_group();
    }

    /// The kernel of pass `key` and the bytes it is estimated to move when it runs (None for an
    /// unknown key).
    pub fn bytes_moved(&self, key: &K) -> Option<(Kernel, u64)> {
        self.entries.get(key).map(|e| (e.kernel, e.bytes_moved))
    }
}
