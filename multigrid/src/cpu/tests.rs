//! The CPU executor against the cycle's steps (`crate::cycle`), and its fused path against the
//! plain one.

use super::testutil::{Lcg, random_hierarchy};
use super::*;

/// Parameter sets: the default W(1,1) from level 1 to 3, and others that move every branch.
fn param_sets() -> Vec<SolverParams> {
    [
        (1, 1, 2, 1, 3),
        (2, 1, 2, 0, 4),
        (0, 2, 1, 0, 0),
        (1, 2, 3, 2, 9),
        (1, 1, 2, 0, 1),
    ]
    .map(|(pre, post, gamma, from, until)| SolverParams {
        pre_sweeps: pre,
        post_sweeps: post,
        gamma,
        gamma_from_level: from,
        gamma_until_level: until,
        ..SolverParams::default()
    })
    .to_vec()
}

fn work_units(shape: &CycleShape, steps: &[CycleStep]) -> f64 {
    steps.iter().map(|s| s.work_units(shape)).sum()
}

/// The CPU executor runs exactly the steps of `crate::cycle` (the GPU plan's source): FMG,
/// the preconditioner (fused or step by step) and a whole solve, on several sizes and
/// parameter sets, with the work units the steps count.
#[test]
fn the_cpu_runs_the_cycle_steps() {
    let mut rng = Lcg(7);
    for n in [16, 32, 64, 128, 256] {
        let hy = random_hierarchy(n, &[0.0, 0.0, 0.0, 1.0, 1e3], &mut rng);
        for params in param_sets() {
            let shape = CycleShape::unfused(hy.levels(), &params);
            let what = format!("{n}^2, {params:?}");
            let mut st = hy.new_state();
            hy.start_trace();
            let wu = hy.fmg(&mut st, &params);
            let fmg = cycle::fmg(&shape);
            assert_eq!(hy.take_trace(), fmg, "FMG, {what}");
            assert_eq!(wu, work_units(&shape, &fmg), "FMG work units, {what}");

            let r = hy.residual_vector(&st.h);
            let mut z = vec![0.0; n * n];
            hy.start_trace();
            let wu = hy.precondition(&r, &mut z, &mut st, &params);
            let pre = cycle::precondition(&shape);
            assert_eq!(hy.take_trace(), pre, "preconditioner, {what}");
            assert_eq!(wu, work_units(&shape, &pre), "preconditioner WU, {what}");

            // A whole solve: FMG, then one preconditioner per FCG direction.
            let mut st = hy.new_state();
            hy.start_trace();
            let (stats, _) = hy.solve(&mut st, &params);
            let trace = hy.take_trace();
            let directions = trace
                .iter()
                .filter(|s| **s == CycleStep::Clear { level: 0 })
                .count();
            assert!(directions >= 1, "{what}");
            let mut expected = fmg.clone();
            for _ in 0..directions {
                expected.extend(&pre);
            }
            assert_eq!(trace, expected, "solve, {what}");
            assert_eq!(stats.work_units, work_units(&shape, &expected), "{what}");
        }
    }
}

/// The fused one-sweep preconditioner (`fast::pre_phase`, `fast::post_phase`) against the
/// same steps run one by one (`precondition_plain`), on problems with free, soft and hard
/// cells: the same work units, and `z` within 4 ulps of its largest value (not bit for bit:
/// `pre_phase` computes the residual after the sweep in the form it has in exact arithmetic,
/// zero on black cells, where the plain residual pass leaves round-off; about a fifth of the
/// cells differ in their last bits).
#[test]
fn the_fused_preconditioner_equals_the_plain_one() {
    let mut rng = Lcg(11);
    let params = SolverParams::default();
    for n in [16, 64, 256] {
        let hy = random_hierarchy(n, &[0.0, 0.0, 0.0, 1.0, 1e3], &mut rng);
        let r: Vec<f32> = (0..n * n).map(|_| rng.below(2000) - 1000.0).collect();
        let q: Vec<f32> = (0..n * n).map(|_| rng.below(2000) - 1000.0).collect();
        let mut st = hy.new_state();
        let mut fused = vec![0.0; n * n];
        let (wu, rz, zq, _) =
            hy.precondition_dots(&r, &mut fused, Some(&q), None, &mut st, &params);
        let mut st = hy.new_state();
        let mut plain = vec![0.0; n * n];
        let (wu0, rz0, zq0) = hy.precondition_plain(&r, &mut plain, Some(&q), &mut st, &params);
        assert_eq!(wu, wu0, "{n}^2");
        let scale = plain.iter().fold(0.0f32, |m, x| m.max(x.abs()));
        let ulps = 4.0 * scale * f32::EPSILON;
        for (i, (a, b)) in fused.iter().zip(&plain).enumerate() {
            assert!(
                (a - b).abs() <= ulps,
                "{n}^2 cell {i}: fused {a}, plain {b}"
            );
        }
        let close = |a: f64, b: f64| (a - b).abs() <= 1e-6 * a.abs().max(b.abs());
        assert!(close(rz, rz0), "{n}^2: r.z {rz} against {rz0}");
        let zq_scale = (dot(&plain, &plain) * dot(&q, &q)).sqrt();
        assert!(
            (zq - zq0).abs() <= 1e-6 * zq_scale,
            "{n}^2: z.q {zq} against {zq0}"
        );
    }
}
