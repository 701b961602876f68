//! Tests of the solver's warm path: the kept residual and the windowed assembly against whole
//! recomputations.

use super::*;
use crate::cpu::Hierarchy;
use crate::fields;
use crate::problem::FieldProblem;
use terrasketch_sketch::benchmark_sketch;

/// The benchmark sketch solved on a grid of side `n`.
fn solved_benchmark(n: usize) -> (Sketch, Grid, CpuSolver) {
    let sketch = benchmark_sketch();
    let grid = Grid::new(n, sketch.extent_m).expect("grid");
    let mut s = CpuSolver::new(grid, SolverParams::default()).expect("solver");
    s.set_sketch(&sketch);
    s.solve();
    (sketch, grid, s)
}

/// Moves stroke `stroke` by `d` metres (east, north) and updates `s` with its old and new
/// spans.
fn move_stroke(s: &mut CpuSolver, sketch: &mut Sketch, stroke: usize, d: [f64; 2]) {
    let grid = s.grid();
    let mut spans = ConstraintMaps::stroke_spans(sketch, stroke, &grid);
    for p in &mut sketch.strokes[stroke].points {
        p[0] += d[0];
        p[1] += d[1];
    }
    spans.extend(ConstraintMaps::stroke_spans(sketch, stroke, &grid));
    s.update_sketch_spans(sketch, &spans);
}

/// A warm start recomputes the heights' residual only where the edit changed the problem or
/// the heights (the windowed assembly's region and the local relaxation's windows) and keeps
/// the last solve's elsewhere: at every start of a drag the kept vector equals a fresh `f - A
/// h` up to the rounding of FCG's recurrence, also when a second edit arrives between the
/// first one's relaxation and FCG's start.
#[test]
fn warm_starts_keep_the_residual_outside_the_edit() {
    let n = 512;
    let (mut sketch, _, mut s) = solved_benchmark(n);
    let scale = s.heights.residual_scale();
    let mut progress = Progress {
        finest_ready_level: None,
        residual: 0.0,
        work_units: 0.0,
        field_work_units: 0.0,
        vcycles: 0,
        converged: false,
    };
    for frame in 0..8 {
        // Odd frames: a second edit (another stroke) after the first one's field solve and
        // relaxation, before FCG starts: the start must cover both.
        for (edit, stroke) in [(0, 0), (1, 3)] {
            if edit == 1 && frame % 2 == 0 {
                continue;
            }
            move_stroke(&mut s, &mut sketch, stroke, [30.0, 20.0]);
            if edit == 0 && frame % 2 == 1 {
                while s.phase != Phase::FcgStart {
                    s.unit(&mut progress);
                }
            }
        }
        let starts = s.fcg.partial_starts;
        while !matches!(s.phase, Phase::Fcg | Phase::Done) {
            s.unit(&mut progress);
        }
        assert_eq!(
            s.fcg.partial_starts,
            starts + 1,
            "frame {frame}: a partial start"
        );
        let kept = s.fcg.residual_vector();
        let fresh = s.heights.residual_vector(&s.height_state.h);
        let (diag, f) = s.heights.level0_diag_rhs();
        let h = &s.height_state.h;
        // Per cell, the rounding of a fresh `f - (d h - sum a h_j)` (large on strongly soft
        // cells, where `f` and `d h` are large) plus that of the recurrence.
        let off = (0..n * n)
            .filter(|&k| {
                let bound = 1e-6 * (f[k].abs() + (diag[k] * h[k]).abs()) + 1e-3;
                (kept[k] - fresh[k]).abs() > bound
            })
            .count();
        let largest = fresh.iter().fold(0.0f32, |m, v| m.max(v.abs())) * scale;
        assert!(largest > 1e-3, "frame {frame}: the edit left no residual");
        assert_eq!(off, 0, "frame {frame}: cells whose kept residual is stale");
        s.solve();
    }
}

/// After warm updates that assemble the height problem only around the edit (the windowed
/// path), the level-0 operator and right-hand side and every coarse operator equal, bit for
/// bit, a whole assembly from the same constraints and gradient field. The gradient field's
/// coarse levels, deferred while its warm solves run no cycle, equal the whole assembly's
/// once flushed, after one and after two deferred updates.
#[test]
fn windowed_warm_assembly_equals_a_whole_assembly() {
    let n = 512;
    let (mut sketch, grid, mut s) = solved_benchmark(n);
    let [ax, ay] = grid.axis_weights();
    for frame in 0..4 {
        move_stroke(&mut s, &mut sketch, 0, [30.0, 20.0]);
        s.solve();
        let p = FieldProblem {
            n,
            ax,
            ay,
            weight: s.maps.elev_weight.clone(),
            value: s.heights.values().to_vec(),
            ..FieldProblem::default()
        };
        let (band, ew, gx, gy) = (&s.maps.band_weight, &p.weight, &s.grad_x.h, &s.grad_y.h);
        let edges = |j: usize, c: (usize, usize), de: &mut [f32], dn: &mut [f32], t: &mut [f32]| {
            fields::edge_differences_row(&grid, [band, ew], (gx, gy), j, c, de, dn, t)
        };
        let mut whole = Hierarchy::new(n, ax, ay);
        whole.assemble_rows_with(&p, 0..n, Some(&edges), None);
        let (d0, f0) = whole.level0_diag_rhs();
        let (d1, f1) = s.heights.level0_diag_rhs();
        let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert!(bits(d0) == bits(d1), "frame {frame}: level-0 diagonal");
        assert!(bits(f0) == bits(f1), "frame {frame}: right-hand side");
        assert!(
            whole.coarse_fingerprint() == s.heights.coarse_fingerprint(),
            "frame {frame}: coarse operators"
        );
        // The gradient field's problem, both right-hand sides.
        let px =
            FieldProblem::diffusion(n / 2, [ax, ay], s.grad_w.clone(), s.grad.values().to_vec());
        let mut whole = Hierarchy::new(n / 2, ax, ay);
        whole.assemble_rows(&px, 0..n / 2);
        let (d0, f0) = whole.level0_diag_rhs();
        let (d1, f1) = s.grad.level0_diag_rhs();
        assert!(bits(d0) == bits(d1), "frame {frame}: gradient diagonal");
        assert!(bits(f0) == bits(f1), "frame {frame}: gx right-hand side");
        assert_eq!(whole.relief().to_bits(), s.grad.relief().to_bits());
        // The drag's field solves ran no cycle: the gradient's coarse levels wait.
        assert!(s.grad.coarse_pending(), "frame {frame}: deferred");
        if frame == 1 {
            // Stale now; frames 1 and 2 accumulate until the flush of frame 2.
            assert!(whole.coarse_fingerprint() != s.grad.coarse_fingerprint());
            continue;
        }
        s.grad.flush_coarse();
        assert!(!s.grad.coarse_pending());
        assert!(
            whole.coarse_fingerprint() == s.grad.coarse_fingerprint(),
            "frame {frame}: gradient coarse operators"
        );
        assert!(s.grad.general_lists_are_complete() && s.heights.general_lists_are_complete());
        let py = FieldProblem::diffusion(
            n / 2,
            [ax, ay],
            s.grad_w.clone(),
            s.grad_rhs_y.values_mut().to_vec(),
        );
        whole.assemble_values_rows(&py, 0..n / 2);
        s.grad.swap_rhs(&mut s.grad_rhs_y);
        let same = bits(whole.level0_diag_rhs().1) == bits(s.grad.level0_diag_rhs().1)
            && whole.relief().to_bits() == s.grad.relief().to_bits();
        s.grad.swap_rhs(&mut s.grad_rhs_y);
        assert!(same, "frame {frame}: gy right-hand side");
    }
    assert_eq!(
        s.windowed_assemblies, 4,
        "every update took the windowed path"
    );
    // A first assembly that changes few diagonals still builds every coarse cell: a hard band
    // from the west border (diagonal 0, as before any assembly) is listed in the coarse rows.
    let m = 128;
    let mut w = vec![0.0f32; m * m];
    for j in 0..m {
        for i in 0..m / 2 {
            w[j * m + i] = 1.0;
        }
    }
    let p = FieldProblem::diffusion(m, [1.0, 1.0], w, vec![5.0; m * m]);
    let mut h = Hierarchy::new(m, 1.0, 1.0);
    h.assemble_rows(&p, 0..m);
    assert!(h.general_lists_are_complete());
}
