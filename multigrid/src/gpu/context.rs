//! Device acquisition, kept apart from the GPU work (the editor can share its own device).

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};

use super::GpuError;
use super::shaders::Kernel;

/// A device and queue the solver runs on.
#[derive(Clone, Debug)]
pub struct GpuContext {
    /// The device.
    pub device: wgpu::Device,
    /// Its queue.
    pub queue: wgpu::Queue,
    /// What the adapter is (name, backend, device type).
    pub adapter_info: wgpu::AdapterInfo,
    /// Errors that escaped every error scope (only on devices made by [`GpuContext::new`]).
    uncaptured: Arc<Mutex<Vec<String>>>,
    /// What the solver did with the device since creation (see [`GpuCounters`]).
    counts: Arc<Counts>,
}

/// Number of kernels (`Kernel as usize` indexes the per-kernel counts).
const KERNELS: usize = Kernel::ALL.len();

/// The atomic counts behind [`GpuCounters`]: the totals in the order of its fields, and per kernel
/// the dispatches and estimated bytes.
#[derive(Debug)]
struct Counts {
    totals: [AtomicU64; 6],
    by_kernel: [[AtomicU64; 2]; KERNELS],
}

impl Default for Counts {
    fn default() -> Counts {
        Counts {
            totals: Default::default(),
            by_kernel: std::array::from_fn(|_| Default::default()),
        }
    }
}

impl Counts {
    /// The counts as they stand.
    fn snapshot(&self) -> GpuCounters {
        let at = |i: usize| self.totals[i].load(Ordering::Relaxed);
        let per = |j: usize| -> [u64; KERNELS] {
            std::array::from_fn(|k| self.by_kernel[k][j].load(Ordering::Relaxed))
        };
        GpuCounters {
            bytes_up: at(UP),
            bytes_read_back: at(DOWN),
            dispatches: at(DISPATCHES),
            submits: at(SUBMITS),
            blocking_waits: at(WAITS),
            bytes_moved_estimate: at(MOVED),
            by_pass: PassCounts {
                dispatches: per(0),
                bytes: per(1),
            },
        }
    }
}

/// Dispatches and estimated bytes moved per kernel (a breakdown of [`GpuCounters::dispatches`] and
/// [`GpuCounters::bytes_moved_estimate`]).
#[derive(Clone, Copy, PartialEq, Eq)]
pub struct PassCounts {
    dispatches: [u64; KERNELS],
    bytes: [u64; KERNELS],
}

impl Default for PassCounts {
    fn default() -> PassCounts {
        PassCounts {
            dispatches: [0; KERNELS],
            bytes: [0; KERNELS],
        }
    }
}

/// The kernels that ran, by name: `{name: (dispatches, bytes)}`.
impl std::fmt::Debug for PassCounts {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_map()
            .entries(
                self.nonzero()
                    .into_iter()
                    .map(|(k, d, b)| (k.name(), (d, b))),
            )
            .finish()
    }
}

impl PassCounts {
    /// Dispatches and estimated bytes of kernel `k`.
    pub fn of(&self, k: Kernel) -> (u64, u64) {
        (self.dispatches[k as usize], self.bytes[k as usize])
    }

    /// `(kernel, dispatches, bytes)` of every kernel that was dispatched or moved bytes, most
    /// bytes first.
    pub fn nonzero(&self) -> Vec<(Kernel, u64, u64)> {
        let mut v: Vec<_> = Kernel::ALL
            .into_iter()
            .map(|k| {
                let (d, b) = self.of(k);
                (k, d, b)
            })
            .filter(|&(_, d, b)| d > 0 || b > 0)
            .collect();
        v.sort_by_key(|&(k, _, b)| (std::cmp::Reverse(b), k.name()));
        v
    }

    fn since(&self, earlier: &PassCounts) -> PassCounts {
        PassCounts {
            dispatches: std::array::from_fn(|i| self.dispatches[i] - earlier.dispatches[i]),
            bytes: std::array::from_fn(|i| self.bytes[i] - earlier.bytes[i]),
        }
    }
}

/// What the solver code did with a device: the figures a GPU's time is estimated from where none
/// can be timed (ALGORITHM.md's paper model). Take differences of two readings to count a span.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct GpuCounters {
    /// Bytes written to the device (`queue.write_buffer` data).
    pub bytes_up: u64,
    /// Bytes read back from the device (mapped staging bytes).
    pub bytes_read_back: u64,
    /// Compute dispatches recorded.
    pub dispatches: u64,
    /// `queue.submit` calls.
    pub submits: u64,
    /// Blocking waits for the device (`poll` until a read-back is mapped): each drains the queue.
    pub blocking_waits: u64,
    /// Estimated bytes the dispatches moved (from each pass's bindings, see
    /// `kernels::bytes_moved_estimate`): device memory traffic where no GPU can be timed.
    pub bytes_moved_estimate: u64,
    /// `dispatches` and `bytes_moved_estimate` per kernel.
    pub by_pass: PassCounts,
}

impl GpuCounters {
    /// The counts from `earlier` to `self`.
    pub fn since(&self, earlier: &GpuCounters) -> GpuCounters {
        GpuCounters {
            bytes_up: self.bytes_up - earlier.bytes_up,
            bytes_read_back: self.bytes_read_back - earlier.bytes_read_back,
            dispatches: self.dispatches - earlier.dispatches,
            submits: self.submits - earlier.submits,
            blocking_waits: self.blocking_waits - earlier.blocking_waits,
            bytes_moved_estimate: self.bytes_moved_estimate - earlier.bytes_moved_estimate,
            by_pass: self.by_pass.since(&earlier.by_pass),
        }
    }
}

/// A reference GPU of the paper model (`GpuCounters::paper_model_ms`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReferenceGpu {
    /// Name in reports.
    pub name: &'static str,
    /// Device memory bandwidth, bytes per second.
    pub bandwidth_bytes_per_s: f64,
    /// Launch cost of one dispatch on the device, microseconds.
    pub launch_us: f64,
    /// One blocking round trip (submit, drain, map), milliseconds.
    pub round_trip_ms: f64,
}

/// A mid-range GPU of today: 450 GB/s, 5 us a dispatch, 0.3 ms a blocking round trip.
pub const MID_RANGE_GPU: ReferenceGpu = ReferenceGpu {
    name: "mid_range",
    bandwidth_bytes_per_s: 450e9,
    launch_us: 5.0,
    round_trip_ms: 0.3,
};

/// An H100-class GPU: 3 TB/s, 4 us a dispatch, 0.15 ms a blocking round trip.
pub const H100_CLASS_GPU: ReferenceGpu = ReferenceGpu {
    name: "h100_class",
    bandwidth_bytes_per_s: 3e12,
    launch_us: 4.0,
    round_trip_ms: 0.15,
};

/// CPU time to encode one dispatch (wgpu and the driver), microseconds.
pub const ENCODE_US_PER_DISPATCH: f64 = 4.0;

impl GpuCounters {
    /// The paper model's time for what was counted on `gpu`, milliseconds. The device's part is its
    /// launches, the bytes over the bandwidth and the blocking round trips. The CPU's encoding adds
    /// to it in a span that waits for the device (the CPU idles through the wait, the device through
    /// the encoding). A span with no blocking wait, one of a stream such as the editor's frames, is
    /// encoded while the device still runs the span before it, so it costs the larger of the two.
    pub fn paper_model_ms(&self, gpu: &ReferenceGpu) -> f64 {
        let d = self.dispatches as f64;
        let device = d * gpu.launch_us * 1e-3
            + self.bytes_moved_estimate as f64 / gpu.bandwidth_bytes_per_s * 1e3
            + self.blocking_waits as f64 * gpu.round_trip_ms;
        let encode = d * ENCODE_US_PER_DISPATCH * 1e-3;
        if self.blocking_waits == 0 {
            device.max(encode)
        } else {
            device + encode
        }
    }
}

/// Indices into `Counts::totals`.
const UP: usize = 0;
const DOWN: usize = 1;
const DISPATCHES: usize = 2;
const SUBMITS: usize = 3;
const WAITS: usize = 4;
const MOVED: usize = 5;

/// Counts dispatches into a context's counters (held by pass tables, which record dispatches without
/// the context at hand).
#[derive(Clone, Debug)]
pub(crate) struct DispatchCounter(Arc<Counts>);

impl DispatchCounter {
    /// Counts one dispatch of `kernel` that moves about `bytes`.
    pub(crate) fn count(&self, kernel: Kernel, bytes: u64) {
        self.0.totals[DISPATCHES].fetch_add(1, Ordering::Relaxed);
        self.0.totals[MOVED].fetch_add(bytes, Ordering::Relaxed);
        let k = &self.0.by_kernel[kernel as usize];
        k[0].fetch_add(1, Ordering::Relaxed);
        k[1].fetch_add(bytes, Ordering::Relaxed);
    }
}

/// "name (backend, device type)" of an adapter, as listed in [`GpuError::NoAdapter`].
fn describe(info: &wgpu::AdapterInfo) -> String {
    format!("{} ({:?}, {:?})", info.name, info.backend, info.device_type)
}

impl GpuContext {
    /// Opens a device: instance options from the environment (`WGPU_BACKEND`, ...), the adapter named by
    /// `WGPU_ADAPTER_NAME` or the default one, the limits from [`GpuContext::required_limits`].
    /// Fails with [`GpuError::NoAdapter`] (listing the adapters seen) when there is none.
    pub fn new() -> Result<GpuContext, GpuError> {
        pollster::block_on(Self::new_async())
    }

    async fn new_async() -> Result<GpuContext, GpuError> {
        let instance =
            wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
        let seen: Vec<String> = instance
            .enumerate_adapters(wgpu::Backends::all())
            .await
            .iter()
            .map(|a| describe(&a.get_info()))
            .collect();
        // `initialize_adapter_from_env` panics when WGPU_ADAPTER_NAME matches nothing: check first.
        if let Ok(wanted) = std::env::var("WGPU_ADAPTER_NAME") {
            let wanted = wanted.to_lowercase();
            if !seen.iter().any(|s| s.to_lowercase().contains(&wanted)) {
                return Err(GpuError::NoAdapter { seen });
            }
        }
        let adapter = wgpu::util::initialize_adapter_from_env_or_default(&instance, None)
            .await
            .map_err(|_| GpuError::NoAdapter { seen })?;
        let adapter_info = adapter.get_info();
        let (device, queue) = adapter
            .request_device(&wgpu::DeviceDescriptor {
                label: Some("multigrid.device"),
                required_features: wgpu::Features::empty(),
                required_limits: Self::required_limits(&adapter.limits()),
                experimental_features: wgpu::ExperimentalFeatures::disabled(),
                memory_hints: wgpu::MemoryHints::Performance,
                trace: wgpu::Trace::Off,
            })
            .await
            .map_err(|source| GpuError::RequestDevice {
                adapter: describe(&adapter_info),
                source,
            })?;
        let uncaptured = Arc::new(Mutex::new(Vec::new()));
        let sink = uncaptured.clone();
        device.on_uncaptured_error(Arc::new(move |e: wgpu::Error| {
            if let Ok(mut v) = sink.lock() {
                v.push(e.to_string());
            }
        }));
        Ok(GpuContext {
            device,
            queue,
            adapter_info,
            uncaptured,
            counts: Arc::default(),
        })
    }

    /// Wraps a device the caller already has (the editor's). The solver checks its limits before
    /// allocating; request them with [`GpuContext::required_limits`]. Errors are caught with error
    /// scopes; the device's uncaptured-error handler is left alone.
    pub fn from_parts(
        device: wgpu::Device,
        queue: wgpu::Queue,
        adapter_info: wgpu::AdapterInfo,
    ) -> GpuContext {
        GpuContext {
            device,
            queue,
            adapter_info,
            uncaptured: Arc::new(Mutex::new(Vec::new())),
            counts: Arc::default(),
        }
    }

    /// Bytes the solver code wrote to the device (`queue.write_buffer` data) and read back from it
    /// (mapped staging bytes) through this context and its clones, since it was made. Callers take
    /// differences to count per frame.
    pub fn traffic(&self) -> (u64, u64) {
        let c = self.counters();
        (c.bytes_up, c.bytes_read_back)
    }

    /// Everything counted through this context and its clones since it was made.
    pub fn counters(&self) -> GpuCounters {
        self.counts.snapshot()
    }

    /// Counts `bytes` sent to the device.
    pub(crate) fn count_up(&self, bytes: u64) {
        self.counts.totals[UP].fetch_add(bytes, Ordering::Relaxed);
    }

    /// Counts `bytes` read back from the device.
    pub(crate) fn count_down(&self, bytes: u64) {
        self.counts.totals[DOWN].fetch_add(bytes, Ordering::Relaxed);
    }

    /// Counts the bytes moved by gated dispatches once they are known to have run, per kernel.
    pub(crate) fn count_moved(&self, bytes: &[(Kernel, u64)]) {
        for &(k, b) in bytes {
            self.counts.totals[MOVED].fetch_add(b, Ordering::Relaxed);
            self.counts.by_kernel[k as usize][1].fetch_add(b, Ordering::Relaxed);
        }
    }

    /// The dispatch counter, for the pass tables that record dispatches.
    pub(crate) fn dispatch_counter(&self) -> DispatchCounter {
        DispatchCounter(self.counts.clone())
    }

    /// Submits `buffers` to the queue, counted.
    pub(crate) fn submit(&self, buffers: impl IntoIterator<Item = wgpu::CommandBuffer>) {
        self.counts.totals[SUBMITS].fetch_add(1, Ordering::Relaxed);
        self.queue.submit(buffers);
    }

    /// Waits until the device has finished all submitted work (a blocking wait, counted).
    pub(crate) fn wait_idle(&self) -> Result<(), wgpu::PollError> {
        self.counts.totals[WAITS].fetch_add(1, Ordering::Relaxed);
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map(|_| ())
    }

    /// Runs the callbacks of finished device work without waiting (not a blocking wait).
    pub(crate) fn poll_nonblocking(&self) -> Result<(), wgpu::PollError> {
        self.device.poll(wgpu::PollType::Poll).map(|_| ())
    }

    /// The limits the solver asks for: WebGPU defaults, with the storage-buffer binding size and the
    /// buffer size raised to the adapter's maxima (large grids need large level-0 and stencil buffers).
    pub fn required_limits(adapter: &wgpu::Limits) -> wgpu::Limits {
        wgpu::Limits {
            max_storage_buffer_binding_size: adapter.max_storage_buffer_binding_size,
            max_buffer_size: adapter.max_buffer_size,
            ..wgpu::Limits::default()
        }
    }

    /// Runs `work` inside validation and out-of-memory error scopes; any error wgpu reports during it
    /// (or that escaped to the uncaptured handler) becomes a [`GpuError`] naming `context`.
    pub fn checked<T>(
        &self,
        context: &str,
        work: impl FnOnce() -> Result<T, GpuError>,
    ) -> Result<T, GpuError> {
        let oom = self.device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
        let validation = self.device.push_error_scope(wgpu::ErrorFilter::Validation);
        let result = work();
        let v = pollster::block_on(validation.pop());
        let o = pollster::block_on(oom.pop());
        if let Some(e) = v {
            return Err(GpuError::Validation {
                context: context.to_string(),
                message: e.to_string(),
            });
        }
        if let Some(e) = o {
            return Err(GpuError::OutOfMemory {
                context: context.to_string(),
                message: e.to_string(),
            });
        }
        if let Some(msg) = self
            .uncaptured
            .lock()
            .ok()
            .and_then(|mut v| v.drain(..).next())
        {
            return Err(GpuError::Validation {
                context: context.to_string(),
                message: msg,
            });
        }
        result
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kernels_index_their_counts_one_to_one() {
        let mut seen = [false; KERNELS];
        for k in Kernel::ALL {
            assert!(
                !std::mem::replace(&mut seen[k as usize], true),
                "{}",
                k.name()
            );
        }
    }

    #[test]
    fn dispatches_and_bytes_add_up_per_kernel() {
        let counts = Arc::new(Counts::default());
        let d = DispatchCounter(counts.clone());
        d.count(Kernel::FcgUpdate, 100);
        d.count(Kernel::DotPartial, 30);
        d.count(Kernel::FcgUpdate, 0);
        let c = counts.snapshot();
        assert_eq!(
            c.by_pass.nonzero(),
            vec![(Kernel::FcgUpdate, 2, 100), (Kernel::DotPartial, 1, 30)]
        );
        assert_eq!((c.dispatches, c.bytes_moved_estimate), (3, 130));
        assert_eq!(c.since(&c).by_pass, PassCounts::default());
    }

    #[test]
    fn the_paper_model_adds_launches_bytes_waits_and_encoding() {
        let c = GpuCounters {
            dispatches: 1000,
            blocking_waits: 10,
            bytes_moved_estimate: 450_000_000,
            ..GpuCounters::default()
        };
        // 5 ms of launches, 1 ms of bytes, 3 ms of round trips, 4 ms of encoding.
        assert!((c.paper_model_ms(&MID_RANGE_GPU) - 13.0).abs() < 1e-9);
        // 4 + 0.15 + 1.5 + 4 ms.
        assert!((c.paper_model_ms(&H100_CLASS_GPU) - 9.65).abs() < 1e-9);
    }

    #[test]
    fn a_span_without_waits_overlaps_encoding_with_the_device() {
        let mut c = GpuCounters {
            dispatches: 200,
            bytes_moved_estimate: 900_000_000,
            ..GpuCounters::default()
        };
        // Device 1 + 2 ms against 0.8 ms of encoding.
        assert!((c.paper_model_ms(&MID_RANGE_GPU) - 3.0).abs() < 1e-9);
        // Device 0.8 + 0.3 ms: the encoding's 0.8 ms is hidden too.
        assert!((c.paper_model_ms(&H100_CLASS_GPU) - 1.1).abs() < 1e-9);
        // Little work and many dispatches: the encoding is the longer part.
        c.bytes_moved_estimate = 0;
        c.dispatches = 1000;
        assert!((c.paper_model_ms(&H100_CLASS_GPU) - 4.0).abs() < 1e-9);
        // One wait: serial again.
        c.blocking_waits = 1;
        assert!((c.paper_model_ms(&H100_CLASS_GPU) - 8.15).abs() < 1e-9);
    }
}
