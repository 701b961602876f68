//! Tests of the plans: which passes run, in which order, and their workgroups.

use super::*;

fn shape(levels: usize) -> CycleShape {
    CycleShape {
        levels,
        pre_sweeps: 1,
        post_sweeps: 1,
        gamma: 2,
        gamma_from_level: 1,
        gamma_until_level: 3,
        fuse_side: 0,
        shift: 0,
    }
}

#[test]
fn dispatch_sizes() {
    assert_eq!(groups_2d(64, 64), [8, 8, 1]);
    assert_eq!(groups_2d(4, 8), [1, 1, 1]);
    assert_eq!(groups_2d(9, 17), [2, 3, 1]);
    assert_eq!(partial_groups(1), 1);
    assert_eq!(partial_groups(256 * 256), 256);
    assert_eq!(partial_groups(16384 * 16384), MAX_PARTIALS);
    assert_eq!(Op::SmoothLevel0 { colour: 1 }.workgroups(256), [16, 32, 1]);
    assert_eq!(
        Op::SmoothCoarse {
            level: 2,
            colour: 3
        }
        .workgroups(256),
        [4, 4, 1]
    );
    assert_eq!(
        Op::ResidualRestrictCoarse { level: 4 }.workgroups(256),
        [1, 1, 1]
    );
    assert_eq!(Op::GalerkinCoarse { level: 2 }.workgroups(256), [8, 8, 1]);
    assert_eq!(Op::DotPartial { stage: 0 }.workgroups(128), [64, 1, 1]);
    // Largest supported grid stays within the 65535 workgroups per dimension.
    for op in all_ops(12) {
        assert!(
            op.workgroups(16384).iter().all(|g| *g <= 65535 && *g >= 1),
            "{op:?}"
        );
    }
    assert_eq!(minmax_finest_side(256), 64);
    assert_eq!(minmax_base_groups(32), [32, 32, 1]);
}

/// Cycles run on level `k` by one cycle on level `top` (`k >= top`): W between levels 1
/// and 3 (each visit from level 1 or 2 runs the next level twice), V below.
fn cycles_below(top: i32, k: i32) -> f64 {
    (top..k)
        .map(|j| if (1..3).contains(&j) { 2.0 } else { 1.0 })
        .product()
}

#[test]
fn work_units_match_the_cpu_counting() {
    // levels 0..=5 (256 -> 8): level-k cycles run 1, 2, 4, 4 times for k = 1..=4.
    let s = shape(6);
    let expected = 2.0
        + (1..=4)
            .map(|k| cycles_below(1, k) * 2.0 * 0.25f64.powi(k))
            .sum::<f64>();
    assert_eq!(work_units(&precondition(&s)), expected);
    // FMG: one cycle per level 4..=1, each with the cycles below it.
    let fmg_expected: f64 = (1..=4)
        .map(|top| {
            (top..=4)
                .map(|k| cycles_below(top, k) * 2.0 * 0.25f64.powi(k))
                .sum::<f64>()
        })
        .sum();
    assert_eq!(work_units(&fmg(&s)), fmg_expected);
}

#[test]
fn plans_only_name_known_ops_and_coarsest_solves_count() {
    let s = shape(6);
    let ops = all_ops(6);
    let mut solves = 0;
    for step in precondition(&s)
        .iter()
        .chain(&fmg(&s))
        .chain(&fcg_init(&s))
        .chain(&fcg_step())
        .chain(&assemble(&s, false))
        .chain(&assemble(&s, true))
    {
        if let Step::Dispatch(op) = step {
            assert!(ops.contains(op), "{op:?} missing from all_ops");
        }
    }
    for step in precondition(&s) {
        if step == Step::Dispatch(Op::CoarsestSolve) {
            solves += 1;
        }
    }
    // One per cycle on level 4 (W only from levels 1 and 2).
    assert_eq!(solves, 4);
    let mut dedup = ops.clone();
    dedup.sort_by_key(|o| format!("{o:?}"));
    dedup.dedup();
    assert_eq!(dedup.len(), ops.len());
}

/// The CPU visits the coarsest level once per visit of its parent, whatever `gamma` says
/// there; so does the plan (a 64^2 hierarchy: W from levels 1 and 2, coarsest level 3).
#[test]
fn the_coarsest_level_is_visited_once_from_its_parent() {
    let s = shape(4);
    assert_eq!(s.coarsest(), 3);
    assert_eq!((s.visits(1), s.visits(2)), (2, 1));
    let solves = precondition(&s)
        .iter()
        .filter(|st| **st == Step::Dispatch(Op::CoarsestSolve))
        .count();
    // Level 2 twice from level 1, the coarsest once from each visit of level 2.
    assert_eq!(solves, 2);
}

#[test]
fn smallest_hierarchy_goes_straight_to_the_direct_solve() {
    let s = shape(2); // 16 -> 8
    let p = precondition(&s);
    assert!(p.contains(&Step::Dispatch(Op::CoarsestSolve)));
    assert!(
        !p.iter()
            .any(|st| matches!(st, Step::Dispatch(Op::SmoothCoarse { .. })))
    );
    let f = fmg(&s);
    // 16 x 16: lift levels 1 ..= 4 pushed, 3 .. 0 pulled, then the restricted residual of h = g.
    let lift_ops: Vec<Step> = [1, 2, 3, 4]
        .map(|level| Step::Dispatch(Op::LiftPush { level }))
        .into_iter()
        .chain([3, 2, 1, 0].map(|level| Step::Dispatch(Op::LiftPull { level })))
        .collect();
    assert_eq!(f[..8], lift_ops[..]);
    assert_eq!(
        f[8],
        Step::Dispatch(Op::ResidualRestrictLevel0 { solution: true })
    );
    assert_eq!(
        f.last(),
        Some(&Step::Dispatch(Op::ProlongLevel0 { solution: true }))
    );
}

#[test]
fn lift_storage_and_dispatches() {
    assert_eq!(lift_offset(8, 1), 0);
    assert_eq!(lift_offset(8, 2), 16);
    assert_eq!(lift_offset(8, 3), 20);
    assert_eq!(lift_len(8), 21);
    assert_eq!(lift_len(4096), (4096 * 4096 - 1) / 3);
    assert_eq!(shape(6).lift_levels(), 8); // 256 = 2^8
    // Levels smaller than a workgroup are one workgroup each.
    assert_eq!(Op::LiftPush { level: 1 }.workgroups(256), [16, 16, 1]);
    assert_eq!(Op::LiftPush { level: 8 }.workgroups(256), [1, 1, 1]);
    assert_eq!(Op::LiftPull { level: 0 }.workgroups(256), [32, 32, 1]);
    assert_eq!(Op::LiftPull { level: 7 }.workgroups(256), [1, 1, 1]);
    // The lift costs no work units (no smoothing sweep), as on the CPU.
    assert_eq!(work_units(&lift(&shape(6))), 0.0);
    assert_eq!(lift(&shape(6)).len(), 16);
}

/// FCG's update writes the `max |r|` partials that `DotFinal` of `STAGE_R` reads: it follows the
/// update directly (no `DotPartial` re-reads `r`), over as many workgroups as the reduction's
/// first pass would dispatch (`DotFinal` reads `partial_groups(n^2)` of them). No pass reduces
/// `p.q`: the direction's `DotFinal` of `STAGE_ZPQ` computes it and `alpha`, after the last
/// colour pass reduced `z.A z` with `z.q` and `r.z`.
#[test]
fn the_update_writes_the_partials_of_max_r() {
    let step = fcg_step();
    let dispatches: Vec<Op> = step
        .iter()
        .filter_map(|s| match s {
            Step::Dispatch(op) => Some(*op),
            _ => None,
        })
        .collect();
    assert_eq!(
        dispatches,
        [Op::FcgUpdate { mode: 0 }, Op::DotFinal { stage: STAGE_R }]
    );
    for first in [true, false] {
        let s = shape(6);
        let (direction, stage) = if first {
            (fcg_first_direction(&s), STAGE_RZ)
        } else {
            (fcg_direction(&s), STAGE_Z)
        };
        let k = direction.len();
        assert_eq!(
            direction[k - 3..],
            [
                Step::Dispatch(Op::SmoothDotLevel0 { stage, colour: 0 }),
                Step::Dispatch(Op::DotFinal { stage: STAGE_ZPQ }),
                Step::Dispatch(Op::FcgUpdate {
                    mode: if first { 2 } else { 1 }
                }),
            ]
        );
    }
    for n in [16, 64, 256, 512, 1024, 4096, 16384] {
        let groups = Op::FcgUpdate { mode: 0 }.workgroups(n);
        assert_eq!(groups, Op::DotPartial { stage: STAGE_R }.workgroups(n));
        assert_eq!(groups, [partial_groups(n * n), 1, 1]);
        assert!(groups[0] <= MAX_PARTIALS);
    }
}

/// `q = A p` is recomputed by the passes that read it (`DotPartial` `p.q` / `z.q`, `FcgUpdate`
/// mode 0), so `p` must not change between the `p.q` of an iteration and the `z.q` of the next
/// direction: only the direction's last pass writes it.
#[test]
fn p_is_unchanged_while_q_is_read() {
    let s = shape(6);
    let writes_p = |st: &Step| {
        matches!(
            st,
            Step::Dispatch(Op::FcgUpdate { mode: 1 | 2 })
                | Step::Dispatch(Op::LiftPush { .. })
                | Step::Dispatch(Op::LiftPull { .. })
        )
    };
    let mut steps = fcg_step();
    steps.extend(fcg_direction(&s));
    let last = steps.len() - 1;
    assert_eq!(steps[last], Step::Dispatch(Op::FcgUpdate { mode: 1 }));
    assert!(!steps[..last].iter().any(writes_p));
    assert!(!steps.contains(&Step::Dispatch(Op::ApplyLevel0)));
    // FCG's start: `p = z` last, after the `z.q` whose `beta` it ignores.
    let init = fcg_init(&s);
    assert_eq!(
        init.last(),
        Some(&Step::Dispatch(Op::FcgUpdate { mode: 2 }))
    );
    assert!(!init[..init.len() - 1].iter().any(writes_p));
}

/// The passes that read level 1's stencils compute them (the `coarse_level1` variants), every
/// other coarse pass reads records; the assembly stores levels 2 .. only.
#[test]
fn level_one_stencils_are_computed_not_stored() {
    for levels in [2, 3, 6] {
        let kc = levels - 1;
        for op in all_ops(levels) {
            let reads_level1 = match op {
                Op::GalerkinCoarse { level } => level == 2,
                Op::SmoothCoarse { level, .. }
                | Op::SweepCoarse { level, .. }
                | Op::ResidualRestrictCoarse { level }
                | Op::ProlongCoarse { level, .. }
                | Op::ProlongCoarseAlt { level, .. } => level == 1,
                Op::CoarsestSolve => kc == 1,
                _ => false,
            };
            for texture_h in [false, true] {
                let computes = op
                    .kernel(kc, texture_h)
                    .imports()
                    .contains(&("coarse", "coarse_level1"));
                assert_eq!(reads_level1, computes, "{op:?} with {levels} levels");
            }
        }
        let built: Vec<usize> = assemble(&shape(levels), false)
            .iter()
            .filter_map(|s| match s {
                Step::Dispatch(Op::GalerkinCoarse { level }) => Some(*level),
                _ => None,
            })
            .collect();
        assert_eq!(built, (2..levels).collect::<Vec<_>>());
    }
}

/// With `h` in the height texture, exactly the passes that bind `h` at binding 1 use the
/// texture variants (the preconditioner's residual and prolongation bind `z` there).
#[test]
fn texture_h_variants_bind_h_only() {
    use crate::gpu::shaders::Variant;
    for op in all_ops(6) {
        let binds_h = matches!(
            op,
            Op::Assemble { .. }
                | Op::ResidualRestrictLevel0 { solution: true }
                | Op::ProlongLevel0 { solution: true }
                | Op::ApplyLevel0
                | Op::FcgUpdate { .. }
                | Op::LiftPull { .. }
                | Op::RelaxTiles { .. }
                | Op::SpikeRelax { .. }
                | Op::SpikeUpdate
        );
        assert_ne!(op.kernel(5, false).base().1, Variant::TextureH, "{op:?}");
        let k = op.kernel(5, true);
        assert_eq!(k.base().1 == Variant::TextureH, binds_h, "{op:?}");
        assert_eq!(k.file(), op.kernel(5, false).file());
    }
}

/// The local relaxation: the residual, the mask pass and the box's, `sweeps` red-black sweeps in
/// tile passes from `h` into the scratch copy and back (at most 5 sweeps each, an even number of
/// passes, so `h` holds the result), the count copied; no work units of its own (the count gives
/// them).
#[test]
fn local_relaxation_plan() {
    let steps = local_relaxation(3);
    assert_eq!(steps.len(), 3 + 2 + 1);
    assert_eq!(steps[0], Step::Dispatch(Op::ApplyLevel0));
    assert_eq!(steps[1], Step::Dispatch(Op::RelaxMask { mode: 0 }));
    assert_eq!(steps[2], Step::Dispatch(Op::RelaxMask { mode: 1 }));
    let tiles = |sweeps: u32, to_z: bool| Op::RelaxTiles { sweeps, to_z };
    assert_eq!(steps[3], Step::Dispatch(tiles(2, true)));
    assert_eq!(steps[4], Step::Dispatch(tiles(1, false)));
    assert_eq!(steps[5], Step::CopyRelaxCells);
    assert_eq!(work_units(&steps), 0.0);
    assert_eq!(relax_tiles(10), vec![tiles(5, true), tiles(5, false)]);
    assert_eq!(relax_tiles(4), vec![tiles(2, true), tiles(2, false)]);
    assert_eq!(relax_tiles(1), vec![tiles(1, true), tiles(0, false)]);
    assert_eq!(
        relax_tiles(11),
        vec![
            tiles(3, true),
            tiles(3, false),
            tiles(3, true),
            tiles(2, false)
        ]
    );
    assert!(relax_tiles(0).is_empty());
    let ops = all_ops(6);
    for step in &steps {
        if let Step::Dispatch(op) = step {
            assert!(ops.contains(op), "{op:?} has no pass");
        }
    }
    assert_eq!(tiles(5, false).workgroups(256), [16, 16, 1]);
    assert_eq!(Op::RelaxMask { mode: 0 }.workgroups(256), [16, 16, 1]);
    assert_eq!(Op::RelaxMask { mode: 1 }.workgroups(256), [1, 1, 1]);
}

/// `steps` with each fused pass replaced by the passes it runs.
fn expand(steps: &[Step]) -> Vec<Step> {
    untile(steps)
        .iter()
        .flat_map(|s| match s {
            Step::Dispatch(op @ Op::CoarseFused { .. }) => op.fused_steps(),
            s => vec![*s],
        })
        .collect()
}

/// `steps` with every tile sweep as its colour passes and every prolongation in place.
fn untile(steps: &[Step]) -> Vec<Step> {
    steps
        .iter()
        .flat_map(|s| match *s {
            Step::Dispatch(Op::SweepCoarse {
                level,
                colours,
                phases,
                restrict,
                ..
            }) => (0..phases)
                .map(|m| {
                    Step::Dispatch(Op::SmoothCoarse {
                        level,
                        colour: (colours >> (2 * m)) & 3,
                    })
                })
                .chain(restrict.then_some(Step::Dispatch(Op::ResidualRestrictCoarse { level })))
                .collect(),
            Step::Dispatch(Op::ProlongCoarseAlt { level, set }) => {
                vec![Step::Dispatch(Op::ProlongCoarse { level, set })]
            }
            Step::Dispatch(Op::SweepLevel0FromZero) => [0, 1]
                .map(|colour| Step::Dispatch(Op::SmoothLevel0 { colour }))
                .to_vec(),
            Step::Dispatch(Op::SweepRestrictLevel0FromZero) => vec![
                Step::Dispatch(Op::SmoothLevel0 { colour: 0 }),
                Step::Dispatch(Op::SmoothLevel0 { colour: 1 }),
                Step::Dispatch(Op::ResidualRestrictLevel0 { solution: false }),
            ],
            Step::Dispatch(Op::ProlongSmoothLevel0 { colour }) => vec![
                Step::Dispatch(Op::ProlongLevel0 { solution: false }),
                Step::Dispatch(Op::SmoothLevel0 { colour }),
            ],
            Step::Dispatch(Op::SmoothDotLevel0 { stage, colour }) => vec![
                Step::Dispatch(Op::SmoothLevel0 { colour }),
                Step::Dispatch(Op::DotPartial { stage }),
            ],
            s => vec![s],
        })
        .collect()
}

/// Tile sweeps run the colour passes they replace, in their order, from the input they read: a
/// run starts right after its level's clear (from zero) or after a prolongation into `alt`, and
/// holds whole sweeps (at most two); the level-0 sweep after `z = 0` is one pass. Every run the
/// plans make is in `all_ops`. At 1024^2 a V-cycle is 25 dispatches (the fusions of
/// `fuse_passes` too) instead of 80.
#[test]
fn tile_sweeps_replace_whole_coarse_sweeps() {
    for levels in 2..=12 {
        for fuse_side in [0, FUSED_SIDE] {
            let s = CycleShape {
                fuse_side,
                ..shape(levels)
            };
            let ops = all_ops(levels);
            for plan in [precondition(&s), fmg(&s)] {
                for (i, step) in plan.iter().enumerate() {
                    let Step::Dispatch(
                        op @ Op::SweepCoarse {
                            level,
                            phases,
                            from_zero,
                            ..
                        },
                    ) = *step
                    else {
                        continue;
                    };
                    assert!(ops.contains(&op), "{op:?} missing from all_ops");
                    assert!(phases == 4 || phases == 8, "{op:?}");
                    let before = if from_zero {
                        Step::ClearU { level }
                    } else {
                        match plan[i - 1] {
                            Step::Dispatch(Op::ProlongCoarseAlt { set, .. }) => {
                                Step::Dispatch(Op::ProlongCoarseAlt { level, set })
                            }
                            other => other,
                        }
                    };
                    assert_eq!(plan[i - 1], before, "{op:?} at {i}");
                }
                // Nothing else reads `alt`: every prolongation into it is followed by its sweep.
                for (i, step) in plan.iter().enumerate() {
                    if let Step::Dispatch(Op::ProlongCoarseAlt { level, .. }) = *step {
                        assert!(matches!(
                            plan[i + 1],
                            Step::Dispatch(Op::SweepCoarse { level: l, from_zero: false, .. })
                                if l == level
                        ));
                    }
                }
                assert_eq!(fuse_passes(tile_sweeps(untile(&plan))), plan);
            }
        }
    }
    let s = CycleShape {
        fuse_side: FUSED_SIDE,
        ..shape(8)
    };
    assert_eq!(dispatches(&precondition(&s)), 25);
    assert_eq!(
        precondition(&s)[1],
        Step::Dispatch(Op::SweepRestrictLevel0FromZero)
    );
    assert_eq!(
        precondition(&s)[precondition(&s).len() - 2],
        Step::Dispatch(Op::ProlongSmoothLevel0 { colour: 1 })
    );
    assert_eq!(dispatches(&untile(&precondition(&s))), 80);
    assert_eq!(
        work_units(&precondition(&s)),
        work_units(&untile(&precondition(&s)))
    );
}

fn dispatches(steps: &[Step]) -> usize {
    steps
        .iter()
        .filter(|s| matches!(s, Step::Dispatch(_)))
        .count()
}

/// The fused passes run exactly the unfused plan's passes, in its order (the preconditioner and
/// FMG, every size), with the same work units; the levels they run are those of side <= 64 from
/// level 2 on, and a hierarchy without two such levels fuses nothing.
#[test]
fn fused_passes_run_the_unfused_plan() {
    for levels in 2..=12 {
        let plain = shape(levels);
        let fused = CycleShape {
            fuse_side: FUSED_SIDE,
            ..plain
        };
        let kc = levels - 1;
        match fused.fused_from() {
            Some(kf) => {
                assert!(kf >= MIN_FUSED_LEVEL && kf < kc);
                assert!(COARSEST_SIDE << (kc - kf) <= FUSED_SIDE);
                assert!(kf == MIN_FUSED_LEVEL || COARSEST_SIDE << (kc - kf + 1) > FUSED_SIDE);
            }
            None => assert!(levels <= 5, "{levels} levels fuse nothing"),
        }
        // A solver using the levels of one `shift` levels finer fuses the same levels.
        for shift in 1..=2 {
            let guest = CycleShape {
                levels: levels - shift.min(levels - 2),
                shift: shift.min(levels - 2),
                ..fused
            };
            if let (Some(g), Some(h)) = (guest.fused_from(), fused.fused_from()) {
                assert_eq!(g + guest.shift, h);
                assert!(g >= 2);
            } else {
                assert_eq!(fused.fused_from(), None);
            }
        }
        for (a, b) in [
            (precondition(&plain), precondition(&fused)),
            (fmg(&plain), fmg(&fused)),
        ] {
            assert_eq!(expand(&b), untile(&a), "{levels} levels");
            assert_eq!(work_units(&b), work_units(&a));
            for op in fused_ops(&fused) {
                assert_eq!(fused_program(op).len(), op.fused_steps().len());
            }
        }
    }
    // 1024^2 (8 levels): the V-cycle's levels 5 ..= 7 (64^2 .. 8^2) in one pass.
    let s = CycleShape {
        fuse_side: FUSED_SIDE,
        ..shape(8)
    };
    assert_eq!(s.fused_from(), Some(4));
    assert_eq!(dispatches(&untile(&precondition(&shape(8)))), 200);
    assert_eq!(dispatches(&untile(&precondition(&s))), 80);
    let words = fused_program(Op::CoarseFused {
        shape: s,
        fmg: false,
    });
    assert_eq!(words[0], fused_kind::SMOOTH);
    assert_eq!(words[3], fused_kind::SMOOTH | 3 << 8);
    assert_eq!(words[4], fused_kind::RESIDUAL_RESTRICT);
    assert_eq!(words[5], fused_kind::CLEAR_U | 1 << 4);
    assert!(words.contains(&(fused_kind::COARSEST_SOLVE | 3 << 4)));
}

/// The plan as it was written before the cycle became backend-neutral (`crate::cycle`),
/// kept to check that the mapped plans are the same passes.
fn old_coarse_cycle(shape: &CycleShape, k: usize, out: &mut Vec<Step>) {
    if Some(k) == shape.fused_from() {
        out.push(Step::Dispatch(Op::CoarseFused {
            shape: *shape,
            fmg: false,
        }));
        return;
    }
    if k == shape.coarsest() {
        out.push(Step::Dispatch(Op::CoarsestSolve));
        return;
    }
    for _ in 0..shape.pre_sweeps {
        for colour in 0..4 {
            out.push(Step::Dispatch(Op::SmoothCoarse { level: k, colour }));
        }
    }
    out.push(Step::Dispatch(Op::ResidualRestrictCoarse { level: k }));
    out.push(Step::ClearU { level: k + 1 });
    for _ in 0..shape.visits(k) {
        old_coarse_cycle(shape, k + 1, out);
    }
    out.push(Step::Dispatch(Op::ProlongCoarse {
        level: k,
        set: false,
    }));
    for _ in 0..shape.post_sweeps {
        for colour in (0..4).rev() {
            out.push(Step::Dispatch(Op::SmoothCoarse { level: k, colour }));
        }
    }
}

fn old_precondition(shape: &CycleShape) -> Vec<Step> {
    let mut out = vec![Step::ClearZ];
    for _ in 0..shape.pre_sweeps {
        out.push(Step::Dispatch(Op::SmoothLevel0 { colour: 0 }));
        out.push(Step::Dispatch(Op::SmoothLevel0 { colour: 1 }));
    }
    out.push(Step::Dispatch(Op::ResidualRestrictLevel0 {
        solution: false,
    }));
    out.push(Step::ClearU { level: 1 });
    for _ in 0..shape.visits(0) {
        old_coarse_cycle(shape, 1, &mut out);
    }
    out.push(Step::Dispatch(Op::ProlongLevel0 { solution: false }));
    for _ in 0..shape.post_sweeps {
        out.push(Step::Dispatch(Op::SmoothLevel0 { colour: 1 }));
        out.push(Step::Dispatch(Op::SmoothLevel0 { colour: 0 }));
    }
    out
}

fn old_fmg(shape: &CycleShape) -> Vec<Step> {
    let mut out = lift(shape);
    out.push(Step::Dispatch(Op::ResidualRestrictLevel0 {
        solution: true,
    }));
    old_fmg_coarse(shape, 1, &mut out);
    out.push(Step::Dispatch(Op::ProlongLevel0 { solution: true }));
    out
}

fn old_fmg_coarse(shape: &CycleShape, top: usize, out: &mut Vec<Step>) {
    let kc = shape.coarsest();
    let fused = shape.fused_from().filter(|&kf| kf >= top);
    let bottom = fused.unwrap_or(kc);
    for level in top..bottom {
        out.push(Step::Dispatch(Op::RestrictSum { level }));
    }
    match fused {
        Some(_) => out.push(Step::Dispatch(Op::CoarseFused {
            shape: *shape,
            fmg: true,
        })),
        None => out.push(Step::Dispatch(Op::CoarsestSolve)),
    }
    for k in (top..bottom).rev() {
        out.push(Step::Dispatch(Op::ProlongCoarse {
            level: k,
            set: true,
        }));
        old_coarse_cycle(shape, k, out);
    }
}

/// The passes mapped from `crate::cycle` are exactly the plan's former hand-written
/// sequence: every size, fused or not, for several parameter sets.
#[test]
fn plans_from_the_neutral_cycle_equal_the_former_plans() {
    let params = [
        (1, 1, 2, 1, 3),
        (2, 1, 2, 0, 4),
        (0, 2, 1, 0, 0),
        (1, 2, 3, 2, 9),
    ];
    for levels in 2..=12 {
        for (pre, post, gamma, from, until) in params {
            for fuse_side in [0, FUSED_SIDE] {
                for shift in [0, 1, 2] {
                    if shift >= levels - 1 {
                        continue;
                    }
                    let s = CycleShape {
                        levels,
                        pre_sweeps: pre,
                        post_sweeps: post,
                        gamma,
                        gamma_from_level: from,
                        gamma_until_level: until,
                        fuse_side,
                        shift,
                    };
                    assert_eq!(untile(&precondition(&s)), old_precondition(&s), "{s:?}");
                    assert_eq!(untile(&fmg(&s)), old_fmg(&s), "{s:?}");
                    for k in 1..levels {
                        let (mut a, mut b) = (Vec::new(), Vec::new());
                        coarse_cycle(&s, k, &mut a);
                        old_coarse_cycle(&s, k, &mut b);
                        assert_eq!(untile(&a), b, "{s:?} level {k}");
                    }
                }
            }
        }
    }
}

#[test]
fn labels() {
    assert_eq!(
        Op::SmoothCoarse {
            level: 3,
            colour: 2
        }
        .label(5),
        "multigrid.smooth_coarse.l3.c2"
    );
    assert_eq!(Op::CoarsestSolve.label(5), "multigrid.coarsest_solve.l5");
    assert_eq!(
        Op::GalerkinCoarse { level: 2 }.label(5),
        "multigrid.galerkin_coarse.l2"
    );
}
