//! Device acquisition and error capture (one test function: it changes the environment).

mod gpu_common;

use terrasketch_multigrid::gpu::{GpuContext, GpuError, GpuFieldSolver, buffer_sizes};

#[test]
fn adapters_limits_and_validation_errors() {
    // A missing adapter is an error that lists what was seen and says how to install one.
    let e = GpuError::NoAdapter {
        seen: vec!["llvmpipe (Vulkan, Cpu)".into()],
    };
    let msg = e.to_string();
    assert!(
        msg.contains("llvmpipe (Vulkan, Cpu)")
            && msg.contains("apt-get install mesa-vulkan-drivers libvulkan1")
    );
    assert!(msg.contains("WGPU_BACKEND=vulkan"));

    let saved = std::env::var("WGPU_ADAPTER_NAME").ok();
    // SAFETY: this test binary has a single test, nothing else reads the environment concurrently.
    unsafe { std::env::set_var("WGPU_ADAPTER_NAME", "no such adapter 7f3a") };
    let r = GpuContext::new();
    // SAFETY: as above.
    unsafe {
        match &saved {
            Some(v) => std::env::set_var("WGPU_ADAPTER_NAME", v),
            None => std::env::remove_var("WGPU_ADAPTER_NAME"),
        }
    }
    match r {
        Err(GpuError::NoAdapter { seen }) => {
            assert!(!seen.is_empty(), "the adapters seen must be listed")
        }
        other => panic!("expected NoAdapter, got {other:?}"),
    }

    let ctx = gpu_common::device();
    // A wgpu validation error inside a checked call becomes a GpuError.
    let r = ctx.checked("test.bad_buffer", || {
        let _b = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("test.bad_buffer"),
            size: 64,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::STORAGE,
            mapped_at_creation: false,
        });
        Ok(())
    });
    assert!(matches!(r, Err(GpuError::Validation { .. })), "{r:?}");
    // The device is still usable afterwards.
    assert!(ctx.checked("test.ok", || Ok(())).is_ok());

    // Sizes beyond the device limits are refused before allocating.
    let limit = ctx.device.limits().max_storage_buffer_binding_size;
    let biggest = |n: usize| {
        buffer_sizes(n, true)
            .into_iter()
            .map(|(_, b)| b)
            .max()
            .unwrap()
    };
    if biggest(16384) > limit {
        let e = GpuFieldSolver::new(&ctx, 16384, 1.0, 1.0)
            .err()
            .expect("16384^2 must be refused here");
        assert!(matches!(e, GpuError::TooLarge { .. }), "{e}");
    }
    assert!(matches!(
        GpuFieldSolver::new(&ctx, 96, 1.0, 1.0),
        Err(GpuError::BadSize { .. })
    ));
    // A problem of the wrong size is refused.
    let mut s = GpuFieldSolver::new(&ctx, 64, 1.0, 1.0).expect("64^2 solver");
    let p = gpu_common::problem(128, 1.0, 1.0);
    assert!(matches!(
        s.upload_problem(&p),
        Err(GpuError::ProblemMismatch(_))
    ));
    assert!(
        matches!(s.fmg(), Err(GpuError::ProblemMismatch(_))),
        "FMG before any upload"
    );
}
