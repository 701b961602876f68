//! The GPU solver's memory at any size (lavapipe's 128 MiB binding limit stops it above 4096^2),
//! from the same buffer list the allocation uses (`gpu::allocated_sizes`: without
//! edge-difference buffers, the heights' `f` in their own `p` and their `h` in mip 0 of the height
//! texture, the gradient field and roughness on
//! the heights' coarse levels and with their level-0 buffers, but roughness's `h`, inside the
//! heights' (`gpu::borrowed_level0`), as `GpuSolver::new` allocates them), per part.
//! Usage: `gpu_budget [SIZE]` (default 4096). Leaves out the few KB of parameter tables, the
//! rasteriser's geometry and stats and the status words. Listed with 0 bytes, as they live in
//! other buffers (see `Buffers` in `gpu::resources`): the rasteriser's `vy` (heights' `diag`), the
//! mips' constraint pyramid (heights' `weight`). No solver has a level-0 `q` (FCG recomputes
//! `q = A p` where it reads it), level-1 stencils (the level-1 passes compute them from the
//! level-0 diagonal) or level-0 roughness maps (the rasteriser writes the roughness problem on
//! level 2). 4096^2: 1022.1 MB with `q`, 955.0 MB without, 887.9 MB with the coarse stencils in
//! 24-byte records instead of 36, 843.1 MB with the constraint pyramid in a dead level-0 buffer,
//! 776.0 MB with the heights' `f` in their `p` (the roughness maps packed as 16-bit pairs to make
//! room), 742.5 MB with level 1's `u` and `f` in the heights' `value` and `weight`, 641.8 MB
//! without level-1 stencils, 574.7 MB with the heights' `h` in the height texture, 580.3 MB with
//! the inputs of the coarse tile sweeps (`alt`, level 1's in the heights' `weight`).
use terrasketch_multigrid::gpu::mips::{constraint_offsets, min_max_offsets};
use terrasketch_multigrid::gpu::{allocated_sizes, borrowed_level0};

fn main() {
    let n: usize = std::env::args()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(4096);
    if !n.is_power_of_two() || !(16..=16384).contains(&n) {
        eprintln!("gpu_budget: SIZE must be a power of two in 16..=16384");
        std::process::exit(2);
    }
    let mb = |b: u64| b as f64 / 1e6;
    let mut total = 0u64;
    let mut line = |what: &str, bytes: u64| {
        total += bytes;
        println!("{what:<44} {:>9.1} MB", mb(bytes));
    };
    // As `GpuSolver::new` allocates them: no solver has edge-difference buffers (the heights compute
    // theirs inside the assembly from the gradient solutions listed below).
    // The gradient field and roughness own no coarse levels: theirs are the heights' (shown as 0);
    // their level-0 buffers but roughness's `h` are ranges of the heights' level-0 buffers.
    for (name, side, shift) in [
        ("heights", n, 0),
        ("gradient field", n / 2, 1),
        ("roughness", n / 4, 2),
    ] {
        let shares_coarse = shift > 0;
        let borrowed = borrowed_level0(shift);
        let sizes = allocated_sizes(side, false, shares_coarse, &borrowed);
        let level0: u64 = sizes
            .iter()
            .filter(|(l, _)| l.ends_with(".l0"))
            .map(|(_, b)| b)
            .sum();
        let stencils: u64 = sizes
            .iter()
            .filter(|(l, _)| l.contains(".stencil."))
            .map(|(_, b)| b)
            .sum();
        let all: u64 = sizes.iter().map(|(_, b)| b).sum();
        let count = sizes.iter().filter(|(l, _)| l.ends_with(".l0")).count();
        line(
            &format!("{name} ({side}^2): {count} level-0 buffers"),
            level0,
        );
        if shift == 0 {
            line("heights: f, level-1 u, f: in dead buffers", 0);
            line("heights: h: the height texture's mip 0", 0);
        } else {
            line(
                &format!("{name}: {} level-0 in the heights'", borrowed.len()),
                0,
            );
        }
        if shares_coarse {
            line(
                &format!("{name}: coarse levels: the heights'"),
                all - level0,
            );
        } else {
            line(
                &format!("{name}: stencils of levels 2.. (24 B/cell)"),
                stencils,
            );
            line(
                &format!("{name}: coarse u, f, reductions"),
                all - level0 - stencils,
            );
        }
    }
    let texture: u64 = (0..=n.trailing_zeros())
        .map(|k| ((n >> k) * (n >> k) * 4) as u64)
        .sum();
    line("height texture, full mip chain", texture);
    let c = constraint_offsets(n);
    let m = min_max_offsets(n);
    // `GpuMips::in_weight_of`: the constraint pyramid is the first 2/3 of the heights' `weight`.
    assert!(c[c.len() - 1] * 8 <= n * n * 4);
    line("mip constraint pyramid: heights' weight", 0);
    line("min/max pyramid", (m[m.len() - 1] * 8) as u64);
    line(
        "gradient solutions gx, gy (level 1)",
        (2 * (n / 2) * (n / 2) * 4) as u64,
    );
    line("level-1 stencils: computed from diag", 0);
    line("rasteriser's vy: heights' diag", 0);
    line("fields' z: heights' stencil.l2", 0);
    println!("{:<44} {:>9.1} MB", format!("total at {n}^2"), mb(total));
}
