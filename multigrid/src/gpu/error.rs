//! Errors of the GPU backend.

use thiserror::Error;

/// What can go wrong on the GPU side. Each is returned once, to the caller.
#[derive(Debug, Error)]
pub enum GpuError {
    /// No adapter could be opened.
    #[error(
        "no GPU adapter found (adapters seen: [{}]). Without a hardware GPU, install the software Vulkan \
         driver: on Debian/Ubuntu `sudo apt-get install mesa-vulkan-drivers libvulkan1`, then run with \
         `WGPU_BACKEND=vulkan` (WGPU_ADAPTER_NAME selects an adapter by name)",
        .seen.join(", ")
    )]
    NoAdapter {
        /// Every adapter the instance listed, as "name (backend, device type)".
        seen: Vec<String>,
    },
    /// The adapter refused the device request.
    #[error("could not open a device on {adapter}: {source}")]
    RequestDevice {
        /// The adapter asked.
        adapter: String,
        /// What wgpu said.
        #[source]
        source: wgpu::RequestDeviceError,
    },
    /// wgpu reported a validation error (a bug in this crate or a misuse of a shared device).
    #[error("GPU validation error in {context}: {message}")]
    Validation {
        /// The operation (label) that produced it.
        context: String,
        /// wgpu's description.
        message: String,
    },
    /// The device ran out of memory.
    #[error("GPU out of memory in {context}: {message}")]
    OutOfMemory {
        /// The operation (label) that produced it.
        context: String,
        /// wgpu's description.
        message: String,
    },
    /// The solver side is not a power of two in the supported range.
    #[error(
        "GPU solver size {n} is not supported: the side must be a power of two from {min} to {max}"
    )]
    BadSize {
        /// The refused side.
        n: usize,
        /// Smallest supported side.
        min: usize,
        /// Largest supported side.
        max: usize,
    },
    /// A buffer or dispatch of this size exceeds a device limit (checked before anything is allocated).
    #[error(
        "a {n} x {n} GPU solve needs {what} of {needed} but this device allows {limit} \
         (limit `{limit_name}`); use a smaller size or a device with larger limits"
    )]
    TooLarge {
        /// Side of the refused solve.
        n: usize,
        /// The resource, e.g. "buffer multigrid.stencil.l1".
        what: String,
        /// What it needs (bytes or workgroups).
        needed: u64,
        /// What the device allows.
        limit: u64,
        /// Name of the `wgpu::Limits` field.
        limit_name: &'static str,
    },
    /// The problem does not fit the solver (size, anisotropy or array lengths).
    #[error("the problem does not match the GPU solver: {0}")]
    ProblemMismatch(String),
    /// A level index outside the hierarchy.
    #[error("level {level} does not exist (this solver has levels 0..{levels})")]
    BadLevel {
        /// The asked level.
        level: usize,
        /// Number of levels.
        levels: usize,
    },
    /// Mapping a buffer for reading failed.
    #[error("reading back {what} failed: {message}")]
    Readback {
        /// The buffer read.
        what: String,
        /// Why.
        message: String,
    },
}
