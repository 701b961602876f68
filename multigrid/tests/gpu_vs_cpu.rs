//! The GPU backend against the CPU oracle (`ALGORITHM.md`): operators, FMG, FCG, warm start, mips.
//! Small grids only (lavapipe is slow); run with `WGPU_BACKEND=vulkan`.

mod gpu_common;

use gpu_common::{device, max_diff, problem};
use terrasketch_multigrid::cpu::{CycleStats, Fcg, FieldState, Hierarchy};
use terrasketch_multigrid::gpu::shaders::Kernel;
use terrasketch_multigrid::gpu::{GpuContext, GpuFieldSolver, GpuMips, mips, oracle};
use terrasketch_multigrid::{FieldProblem, SolverParams, pyramid};

/// Agreement asked by ALGORITHM.md: 1e-3 of the relief.
const REL_TOL: f32 = 1e-3;

/// Agreement of the FMG lift (no iteration, the same sums in the same order on both backends).
const LIFT_TOL: f32 = 1e-5;

/// CPU FMG as `Hierarchy::fmg` (`fmg_start`, `fmg_level` k = kc-1 .. 1, `fmg_finish`), also returning
/// the lift `g_k` of levels 1 ..= log2 n as it was during FMG. Returns (work units, lifts).
fn cpu_fmg_with_lift(
    cpu: &Hierarchy,
    st: &mut FieldState,
    params: &SolverParams,
) -> (f64, Vec<Vec<f32>>) {
    let mut scratch = Vec::new();
    let mut k = cpu.fmg_start(st, Vec::new(), &mut scratch);
    let top = cpu.n().trailing_zeros() as usize;
    let lifts: Vec<Vec<f32>> = (1..=top).map(|k| cpu.level_lift(st, k).to_vec()).collect();
    let mut wu = 0.0;
    while k >= 1 {
        wu += cpu.fmg_level(k, st, params);
        k -= 1;
    }
    cpu.fmg_finish(st);
    (wu, lifts)
}

/// The lift alone on both backends: level 0 (`h` right after `fmg_start`) and every level 1 ..= log2 n.
fn check_lift(ctx: &GpuContext, p: &FieldProblem) {
    let relief = p.relief();
    let cpu = cpu_setup(p);
    let mut st = cpu.new_state();
    let mut scratch = Vec::new();
    cpu.fmg_start(&mut st, Vec::new(), &mut scratch);
    let mut gpu = GpuFieldSolver::new(ctx, p.n, p.ax, p.ay).unwrap();
    gpu.upload_problem(p).unwrap();
    gpu.lift().unwrap();
    let g0 = gpu.read_solution().unwrap();
    let d0 = max_diff(&g0, &st.h) / relief;
    eprintln!(
        "n={} lift level 0: max |gpu - cpu| / relief = {d0:.2e}",
        p.n
    );
    assert!(
        d0 <= LIFT_TOL,
        "lift level 0 differs by {d0:.2e} of the relief"
    );
    for (i, w) in p.weight.iter().enumerate() {
        if *w >= 1.0 {
            assert_eq!(g0[i], p.value[i], "lift must hold E on hard cell {i}");
        }
    }
    let top = p.n.trailing_zeros() as usize;
    for k in 1..=top {
        let c = cpu.level_lift(&st, k);
        assert_eq!(c.len(), (p.n >> k) * (p.n >> k));
        let d = max_diff(&gpu.read_lift(k).unwrap(), c) / relief;
        eprintln!(
            "n={} lift level {k}: max |gpu - cpu| / relief = {d:.2e}",
            p.n
        );
        assert!(
            d <= LIFT_TOL,
            "lift level {k} differs by {d:.2e} of the relief"
        );
    }
    assert!(gpu.read_lift(0).is_err());
    assert!(gpu.read_lift(top + 1).is_err());
    // The lift is not constant on this problem (else the comparison above proves little).
    let (lo, hi) = g0
        .iter()
        .fold((f32::MAX, f32::MIN), |(a, b), v| (a.min(*v), b.max(*v)));
    assert!(hi - lo > 0.5 * relief, "lift range {lo} .. {hi}");
}

#[test]
fn lift_matches_cpu() {
    let ctx = device();
    check_lift(&ctx, &problem(128, 1.0, 1.0));
    check_lift(&ctx, &problem(64, 0.5, 2.0));
    // The smallest solver side: every lift level below one workgroup.
    check_lift(&ctx, &problem(16, 1.0, 1.0));
}

fn cpu_setup(p: &FieldProblem) -> Hierarchy {
    let mut h = Hierarchy::new(p.n, p.ax, p.ay);
    h.assemble(p);
    h
}

/// CPU FCG as `Hierarchy::iterate_to_tolerance`, keeping the residual history.
fn cpu_fcg(
    cpu: &Hierarchy,
    st: &mut FieldState,
    params: &SolverParams,
    max_iters: u32,
) -> (CycleStats, u32, Vec<f32>) {
    let mut fcg = Fcg::default();
    let mut wu = fcg.start(cpu, st, params);
    let mut hist = vec![fcg.residual];
    while fcg.residual > params.tolerance && fcg.iterations < max_iters {
        match fcg.iterate(cpu, st, params) {
            Some(s) => {
                wu += s.work_units;
                hist.push(s.residual);
            }
            None => break,
        }
    }
    (
        CycleStats {
            work_units: wu,
            residual: fcg.residual,
        },
        fcg.iterations,
        hist,
    )
}

/// Compares the GPU's operators with the CPU's; returns the number of inactive level-1 cells.
fn check_operators(ctx: &GpuContext, p: &FieldProblem) -> usize {
    let cpu = cpu_setup(p);
    let mut gpu = GpuFieldSolver::new(ctx, p.n, p.ax, p.ay).unwrap();
    gpu.upload_problem(p).unwrap();
    assert_eq!(gpu.levels(), cpu.levels());
    let (diag, f) = oracle::cpu_level0(&cpu);
    let gd = gpu.read_diag().unwrap();
    let gf = gpu.read_rhs(0).unwrap();
    assert!(
        gd.iter().zip(diag).all(|(g, c)| (*g == 0.0) == (*c == 0.0)),
        "hard cells differ"
    );
    let fscale = f.iter().fold(1.0f32, |m, v| m.max(v.abs()));
    assert!(
        max_diff(&gd, diag) <= 1e-6 * diag.iter().fold(0.0f32, |m, v| m.max(*v)),
        "diag differs"
    );
    assert!(
        max_diff(&gf, f) <= 1e-6 * fscale,
        "f differs by {}",
        max_diff(&gf, f)
    );
    let mut inactive1 = 0;
    for k in 1..cpu.levels() {
        let g = gpu.read_stencils(k).unwrap();
        let c = oracle::cpu_stencils(&cpu, k);
        if k == 1 {
            inactive1 = c.iter().filter(|s| s[4] == 0.0).count();
        }
        let mut worst = 0.0f32;
        let mut worst_sum = 0.0f64;
        let mut activity = 0;
        for (gs, cs) in g.iter().zip(c) {
            if (gs[4] == 0.0) != (cs[4] == 0.0) {
                activity += 1;
            }
            let scale = cs.iter().fold(0.0f32, |m, v| m.max(v.abs())).max(1e-30);
            let d = gs
                .iter()
                .zip(cs)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0f32, f32::max)
                / scale;
            worst = worst.max(d);
            // The GPU's records (levels >= 2) keep each row sum (the centre is the stored sum minus
            // the stored off-centre coefficients), while those coefficients round to 16 bits.
            let sum = |s: &[f32; 9]| s.iter().map(|&v| f64::from(v)).sum::<f64>();
            worst_sum = worst_sum.max((sum(gs) - sum(cs)).abs() / f64::from(scale));
        }
        eprintln!(
            "n={} level {k}: stencil max relative difference {worst:.2e}, row sums {worst_sum:.2e}",
            p.n
        );
        assert!(
            worst_sum <= 1e-5,
            "level {k}: row sums differ by {worst_sum:.2e} relative"
        );
        assert_eq!(activity, 0, "level {k}: active/inactive cells differ");
        assert!(
            worst <= 1e-4,
            "level {k}: stencils differ by {worst:.2e} relative"
        );
        if k == 1 {
            // Level 1 is not stored: each pass computes its stencils from the level-0 diagonal
            // with the CPU's f32 arithmetic in the CPU's order.
            assert!(
                worst <= 1e-6,
                "level 1: computed stencils differ by {worst:.2e} relative"
            );
        }
    }
    inactive1
}

/// `problem` with a hard square (E = 500) of `side` cells from `(x, y)`: hard regions make whole
/// coarse cells inactive.
fn with_hard_block(mut p: FieldProblem, (x, y, side): (usize, usize, usize)) -> FieldProblem {
    for j in y..y + side {
        for i in x..x + side {
            p.weight[j * p.n + i] = 1.0;
            p.value[j * p.n + i] = 500.0;
        }
    }
    p
}

#[test]
fn operators_match_cpu_128_and_256() {
    let ctx = device();
    check_operators(&ctx, &problem(128, 1.0, 1.0));
    check_operators(&ctx, &problem(256, 1.0, 1.0));
    check_operators(&ctx, &problem(128, 0.5, 2.0));
    // Inactive level-1 cells (all 4 children hard), one block touching the west and south
    // borders (clamped prolongation), one inside at odd offsets.
    let p = with_hard_block(problem(128, 1.0, 1.0), (0, 0, 9));
    let p = with_hard_block(p, (67, 41, 13));
    let inactive = check_operators(&ctx, &p);
    eprintln!("hard blocks: {inactive} inactive level-1 cells");
    assert!(inactive >= 16 + 25, "{inactive} inactive level-1 cells");
}

/// The smallest solvers: 16 x 16 (level 1 is the coarsest, solved exactly from stencils computed
/// from the level-0 diagonal) and 32 x 32.
#[test]
fn smallest_solvers_match_cpu() {
    let ctx = device();
    check_operators(&ctx, &with_hard_block(problem(16, 1.0, 1.0), (10, 2, 4)));
    check_solve(&ctx, &problem(16, 1.0, 1.0), false);
    check_solve(&ctx, &problem(32, 1.0, 1.0), false);
}

/// FMG then FCG on both backends; returns the GPU solver for further checks.
fn check_solve(ctx: &GpuContext, p: &FieldProblem, check_rate: bool) -> GpuFieldSolver {
    let params = GpuFieldSolver::algorithm_params();
    let tol = 1e-5;
    let relief = p.relief();
    let cpu = cpu_setup(p);
    let mut st = cpu.new_state();
    let (cpu_fmg_wu, cpu_lifts) = cpu_fmg_with_lift(&cpu, &mut st, &params);
    {
        // The composed CPU FMG is `Hierarchy::fmg` exactly.
        let mut st2 = cpu.new_state();
        assert_eq!(cpu.fmg(&mut st2, &params), cpu_fmg_wu);
        assert_eq!(st2.h, st.h);
    }

    let mut gpu = GpuFieldSolver::new(ctx, p.n, p.ax, p.ay).unwrap();
    gpu.upload_problem(p).unwrap();
    let gpu_fmg_wu = gpu.fmg().unwrap();
    assert_eq!(gpu_fmg_wu, cpu_fmg_wu, "FMG work units");
    for (k, c) in cpu_lifts.iter().enumerate().map(|(i, c)| (i + 1, c)) {
        let d = max_diff(&gpu.read_lift(k).unwrap(), c) / relief;
        assert!(
            d <= LIFT_TOL,
            "FMG lift level {k} differs by {d:.2e} of the relief"
        );
    }
    for k in 1..cpu.levels() {
        let d = max_diff(&gpu.read_level(k).unwrap(), cpu.level_unknowns(&st, k)) / relief;
        eprintln!(
            "n={} FMG level {k}: max |gpu - cpu| / relief = {d:.2e}",
            p.n
        );
        assert!(
            d <= REL_TOL,
            "FMG level {k} differs by {d:.2e} of the relief"
        );
    }
    let d_fmg = max_diff(&gpu.read_solution().unwrap(), &st.h) / relief;
    eprintln!(
        "n={} FMG level 0: max |gpu - cpu| / relief = {d_fmg:.2e}",
        p.n
    );
    assert!(
        d_fmg <= REL_TOL,
        "FMG result differs by {d_fmg:.2e} of the relief"
    );
    let r_gpu = gpu.residual().unwrap();
    let r_cpu = cpu.residual(&st);
    eprintln!(
        "n={} residual after FMG: gpu {r_gpu:.3e} cpu {r_cpu:.3e}",
        p.n
    );
    assert!((r_gpu - r_cpu).abs() <= 0.05 * r_cpu + 1e-6);

    let cpu_params = SolverParams {
        tolerance: tol,
        ..params
    };
    let (cpu_stats, cpu_iters, cpu_hist) = cpu_fcg(&cpu, &mut st, &cpu_params, 30);
    let rep = gpu.fcg(30, tol).unwrap();
    let rates: Vec<String> = rep
        .history
        .windows(2)
        .map(|w| format!("{:.3}", w[1] / w[0]))
        .collect();
    let cpu_rates: Vec<String> = cpu_hist
        .windows(2)
        .map(|w| format!("{:.3}", w[1] / w[0]))
        .collect();
    eprintln!(
        "n={} FCG: gpu {} iterations {:.2} WU res {:.2e} rates {rates:?}\n        cpu {cpu_iters} iterations {:.2} WU res {:.2e} rates {cpu_rates:?}",
        p.n,
        rep.iterations,
        rep.stats.work_units,
        rep.stats.residual,
        cpu_stats.work_units,
        cpu_stats.residual
    );
    assert!(
        rep.stats.residual <= tol,
        "GPU FCG did not converge: {:?}",
        rep.history
    );
    assert!(
        rep.iterations.abs_diff(cpu_iters) <= 1,
        "iterations: gpu {} cpu {cpu_iters}",
        rep.iterations
    );
    if rep.iterations == cpu_iters {
        assert_eq!(rep.stats.work_units, cpu_stats.work_units, "FCG work units");
    }
    if check_rate {
        for w in rep.history.windows(2) {
            assert!(
                w[1] / w[0] < 0.2,
                "residual reduction {:.3} >= 0.2 per iteration: {:?}",
                w[1] / w[0],
                rep.history
            );
        }
    }
    let d = max_diff(&gpu.read_solution().unwrap(), &st.h) / relief;
    eprintln!("n={} converged: max |gpu - cpu| / relief = {d:.2e}", p.n);
    assert!(
        d <= REL_TOL,
        "converged solutions differ by {d:.2e} of the relief"
    );
    // Hard cells hold their values exactly.
    let h = gpu.read_solution().unwrap();
    for (i, w) in p.weight.iter().enumerate() {
        if *w >= 1.0 {
            assert_eq!(h[i], p.value[i]);
        }
    }
    gpu
}

#[test]
fn fmg_and_fcg_match_cpu_128() {
    let ctx = device();
    check_solve(&ctx, &problem(128, 1.0, 1.0), true);
}

#[test]
fn fmg_and_fcg_match_cpu_256() {
    let ctx = device();
    check_solve(&ctx, &problem(256, 1.0, 1.0), true);
}

#[test]
fn anisotropic_cells_match_cpu() {
    let ctx = device();
    check_solve(&ctx, &problem(128, 0.5, 2.0), false);
}

/// The GPU's local relaxation (`fcg_start_relaxed`) against the CPU's from the same `h`: an edit
/// (a stretch of the straight line raised by 600 m, a warm start from the converged solution)
/// leaves large residuals next to it; for two stretches (with the heights' 10 sweeps and the
/// fields' 4), the relaxed heights and the work units agree, and the relaxation changes `h`. A
/// threshold that seeds windows over more than a quarter of the level relaxes nothing on either
/// backend.
#[test]
fn local_relaxation_matches_cpu() {
    let ctx = device();
    let n = 128;
    let p = problem(n, 1.0, 1.0);
    let relief = p.relief();
    let mut gpu = check_solve(&ctx, &p, false);
    let converged = gpu.read_solution().unwrap();
    let mut counts = Vec::new();
    for (stretch, threshold, sweeps) in [
        (n / 4..n / 2, 0.1, 10),
        (0..n / 8, 0.1, 4),
        (n / 4..n / 2, 1e-12, 10),
    ] {
        let mut p2 = p.clone();
        for i in stretch {
            p2.value[(n / 5) * n + i] = 800.0;
        }
        let cpu = cpu_setup(&p2);
        gpu.warm_start(&p2).unwrap();
        let h0 = gpu.read_solution().unwrap();
        let with = gpu.fcg_start_relaxed(threshold, sweeps).unwrap();
        let h_gpu = gpu.read_solution().unwrap();
        let without = gpu.fcg_start().unwrap();
        let mut h_cpu = h0.clone();
        let wu_cpu = oracle::cpu_local_relaxation(&cpu, &mut h_cpu, threshold, sweeps);
        let wu_gpu = with.work_units - without.work_units;
        let d = max_diff(&h_gpu, &h_cpu) / relief;
        let moved = max_diff(&h_cpu, &h0) / relief;
        eprintln!(
            "threshold {threshold:e}: relaxation WU gpu {wu_gpu:.4} cpu {wu_cpu:.4}, \
             |gpu - cpu| {d:.2e}, moved {moved:.2e} of the relief"
        );
        assert!(
            (wu_gpu - wu_cpu).abs() <= 1e-9,
            "work units: gpu {wu_gpu} cpu {wu_cpu}"
        );
        assert!(d <= 1e-5, "relaxed heights differ by {d:.2e} of the relief");
        if threshold < 1e-6 {
            assert_eq!(
                wu_cpu, 0.0,
                "windows over a quarter of the level must not relax"
            );
            assert_eq!(moved, 0.0);
        } else {
            assert!(
                wu_cpu > 0.0 && moved > 1e-2,
                "nothing relaxed at {threshold}"
            );
            counts.push(wu_cpu);
        }
        // Back to the converged solution of `p` for the next edit.
        gpu.upload_problem(&p).unwrap();
        gpu.fcg(60, 1e-6).unwrap();
        assert!(max_diff(&gpu.read_solution().unwrap(), &converged) / relief <= 1e-4);
    }
    assert!(
        counts[0] != counts[1],
        "the two edits relaxed the same windows"
    );
}

/// `fcg_relaxed` (the GPU's field solves) against the CPU's sequence (local relaxation, then FCG
/// only if the tolerance does not hold yet) after the edit of `local_relaxation_matches_cpu`: at a
/// loose tolerance the relaxation alone meets it on both backends (no preconditioner, the same
/// heights bit for bit, the same work units); at a tight one both iterate, to the same solution.
#[test]
fn relaxed_fcg_matches_cpu() {
    let ctx = device();
    let n = 128;
    let p = problem(n, 1.0, 1.0);
    let relief = p.relief();
    let mut gpu = check_solve(&ctx, &p, false);
    let mut p2 = p.clone();
    for i in n / 4..n / 2 {
        p2.value[(n / 5) * n + i] = 800.0;
    }
    let cpu = cpu_setup(&p2);
    let (threshold, sweeps) = (0.05, 4);
    for tolerance in [5e-2, 1e-5] {
        if tolerance < 1e-2 {
            // Back to the converged solution of `p`.
            gpu.upload_problem(&p).unwrap();
            gpu.fcg(60, 1e-6).unwrap();
        }
        gpu.warm_start(&p2).unwrap();
        let mut st = cpu.new_state();
        st.h = gpu.read_solution().unwrap();
        let rep = gpu.fcg_relaxed(30, tolerance, threshold, sweeps).unwrap();
        let relaxed = oracle::cpu_local_relaxation(&cpu, &mut st.h, threshold, sweeps);
        let params = SolverParams {
            tolerance,
            ..GpuFieldSolver::algorithm_params()
        };
        let (stats, iterations) = cpu.iterate_to_tolerance(&mut st, &params);
        let d = max_diff(&gpu.read_solution().unwrap(), &st.h) / relief;
        eprintln!(
            "tolerance {tolerance:e}: gpu {} iterations {:.3} WU, cpu {iterations} iterations \
             {:.3} WU, |gpu - cpu| {d:.2e} of the relief",
            rep.iterations,
            rep.stats.work_units,
            relaxed + stats.work_units
        );
        assert!(relaxed > 0.0);
        assert!(rep.stats.residual <= tolerance && stats.residual <= tolerance);
        if tolerance > 1e-2 {
            assert_eq!((rep.iterations, iterations), (0, 0));
            assert_eq!(rep.stats.work_units, relaxed);
            assert_eq!(d, 0.0, "relaxed heights differ");
        } else {
            assert!(rep.iterations >= 1 && iterations >= 1);
            assert!(rep.iterations.abs_diff(iterations) <= 1);
            assert!(d <= REL_TOL, "solutions differ by {d:.2e} of the relief");
        }
    }
}

/// FCG queued whole with its stop test on the GPU (`queue_fcg_relaxed`, `fcg_gate.wgsl`) runs the
/// passes the CPU-driven loop (`fcg_relaxed`, a round trip per iteration) runs: the same iterations,
/// work units and heights bit for bit, whether fewer iterations were queued than needed (more are
/// queued after each report), or many more (the gate stops them), or the relaxation alone meets the
/// tolerance. One blocking wait per report, and each pass's bytes counted once however many
/// reports show it.
#[test]
fn queued_fcg_stops_on_the_gpu_where_the_cpu_loop_stops() {
    let ctx = device();
    let n = 128;
    let p = problem(n, 1.0, 1.0);
    let mut p2 = p.clone();
    for i in n / 4..n / 2 {
        p2.value[(n / 5) * n + i] = 800.0;
    }
    let (threshold, sweeps) = (0.05, 4);
    let fresh = || {
        let mut g = check_solve(&ctx, &p, false);
        g.fcg(60, 1e-6).unwrap();
        g.warm_start(&p2).unwrap();
        g
    };
    let mut moved = Vec::new();
    for (tolerance, queued) in [(1e-5, 1), (1e-5, 30), (5e-2, 3)] {
        let mut looped = fresh();
        let rep = looped
            .fcg_relaxed(30, tolerance, threshold, sweeps)
            .unwrap();
        let mut gated = fresh();
        let before = ctx.counters();
        gated
            .queue_fcg_relaxed(30, tolerance, threshold, sweeps, Some(queued), None, None)
            .unwrap();
        let mut q = gated.queued_report().unwrap();
        let mut reports = 1;
        while !q.stopped {
            gated.queue_more(2).unwrap();
            q = gated.queued_report().unwrap();
            reports += 1;
        }
        let c = ctx.counters().since(&before);
        eprintln!(
            "tolerance {tolerance:e}, {queued} queued: loop {} iterations, gated {} in {reports} \
             reports ({c:?})",
            rep.iterations, q.iterations
        );
        assert_eq!(c.blocking_waits, reports);
        moved.push(c.bytes_moved_estimate as f64);
        assert_eq!(q.iterations, rep.iterations);
        assert_eq!(q.stats.work_units, rep.stats.work_units);
        assert_eq!(q.stats.residual, rep.stats.residual);
        let (a, b) = (
            looped.read_solution().unwrap(),
            gated.read_solution().unwrap(),
        );
        assert!(a == b, "gated heights differ from the loop's");
        if tolerance > 1e-2 {
            assert_eq!(
                q.iterations, 0,
                "the relaxation alone meets a loose tolerance"
            );
            assert!(!q.started);
        } else {
            assert!(q.iterations >= 2 && q.started);
        }
    }
    // The same passes ran after one report and after several (only the gates' few bytes differ).
    assert!(
        (moved[0] / moved[1] - 1.0).abs() < 0.01,
        "{} bytes over several reports, {} in one",
        moved[0],
        moved[1]
    );
}

/// FCG's stop-test relaxation (`cpu::Fcg::iterate`, `gpu::plan::spike_relaxation`): with the
/// tolerance set to two thirds of an iteration's residual, that iteration ends within twice the
/// tolerance; where only a few cells exceed it, both backends relax their correction, and the
/// solve stops there. For each such tolerance the GPU's loop matches the CPU's (iterations, work
/// units, residual within 5 %, heights within 1e-3 of the relief), and its queued run matches its
/// loop bit for bit; at least one of them relaxed.
#[test]
fn stop_test_relaxation_matches_cpu() {
    let ctx = device();
    let n = 256;
    let p = problem(n, 1.0, 1.0);
    let relief = p.relief();
    let params = GpuFieldSolver::algorithm_params();
    let cpu = cpu_setup(&p);
    let fmg = || {
        let mut st = cpu.new_state();
        cpu.fmg(&mut st, &params);
        st
    };
    let loose = |tolerance: f32| SolverParams {
        tolerance,
        ..params
    };
    // Iterations 1 and 3 stop at their relaxation; 2 restarts FCG after it (lavapipe is slow: 3).
    let (_, _, history) = cpu_fcg(&cpu, &mut fmg(), &loose(1e-9), 3);
    let mut relaxed = 0;
    for (k, residual) in history.iter().enumerate().skip(1) {
        let tolerance = residual / 1.5;
        let mut st = fmg();
        let (cpu_stats, cpu_iters, _) = cpu_fcg(&cpu, &mut st, &loose(tolerance), 30);
        let gpu_after_fmg = || {
            let mut g = GpuFieldSolver::new(&ctx, n, p.ax, p.ay).unwrap();
            g.upload_problem(&p).unwrap();
            g.fmg().unwrap();
            g
        };
        let mut gpu = gpu_after_fmg();
        let rep = gpu.fcg(30, tolerance).unwrap();
        let spikes = gpu.spike_runs();
        eprintln!(
            "iteration {k}: tolerance {tolerance:.3e}: cpu {cpu_iters} iterations {:.4} WU, \
             gpu {} iterations {:.4} WU, {spikes} stop-test relaxations",
            cpu_stats.work_units, rep.iterations, rep.stats.work_units
        );
        assert_eq!(rep.iterations, cpu_iters, "tolerance {tolerance:e}");
        assert_eq!(rep.stats.work_units, cpu_stats.work_units);
        assert!((rep.stats.residual - cpu_stats.residual).abs() <= 0.05 * cpu_stats.residual);
        assert!(rep.stats.residual <= tolerance);
        let d = max_diff(&gpu.read_solution().unwrap(), &st.h) / relief;
        assert!(d <= REL_TOL, "heights differ by {d:.2e} of the relief");
        if spikes > 0 {
            relaxed += 1;
        }
        // The same run queued whole, stopped on the GPU.
        let mut looped = gpu_after_fmg();
        let a = looped.fcg_relaxed(30, tolerance, 1.0, 0).unwrap();
        let mut queued = gpu_after_fmg();
        queued
            .queue_fcg_relaxed(30, tolerance, 1.0, 0, Some(30), None, None)
            .unwrap();
        let q = queued.queued_report().unwrap();
        assert_eq!(q.iterations, a.iterations);
        assert_eq!(q.stats.work_units, a.stats.work_units);
        assert_eq!(q.stats.residual, a.stats.residual);
        assert!(looped.read_solution().unwrap() == queued.read_solution().unwrap());
    }
    assert!(relaxed > 0, "no iteration relaxed: residuals {history:?}");
}

/// A solver of the `n x n` test problem with `ax`, after its FMG start.
fn after_fmg(ctx: &GpuContext, n: usize, ax: f32) -> GpuFieldSolver {
    let mut gpu = GpuFieldSolver::new(ctx, n, ax, 1.0).unwrap();
    gpu.upload_problem(&problem(n, ax, 1.0)).unwrap();
    gpu.fmg().unwrap();
    gpu
}

/// FCG's update reduces `max |r|` as it writes `r` (no pass re-reads it): after every iteration the
/// reported residual equals, bit for bit, the one the reduction passes recount from `r`, and an
/// iteration dispatches no `dot_partial` but the stop-test relaxation's gated recount, which runs
/// only after a relaxation (the later ones' `z.q` with `r.z` and `z.A z`, which gives `p.q`, are
/// reduced by the preconditioner's last colour pass, `smooth_dot_level0`).
#[test]
fn fused_max_residual_equals_a_recount_and_saves_a_dispatch() {
    let ctx = device();
    for (n, ax) in [(64, 1.0), (256, 0.5)] {
        let mut gpu = after_fmg(&ctx, n, ax);
        gpu.fcg_start().unwrap();
        let mut iterations = 0;
        while let Some(s) = {
            let before = ctx.counters();
            let s = gpu.fcg_iterate().unwrap();
            let c = ctx.counters().since(&before).by_pass;
            let later = u64::from(iterations > 0);
            assert_eq!(c.of(Kernel::DotPartial).0, 1, "n={n}");
            assert_eq!(c.of(Kernel::SmoothDotLevel0).0, later, "n={n}");
            assert_eq!(c.of(Kernel::DotFinal).0, 2 + later, "n={n}");
            s
        } {
            iterations += 1;
            let recounted = gpu.recount_residual().unwrap();
            assert_eq!(
                s.residual.to_bits(),
                recounted.to_bits(),
                "n={n} iteration {iterations}: fused {} recounted {recounted}",
                s.residual
            );
            if s.residual <= 1e-6 || iterations == 10 {
                break;
            }
        }
        assert!(iterations >= 3, "n={n}: {iterations} iterations");
    }
}

/// FCG's first direction reduces `r.z` alone (its `z.q` would be unused: `p = z` follows): the
/// `r.z` it leaves equals, bit for bit, the one the full `z.q`, `r.z` reduction recounts, and the
/// iterations that follow run as before.
#[test]
fn first_direction_reduces_r_z_alone_to_the_same_bits() {
    let ctx = device();
    for (n, ax) in [(64, 1.0), (256, 0.5)] {
        let mut gpu = after_fmg(&ctx, n, ax);
        let before = ctx.counters();
        gpu.fcg_start().unwrap();
        let c = ctx.counters().since(&before).by_pass;
        // The residual's max |r|, and the first direction's r.z with its last colour pass.
        assert_eq!(c.of(Kernel::DotPartial).0, 1, "n={n}");
        assert_eq!(c.of(Kernel::SmoothDotLevel0).0, 1, "n={n}");
        let (rz, recounted) = gpu.recount_rz().unwrap();
        assert!(rz > 0.0, "n={n}: r.z {rz}");
        assert_eq!(
            rz.to_bits(),
            recounted.to_bits(),
            "n={n}: first direction {rz}, recounted {recounted}"
        );
        for _ in 0..3 {
            assert!(gpu.fcg_iterate().unwrap().is_some(), "n={n}");
        }
    }
}

#[test]
fn warm_start_keeps_h_resets_hard_and_matches_cpu() {
    let ctx = device();
    let n = 128;
    let p = problem(n, 1.0, 1.0);
    let mut gpu = check_solve(&ctx, &p, false);
    let before = gpu.read_solution().unwrap();
    // Raise the straight line from 200 m to 300 m.
    let mut p2 = p.clone();
    for i in 0..n {
        p2.value[(n / 5) * n + i] = 300.0;
    }
    gpu.warm_start(&p2).unwrap();
    let after = gpu.read_solution().unwrap();
    for i in 0..n * n {
        let expected = if p2.weight[i] >= 1.0 {
            p2.value[i]
        } else {
            before[i]
        };
        assert_eq!(after[i], expected, "cell {i} after warm start");
    }
    let cpu = cpu_setup(&p2);
    let mut st = cpu.new_state();
    st.h = before;
    cpu.reset_hard(&mut st);
    let params = SolverParams {
        tolerance: 1e-5,
        ..GpuFieldSolver::algorithm_params()
    };
    let (_, cpu_iters, _) = cpu_fcg(&cpu, &mut st, &params, 30);
    let rep = gpu.fcg(30, 1e-5).unwrap();
    eprintln!(
        "warm start: gpu {} iterations, cpu {cpu_iters}",
        rep.iterations
    );
    assert!(rep.stats.residual <= 1e-5);
    let d = max_diff(&gpu.read_solution().unwrap(), &st.h) / p2.relief();
    assert!(
        d <= REL_TOL,
        "warm-started solutions differ by {d:.2e} of the relief"
    );
}

#[test]
fn mips_and_minmax_match_cpu_oracle() {
    let ctx = device();
    // 16 and 64: the one-workgroup passes start from level 0; 128 and 256: from a level's pass,
    // with a last one of two levels.
    for n in [16, 64, 128, 256] {
        let p = problem(n, 1.0, 1.0);
        let mut gpu = GpuFieldSolver::new(&ctx, n, 1.0, 1.0).unwrap();
        gpu.upload_problem(&p).unwrap();
        gpu.fmg().unwrap();
        gpu.fcg(30, 1e-5).unwrap();
        let h = gpu.read_solution().unwrap();
        let mips = GpuMips::new(&gpu).unwrap();
        mips.update().unwrap();
        assert_eq!(mips.mip_count(), n.trailing_zeros() as usize + 1);
        let summary = pyramid::HardSummary::new(n, &p.weight, &p.value);
        let mut expected = h.clone();
        assert_eq!(mips.read_mip(0).unwrap(), expected, "mip 0 must be h");
        for k in 1..mips.mip_count() {
            expected = pyramid::display_downsample(&expected, &summary.levels[k - 1]);
            let got = mips.read_mip(k).unwrap();
            let d = max_diff(&got, &expected) / p.relief();
            assert!(d <= 1e-6, "n={n} mip {k} differs by {d:.2e} of the relief");
        }
        let mm = mips.read_min_max().unwrap();
        let cpu_mm = pyramid::minmax_pyramid(n, &h);
        assert_eq!(mm, cpu_mm, "n={n} min/max pyramid");
        assert_eq!(
            mips.min_max_bytes() as usize,
            pyramid::minmax_bytes(&cpu_mm)
        );
        eprintln!(
            "n={n}: min/max pyramid {} bytes, mips {} bytes, solver {} bytes",
            mips.min_max_bytes(),
            mips.gpu_bytes(),
            gpu.gpu_bytes()
        );
    }
}

/// A solver may keep `h` in mip 0 of the height texture (`GpuSolver`'s heights: the displayed mip 0
/// is `h` itself, no `h` buffer, no copy). The texture variants of the passes that bind `h` do the
/// buffer variants' arithmetic: FMG, FCG, a warm start and a cold re-upload give the same bits as
/// with `h` in a buffer, and the mips publish the same texture without copying `h`.
#[test]
fn h_in_the_height_texture_matches_a_buffer_bit_for_bit() {
    let ctx = device();
    let n = 128;
    let p = problem(n, 1.0, 1.0);
    let params = GpuFieldSolver::algorithm_params();
    let mut buf = GpuFieldSolver::new(&ctx, n, 1.0, 1.0).unwrap();
    let texture = mips::height_texture(&ctx, n);
    let mut tex =
        GpuFieldSolver::with_texture_h(&ctx, n, 1.0, 1.0, &params, true, &texture).unwrap();
    // The texture is not the solver's to count; it has no `h` buffer.
    assert_eq!(buf.gpu_bytes() - tex.gpu_bytes(), (n * n * 4) as u64);
    let both = |buf: &GpuFieldSolver, tex: &GpuFieldSolver, what: &str| {
        let (b, t) = (buf.read_solution().unwrap(), tex.read_solution().unwrap());
        let same = b.iter().zip(&t).filter(|(x, y)| x == y).count();
        assert_eq!(same, n * n, "{what}: {same} of {} cells equal", n * n);
        b
    };
    for s in [&mut buf, &mut tex] {
        s.upload_problem(&p).unwrap();
        s.fmg().unwrap();
    }
    let fmg = both(&buf, &tex, "FMG");
    for k in 1..=n.trailing_zeros() as usize {
        assert_eq!(
            buf.read_lift(k).unwrap(),
            tex.read_lift(k).unwrap(),
            "lift {k}"
        );
    }
    assert_eq!(buf.residual().unwrap(), tex.residual().unwrap());
    let (rb, rt) = (buf.fcg(30, 1e-6).unwrap(), tex.fcg(30, 1e-6).unwrap());
    assert_eq!(rb.history, rt.history);
    let solved = both(&buf, &tex, "FCG");
    assert_ne!(solved, fmg, "FCG changes h");
    // Publishing: `tex`'s mips take its texture, whose mip 0 is `h`.
    let (mb, mt) = (GpuMips::new(&buf).unwrap(), GpuMips::new(&tex).unwrap());
    assert!(*mt.texture() == texture && *mb.texture() != texture);
    // The texture is counted by the mips (`mt` has one params block less: no `mip_level0`).
    let tex_bytes: u64 = (0..mb.mip_count())
        .map(|k| ((n >> k) * (n >> k) * 4) as u64)
        .sum();
    assert!(mt.gpu_bytes() >= tex_bytes && mb.gpu_bytes() - mt.gpu_bytes() <= 1024);
    mb.update().unwrap();
    mt.update().unwrap();
    for k in 0..mb.mip_count() {
        assert_eq!(mb.read_mip(k).unwrap(), mt.read_mip(k).unwrap(), "mip {k}");
    }
    assert_eq!(mb.read_min_max().unwrap(), mt.read_min_max().unwrap());
    // Warm start after raising the straight line: hard cells reset, then FCG.
    let mut p2 = p.clone();
    for i in 0..n {
        p2.value[(n / 5) * n + i] = 300.0;
    }
    for s in [&mut buf, &mut tex] {
        s.warm_start(&p2).unwrap();
    }
    both(&buf, &tex, "warm start");
    let (rb, rt) = (buf.fcg(30, 1e-6).unwrap(), tex.fcg(30, 1e-6).unwrap());
    assert_eq!(rb.history, rt.history);
    let warm = both(&buf, &tex, "warm FCG");
    // Mip 0 is `h` at every moment: FCG changed it without a publish (mip 1 did not change).
    assert_eq!(mt.read_mip(0).unwrap(), warm);
    assert_ne!(mb.read_mip(0).unwrap(), warm);
    assert_eq!(mt.read_mip(1).unwrap(), mb.read_mip(1).unwrap());
    // A cold upload sets `h` = E on hard cells and 0 elsewhere (the assembly writes it).
    for s in [&mut buf, &mut tex] {
        s.upload_problem(&p).unwrap();
    }
    let cold = both(&buf, &tex, "cold upload");
    for (i, h) in cold.iter().enumerate() {
        let expected = if p.weight[i] >= 1.0 { p.value[i] } else { 0.0 };
        assert_eq!(*h, expected, "cell {i} after a cold upload");
    }
    // Only `GpuSolver`'s kind of texture is taken.
    let small = mips::height_texture(&ctx, n / 2);
    assert!(GpuFieldSolver::with_texture_h(&ctx, n, 1.0, 1.0, &params, true, &small).is_err());
}

#[test]
fn gpu_bytes_counts_every_allocation() {
    let ctx = device();
    let n = 128;
    let gpu = GpuFieldSolver::new(&ctx, n, 1.0, 1.0).unwrap();
    let buffers = |edges: bool| -> u64 {
        terrasketch_multigrid::gpu::buffer_sizes(n, edges)
            .iter()
            .map(|(_, b)| b)
            .sum()
    };
    assert!(
        gpu.gpu_bytes() > buffers(true),
        "params arena and status staging are counted too"
    );
    assert!(gpu.gpu_bytes() < buffers(true) + 64 * 1024);
    // Without edge differences: no `d_east` / `d_north`, and the count follows the shorter list.
    let mut bare = GpuFieldSolver::with_edges(
        &ctx,
        n,
        1.0,
        1.0,
        &GpuFieldSolver::algorithm_params(),
        false,
    )
    .unwrap();
    // Such a solver refuses a problem with edge differences (`problem` has a band of them).
    assert!(bare.upload_problem(&problem(n, 1.0, 1.0)).is_err());
    assert!(bare.gpu_bytes() > buffers(false));
    assert!(bare.gpu_bytes() < buffers(false) + 64 * 1024);
    assert_eq!(
        gpu.gpu_bytes() - bare.gpu_bytes(),
        buffers(true) - buffers(false)
    );
    assert_eq!(buffers(true) - buffers(false), 2 * (n * n * 4) as u64);
    // A coarser solver on `gpu`'s coarse levels allocates only its level 0 (and reductions).
    let params = GpuFieldSolver::algorithm_params();
    let guest =
        GpuFieldSolver::sharing_coarse_levels(&ctx, n / 2, 1.0, 1.0, &params, &gpu).unwrap();
    let own: u64 = terrasketch_multigrid::gpu::allocated_sizes(n / 2, false, true, &[])
        .iter()
        .map(|(_, b)| b)
        .sum();
    assert!(guest.gpu_bytes() > own && guest.gpu_bytes() < own + 64 * 1024);
    assert!(
        !terrasketch_multigrid::gpu::allocated_sizes(n / 2, false, true, &[])
            .iter()
            .any(|(l, _)| l.contains(".stencil.") || l.contains(".u.") || l.contains(".f.l1"))
    );
    // Level 0 of a solver on its own: eight buffers (FCG keeps no `q = A p`: it is recomputed
    // where it is read), plus `d_east`, `d_north` with edge differences.
    let level0 = |edges: bool| {
        terrasketch_multigrid::gpu::buffer_sizes(n, edges)
            .iter()
            .filter(|(l, _)| l.ends_with(".l0"))
            .count()
    };
    assert_eq!((level0(false), level0(true)), (8, 10));
    assert!(
        !terrasketch_multigrid::gpu::buffer_sizes(n, true)
            .iter()
            .any(|(l, _)| l == "multigrid.q.l0")
    );
    // `GpuSolver`'s gradient field (shift 1) and roughness (shift 2) also keep their level-0
    // buffers in the heights' (all eight; all but `h`): only the reductions (and roughness's `h`)
    // stay on the list both the allocation and `gpu_budget` use.
    use terrasketch_multigrid::gpu::borrowed_level0;
    // (`GpuSolver`'s heights themselves keep their `f` in their `p`, `h` in the height texture,
    // level 1's `u`, `f` and tile-sweep input in their `value` and `weight`.)
    assert_eq!(borrowed_level0(0), vec!["f", "h", "u.l1", "f.l1", "alt.l1"]);
    assert!(borrowed_level0(3).is_empty());
    assert_eq!(borrowed_level0(1).len(), 8);
    assert_eq!(borrowed_level0(2).len(), 7);
    assert!(!borrowed_level0(2).contains(&"h"));
    let listed = |side: usize, shift: usize| -> Vec<String> {
        terrasketch_multigrid::gpu::allocated_sizes(side, false, true, &borrowed_level0(shift))
            .into_iter()
            .map(|(l, _)| l)
            .collect()
    };
    assert_eq!(
        listed(n / 2, 1),
        ["multigrid.partials", "multigrid.scalars"]
    );
    assert_eq!(
        listed(n / 4, 2),
        ["multigrid.h.l0", "multigrid.partials", "multigrid.scalars"]
    );
    assert!(GpuFieldSolver::sharing_coarse_levels(&ctx, n, 1.0, 1.0, &params, &gpu).is_err());
    assert!(GpuFieldSolver::sharing_coarse_levels(&ctx, 2 * n, 1.0, 1.0, &params, &gpu).is_err());
    let mips = GpuMips::new(&gpu).unwrap();
    let tex: u64 = (0..=7).map(|k| ((n >> k) * (n >> k) * 4) as u64).sum();
    assert!(mips.gpu_bytes() >= tex + mips.min_max_bytes());
}
