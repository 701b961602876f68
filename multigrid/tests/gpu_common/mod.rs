//! Shared helpers of the GPU tests: a device per test (failing, never skipping, when there is none) and
//! the test problems.
#![allow(dead_code)]

use terrasketch_multigrid::FieldProblem;
use terrasketch_multigrid::gpu::GpuContext;

/// A fresh device for one test. Panics with the adapters seen (and how to install one) when there is
/// none: a missing GPU is a failure, not a skip. Run with `WGPU_BACKEND=vulkan` on lavapipe.
pub fn device() -> GpuContext {
    match GpuContext::new() {
        Ok(ctx) => {
            eprintln!(
                "GPU test device: {} ({:?})",
                ctx.adapter_info.name, ctx.adapter_info.backend
            );
            ctx
        }
        Err(e) => panic!("GPU tests need an adapter: {e}"),
    }
}

/// A two-curve problem (a sine curve up to 1000 m and a line at 200 m, one cell
/// wide, hard), plus a soft disc (w = 0.5, E = 600) and a band of prescribed edge differences.
pub fn problem(n: usize, ax: f32, ay: f32) -> FieldProblem {
    let cells = n * n;
    let mut p = FieldProblem {
        n,
        ax,
        ay,
        weight: vec![0.0; cells],
        value: vec![0.0; cells],
        d_east: vec![0.0; cells],
        d_north: vec![0.0; cells],
    };
    for i in 0..n {
        let x = i as f32 / n as f32;
        let y = 0.5 + 0.3 * (x * 6.0).sin();
        let j = (y * n as f32) as usize;
        p.weight[j * n + i] = 1.0;
        p.value[j * n + i] = 1000.0 * (x * 3.0).sin().abs();
        let j2 = n / 5;
        p.weight[j2 * n + i] = 1.0;
        p.value[j2 * n + i] = 200.0;
    }
    let (cx, cy, rad) = (0.72 * n as f32, 0.32 * n as f32, 0.07 * n as f32);
    for j in 0..n {
        for i in 0..n {
            let idx = j * n + i;
            let (dx, dy) = (i as f32 + 0.5 - cx, j as f32 + 0.5 - cy);
            if dx * dx + dy * dy < rad * rad && p.weight[idx] < 1.0 {
                p.weight[idx] = 0.5;
                p.value[idx] = 600.0;
            }
            // A gradient band: rising 3 m per cell eastwards, falling 1.5 m per cell northwards.
            if (8 * n / 10..9 * n / 10).contains(&j) && (n / 10..6 * n / 10).contains(&i) {
                p.d_east[idx] = 3.0;
                p.d_north[idx] = -1.5;
            }
        }
    }
    p
}

/// `max |a - b|`.
pub fn max_diff(a: &[f32], b: &[f32]) -> f32 {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f32::max)
}
