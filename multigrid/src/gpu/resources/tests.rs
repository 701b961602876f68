//! Tests of the buffer list, the ranges shared between solvers and the device-limit check.

use super::*;
use crate::cycle::CycleShape;
use crate::gpu::params::{STAGE_R, STAGE_RZ, STAGE_Z};
use crate::gpu::plan::Op;

#[test]
fn sizes_and_levels() {
    assert_eq!(solve_levels(16), 2);
    assert_eq!(solve_levels(256), 6);
    let s = buffer_sizes(256, true);
    // Levels 1 ..= 5: stencils from level 2 on (level 1's are computed), `u`, `f`, `alt` of
    // levels 1 ..= 3, and of the fused levels 4, 5 one `u`, `f` buffer each.
    assert_eq!(s.len(), 10 + 4 + 9 + 2 + 2);
    assert_eq!(buffer_sizes(256, false).len(), 8 + 4 + 9 + 2 + 2);
    assert!(s.iter().any(|(l, _)| l == "multigrid.alt.l3"));
    assert!(!s.iter().any(|(l, _)| l.starts_with("multigrid.alt.l4")));
    let fused_u = s.iter().find(|(l, _)| l == "multigrid.u.l4_down").unwrap();
    assert_eq!(fused_u.1, 4 * (16 * 16 + 8 * 8));
    assert!(s.iter().any(|(l, _)| l == "multigrid.u.l3"));
    assert!(!s.iter().any(|(l, _)| l == "multigrid.u.l5"));
    // 4096^2: levels 1 ..= 5 (2048^2 .. 128^2) unfused, 6 ..= 9 (64^2 .. 8^2) fused.
    let big = buffer_sizes(4096, false);
    assert!(big.iter().any(|(l, _)| l == "multigrid.f.l5"));
    assert!(big.iter().any(|(l, _)| l == "multigrid.f.l6_down"));
    assert!(!s.iter().any(|(l, _)| l == "multigrid.stencil.l1"));
    // FCG recomputes `q = A p` where it reads it: no buffer.
    assert!(!s.iter().any(|(l, _)| l == "multigrid.q.l0"));
    assert!(
        !buffer_sizes(256, false)
            .iter()
            .any(|(l, _)| l.contains("d_east") || l.contains("d_north"))
    );
    assert_eq!(
        s.iter()
            .find(|(l, _)| l == "multigrid.stencil.l2")
            .unwrap()
            .1,
        64 * 64 * 24
    );
    assert_eq!(buffer_sizes(16, false).len(), 8 + 3 + 2);
    // The FMG lift's packed levels fit in the level-0 vectors it borrows (`z`, `p` or `r`),
    // and the heights' level-2 stencils hold the fields' `z` (6 units).
    for n in [64, 256, 4096, MAX_SIDE] {
        let s = buffer_sizes(n, false);
        for name in ["multigrid.z.l0", "multigrid.p.l0", "multigrid.r.l0"] {
            let bytes = s.iter().find(|(l, _)| l == name).unwrap().1;
            assert!(4 * plan::lift_len(n) as u64 <= bytes, "{name} at n = {n}");
        }
        let l2 = s
            .iter()
            .find(|(l, _)| l == "multigrid.stencil.l2")
            .unwrap()
            .1;
        assert_eq!(l2, Host::Stencil2.units() * (n * n / 16 * 4) as u64);
    }
}

/// The ranges lent to `GpuSolver`'s gradient field and roughness and to the rasteriser's `vy`
/// fit in their hosts, lie only in heights' buffers dead while the fields run (level-0 `diag`,
/// `z`, `p` and the level-2 stencils; never `weight`, `value`, `r`, `h`), do not overlap, cover
/// every guest buffer but roughness's `h`, and no solver pass binds one host both read-only and
/// read-write.
#[test]
fn lent_ranges_fit_and_do_not_overlap() {
    use Level0Buf::*;
    // Units of n^2 / 16 floats: height buffers 16, gradient-field buffers 4, roughness 1.
    let mut ranges: Vec<(Host, u64, u64, String)> = GUEST_LEVEL0
        .iter()
        .map(|g| (g.host, g.at, g.units(), format!("{}.{:?}", g.shift, g.buf)))
        .collect();
    ranges.push((VY_HOME.0, VY_HOME.1, 4, "vy".into()));
    for (i, a) in ranges.iter().enumerate() {
        assert!(
            [
                Host::Level0(Diag),
                Host::Level0(Z),
                Host::Level0(P),
                Host::Stencil2
            ]
            .contains(&a.0),
            "{} in {:?}",
            a.3,
            a.0
        );
        assert!(
            a.1 + a.2 <= a.0.units(),
            "{} past the end of {:?}",
            a.3,
            a.0
        );
        for b in &ranges[i + 1..] {
            let apart = a.0 != b.0 || a.1 + a.2 <= b.1 || b.1 + b.2 <= a.1;
            assert!(apart, "{} and {} overlap in {:?}", a.3, b.3, a.0);
        }
    }
    assert_eq!(Level0Buf::ALL.map(Level0Buf::name), LEVEL0);
    let mut all = LEVEL0.to_vec();
    all.sort();
    let mut grad = borrowed_level0(1);
    grad.sort();
    assert_eq!(grad, all);
    let mut rough = borrowed_level0(2);
    rough.push("h");
    rough.sort();
    assert_eq!(rough, all);
    // The rasteriser writes the roughness problem (`weight`, `value`, adjacent: one binding)
    // while writing the level-0 maps into `weight`, `value`, `r`, `diag`, `z` of the heights;
    // the gradient downsampling's x pass writes grad `weight` / `value` while reading the maps
    // in `r`, `diag`, `z`, its y pass `vy` while reading `r`, `z`; the copy of `vy` into the
    // gradient field's `value` needs two buffers.
    let home = |shift: usize, buf: Level0Buf| {
        GUEST_LEVEL0
            .iter()
            .find(|g| g.shift == shift && g.buf == buf)
            .map(|g| (g.host, g.at))
    };
    assert_eq!(home(2, Weight).map(|h| (h.0, h.1 + 1)), home(2, Value));
    for buf in [Weight, Value] {
        for shift in [1, 2] {
            let (host, _) = home(shift, buf).unwrap();
            assert!(
                ![Weight, Value, R, Diag, Z]
                    .map(Host::Level0)
                    .contains(&host)
            );
        }
    }
    assert!(![R, Z].map(Host::Level0).contains(&VY_HOME.0));
    assert_ne!(home(1, Value).map(|h| h.0), Some(VY_HOME.0));
    let home = |shift: usize, name: &str| {
        let buf = Level0Buf::ALL.into_iter().find(|b| b.name() == name)?;
        home(shift, buf).map(|h| h.0)
    };
    // The heights keep `f` in their own `p`, `h` in the height texture, level 1's `u` in
    // `value` (from 0) and its `f` in `weight` from 3/4, past the mips' constraint pyramid
    // (first `(n^2 - 1) / 3` pairs).
    assert_eq!(borrowed_level0(0), vec!["f", "h", "u.l1", "f.l1", "alt.l1"]);
    for n in [16, 64, 4096, MAX_SIDE] {
        let c = super::super::mips::constraint_offsets(n);
        assert!(c[c.len() - 1] * 8 <= 3 * n * n, "pyramid at n = {n}");
    }
    // The level-0 buffers each solver pass reads and writes (as `pass_spec` binds them; the
    // guests have no edge differences: the assembly's unread slots are `weight`). A guest's
    // buffers that one pass reads and those it writes must lie in different height buffers
    // (roughness's own `h` is no height buffer).
    let passes: [(&str, &[&str], &[&str]); 13] = [
        ("assemble", &["weight", "value"], &["diag", "f", "h"]),
        // The level-1 passes compute level 1's stencils from `diag` and write coarse buffers.
        ("level-1 passes", &["diag"], &[]),
        ("smooth_level0", &["r", "diag"], &["z"]),
        ("residual_restrict_level0", &["z", "r", "diag"], &[]),
        ("residual_restrict_level0.h", &["h", "f", "diag"], &[]),
        ("prolong_level0", &["diag"], &["z"]),
        ("prolong_level0.h", &["diag"], &["h"]),
        ("apply_level0", &["h", "f", "diag"], &["r"]),
        ("dot_partial", &["r", "z", "p", "diag"], &[]),
        ("fcg_update", &["z", "diag"], &["h", "r", "p"]),
        ("lift_push", &["diag", "value"], &["z", "p"]),
        ("lift_pull", &["diag", "value", "z"], &["p", "h"]),
        ("clear_z", &[], &["z"]),
    ];
    for shift in [1, 2] {
        for (pass, reads, writes) in passes {
            for r in reads {
                for w in writes {
                    let (hr, hw) = (home(shift, r), home(shift, w));
                    assert!(
                        hr.is_none() || hr != hw,
                        "{pass} of the field at shift {shift} reads {r} and writes {w}, both in {hr:?}"
                    );
                }
            }
        }
    }
}

/// Who owns the data in a range: a solver of `GpuSolver` (the heights, the gradient field,
/// roughness) or the rasteriser's maps and the mips' pyramid.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
enum Who {
    Heights,
    Grad,
    Rough,
    Raster,
    Mips,
}

/// A solver's buffer (`L0`, coarse level `k`), or the rasteriser's maps (band weight, the
/// gradient problem's y values) and the mips' pyramid.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
enum Buf {
    L0(Level0Buf),
    Stencil(usize),
    U(usize),
    Fc(usize),
    Alt(usize),
    Band,
    Vy,
    Pyramid,
}

type Tenant = (Who, Buf);

/// A physical buffer of `GpuSolver`: the heights' level-0 buffers (units of `n^2 / 16`
/// floats), the height texture, a field's own level-0 buffer (roughness's `h`), the heights' coarse buffers (the level-2
/// stencils in 6 units, the others one unit: their tenants share them whole).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
enum Phys {
    L0(Level0Buf),
    Texture,
    Own(Who, Level0Buf),
    Stencil(usize),
    U(usize),
    Fc(usize),
    Alt(usize),
}

/// Where a tenant lives, as `Buffers::new` places it for `GpuSolver` (`GUEST_LEVEL0`,
/// `VY_HOME`, a field's level k being the heights' level `k + shift`, the heights' `f` in
/// their `p`, `h` in the texture, level 1's `u` in `value` 0..4 and `f` in `weight` 12..16,
/// the mips' pyramid in `weight`'s first 2/3).
fn place(t: Tenant) -> (Phys, u64, u64) {
    use Level0Buf::*;
    let host = |h: Host| match h {
        Host::Level0(b) => Phys::L0(b),
        Host::Stencil2 => Phys::Stencil(2),
    };
    match t {
        (Who::Heights, Buf::L0(F)) => (Phys::L0(P), 0, 16),
        (Who::Heights, Buf::L0(H)) => (Phys::Texture, 0, 16),
        (Who::Heights, Buf::L0(b)) => (Phys::L0(b), 0, 16),
        (Who::Heights, Buf::U(1)) => (Phys::L0(Value), 0, 4),
        (Who::Heights, Buf::Fc(1)) => (Phys::L0(Weight), 12, 16),
        (Who::Heights, Buf::Stencil(2)) => (Phys::Stencil(2), 0, Host::Stencil2.units()),
        (Who::Heights, Buf::Stencil(k)) => (Phys::Stencil(k), 0, 1),
        (Who::Heights, Buf::U(k)) => (Phys::U(k), 0, 1),
        (Who::Heights, Buf::Fc(k)) => (Phys::Fc(k), 0, 1),
        (Who::Heights, Buf::Alt(1)) => (Phys::L0(Weight), 0, 4),
        (Who::Heights, Buf::Alt(k)) => (Phys::Alt(k), 0, 1),
        (who @ (Who::Grad | Who::Rough), b) => {
            let shift = if who == Who::Grad { 1 } else { 2 };
            match b {
                // A buffer not lent is the field's own (roughness's `h`).
                Buf::L0(b) => match GUEST_LEVEL0.iter().find(|g| g.shift == shift && g.buf == b) {
                    Some(g) => (host(g.host), g.at, g.at + g.units()),
                    None => (Phys::Own(who, b), 0, 1),
                },
                Buf::Stencil(k) => place((Who::Heights, Buf::Stencil(k + shift))),
                Buf::U(k) => place((Who::Heights, Buf::U(k + shift))),
                Buf::Fc(k) => place((Who::Heights, Buf::Fc(k + shift))),
                Buf::Alt(k) => place((Who::Heights, Buf::Alt(k + shift))),
                _ => unreachable!("{t:?}"),
            }
        }
        (Who::Raster, Buf::Band) => (Phys::L0(R), 0, 16),
        (Who::Raster, Buf::Vy) => (host(VY_HOME.0), VY_HOME.1, VY_HOME.1 + 4),
        (Who::Mips, Buf::Pyramid) => (Phys::L0(Weight), 0, 12),
        _ => unreachable!("{t:?}"),
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Access {
    Read,
    /// Overwrites the range before anything reads it.
    Write,
    /// Reads and writes (a smoother's unknowns, an update `x += ..`).
    Modify,
}

/// The buffers a plan step reads and writes (the passes' Reads / Writes headers in
/// `shaders/`, as `pass_spec` binds them; the reductions' and gates' own buffers left out).
/// `f_in_p`: the heights (their lift keeps its values in `r`). The fused pass is its steps.
fn accesses(step: plan::Step, levels: usize, who: Who) -> Vec<(Buf, Access)> {
    use Access::*;
    use Level0Buf::*;
    let kc = levels - 1;
    let heights = who == Who::Heights;
    let lift_values = Buf::L0(if heights { R } else { P });
    let st = |k: usize| {
        if k == 1 {
            Buf::L0(Diag)
        } else {
            Buf::Stencil(k)
        }
    };
    let l0 = Buf::L0;
    let op = match step {
        plan::Step::Dispatch(op) | plan::Step::Gated(op) => op,
        plan::Step::ClearU { level } => return vec![(Buf::U(level), Write)],
        plan::Step::ClearZ => return vec![(l0(Z), Write)],
        _ => return Vec::new(),
    };
    match op {
        Op::Assemble { cold } => {
            let band = if heights { Buf::Band } else { l0(Weight) };
            let h = if cold { Write } else { Modify };
            vec![
                (l0(Weight), Read),
                (l0(Value), Read),
                (band, Read),
                (l0(Diag), Write),
                (l0(F), Write),
                (l0(H), h),
            ]
        }
        Op::GalerkinCoarse { level } => {
            vec![(st(level - 1), Read), (Buf::Stencil(level), Write)]
        }
        Op::SmoothLevel0 { .. } => vec![(l0(R), Read), (l0(Diag), Read), (l0(Z), Modify)],
        Op::ProlongSmoothLevel0 { .. } => vec![
            (Buf::U(1), Read),
            (l0(R), Read),
            (l0(Diag), Read),
            (l0(Z), Modify),
        ],
        Op::SweepLevel0FromZero => vec![(l0(R), Read), (l0(Diag), Read), (l0(Z), Write)],
        Op::SweepRestrictLevel0FromZero => vec![
            (l0(R), Read),
            (l0(Diag), Read),
            (l0(Z), Write),
            (Buf::Fc(1), Write),
        ],
        Op::SmoothCoarse { level, .. } => vec![
            (st(level), Read),
            (Buf::Fc(level), Read),
            (Buf::U(level), Modify),
        ],
        Op::SweepCoarse {
            level,
            from_zero,
            restrict,
            ..
        } => {
            let mut v = vec![(st(level), Read), (Buf::Fc(level), Read)];
            if !from_zero {
                v.push((Buf::Alt(level), Read));
            }
            v.push((Buf::U(level), Write));
            if restrict {
                v.push((Buf::Fc(level + 1), Write));
            }
            v
        }
        Op::ProlongCoarseAlt { level, set } => {
            let mut v = vec![(st(level), Read), (Buf::U(level + 1), Read)];
            if !set {
                v.push((Buf::U(level), Read));
            }
            v.push((Buf::Alt(level), Write));
            v
        }
        Op::ResidualRestrictLevel0 { solution } => {
            let (x, rhs) = if solution { (H, F) } else { (Z, R) };
            vec![
                (l0(x), Read),
                (l0(rhs), Read),
                (l0(Diag), Read),
                (Buf::Fc(1), Write),
            ]
        }
        Op::ResidualRestrictCoarse { level } => vec![
            (st(level), Read),
            (Buf::U(level), Read),
            (Buf::Fc(level), Read),
            (Buf::Fc(level + 1), Write),
        ],
        Op::ProlongLevel0 { solution } => {
            let x = if solution { H } else { Z };
            vec![(Buf::U(1), Read), (l0(Diag), Read), (l0(x), Modify)]
        }
        Op::ProlongCoarse { level, set } => vec![
            (st(level), Read),
            (Buf::U(level + 1), Read),
            (Buf::U(level), if set { Write } else { Modify }),
        ],
        Op::RestrictSum { level } => vec![(Buf::Fc(level), Read), (Buf::Fc(level + 1), Write)],
        Op::CoarsestSolve => vec![(st(kc), Read), (Buf::Fc(kc), Read), (Buf::U(kc), Write)],
        Op::CoarseFused { .. } => op
            .fused_steps()
            .into_iter()
            .flat_map(|s| accesses(s, levels, who))
            .collect(),
        Op::ApplyLevel0 => vec![
            (l0(H), Read),
            (l0(F), Read),
            (l0(Diag), Read),
            (l0(R), Write),
        ],
        Op::RelaxMask { mode: 0 | 2 } => vec![(l0(R), Read), (l0(Z), Write)],
        // Mode 1 turns the windows' bounds into the tile passes' workgroups: it touches only
        // the relaxation box and the scalars, which no other tenant shares.
        Op::RelaxMask { .. } => Vec::new(),
        Op::SpikeRelax { .. } => vec![
            (l0(R), Read),
            (l0(Diag), Read),
            (l0(Z), Read),
            (l0(P), Write),
        ],
        Op::SpikeUpdate => vec![
            (l0(P), Read),
            (l0(Diag), Read),
            (l0(Z), Read),
            (l0(H), Modify),
            (l0(R), Modify),
        ],
        Op::RelaxTiles { to_z, .. } => {
            // The mask in `z`, `r` the scratch copy.
            let (from, to) = if to_z { (H, R) } else { (R, H) };
            vec![
                (l0(F), Read),
                (l0(Diag), Read),
                (l0(Z), Read),
                (l0(from), Read),
                (l0(to), Write),
            ]
        }
        // `z.q` also reads `p`, but the first direction ignores it (`p = z` follows), so
        // only `p.q` checks `p`.
        Op::DotPartial { stage: STAGE_Z } => {
            vec![(l0(R), Read), (l0(Z), Read), (l0(Diag), Read)]
        }
        Op::DotPartial { stage: STAGE_R } => vec![(l0(R), Read)],
        Op::DotPartial { stage: STAGE_RZ } => vec![(l0(R), Read), (l0(Z), Read)],
        Op::SmoothDotLevel0 { .. } => vec![(l0(R), Read), (l0(Diag), Read), (l0(Z), Modify)],
        Op::DotPartial { .. } => vec![(l0(P), Read), (l0(Diag), Read)],
        Op::FcgUpdate { mode: 0 } => vec![
            (l0(P), Read),
            (l0(Diag), Read),
            (l0(H), Modify),
            (l0(R), Modify),
        ],
        Op::FcgUpdate { mode: 1 } => vec![(l0(Z), Read), (l0(P), Modify)],
        Op::FcgUpdate { .. } => vec![(l0(Z), Read), (l0(P), Write)],
        // Level 1 from level 0's problem; the next levels from the previous ones, in the
        // same ranges.
        Op::LiftPush { level: 1 } => vec![
            (l0(Diag), Read),
            (l0(Value), Read),
            (l0(Z), Write),
            (lift_values, Write),
        ],
        Op::LiftPush { .. } => vec![(l0(Z), Modify), (lift_values, Modify)],
        Op::LiftPull { level: 0 } => vec![
            (l0(Z), Read),
            (lift_values, Read),
            (l0(Diag), Read),
            (l0(Value), Read),
            (l0(H), Write),
        ],
        Op::LiftPull { .. } => vec![(l0(Z), Read), (lift_values, Modify)],
        Op::DotFinal { .. } | Op::Gate { .. } | Op::SpikeGate => Vec::new(),
    }
}

/// The last tenant to write each unit of each physical buffer.
#[derive(Default)]
struct Memory {
    owner: std::collections::HashMap<Phys, Vec<Option<Tenant>>>,
}

impl Memory {
    fn units(&mut self, t: Tenant) -> (&mut [Option<Tenant>], std::ops::Range<usize>) {
        let (phys, a, b) = place(t);
        let v = self.owner.entry(phys).or_insert_with(|| vec![None; 16]);
        (v.as_mut_slice(), a as usize..b as usize)
    }

    /// `t` reads its range: every unit must still hold what `t` wrote.
    fn read(&mut self, t: Tenant, what: &str) {
        let (v, r) = self.units(t);
        for u in r {
            assert_eq!(
                v[u],
                Some(t),
                "{what}: {t:?} reads unit {u} of {:?}, last written by {:?}",
                place(t).0,
                v[u]
            );
        }
    }

    fn write(&mut self, t: Tenant) {
        let (v, r) = self.units(t);
        v[r].fill(Some(t));
    }

    fn access(&mut self, who: Who, b: Buf, a: Access, what: &str) {
        // The heights' assembly reads the rasteriser's band weight.
        let who = if b == Buf::Band { Who::Raster } else { who };
        if a != Access::Write {
            self.read((who, b), what);
        }
        if a != Access::Read {
            self.write((who, b));
        }
    }

    fn run(&mut self, who: Who, levels: usize, steps: &[plan::Step], what: &str) {
        for (i, &s) in steps.iter().enumerate() {
            for (b, a) in accesses(s, levels, who) {
                self.access(who, b, a, &format!("{what}, step {i} {s:?}"));
            }
        }
    }
}

/// One solve of a field as `GpuSolver::begin` runs it (`solve` there): the assembly, FMG
/// on a cold start, the queued relaxation and FCG (gated passes counted as run).
fn field_solve(mem: &mut Memory, who: Who, shape: &CycleShape, cold: bool, what: &str) {
    let l = shape.levels;
    mem.run(who, l, &plan::assemble(shape, cold), what);
    if cold {
        mem.run(who, l, &plan::fmg(shape), what);
    }
    let sweeps = if who == Who::Heights {
        crate::cycle::SWEEPS
    } else {
        crate::cycle::FIELD_WARM_SWEEPS
    };
    mem.run(who, l, &plan::fcg_queued(shape, sweeps, 3, true), what);
}

/// The buffers `GpuSolver` shares between its solvers (`GUEST_LEVEL0`, `VY_HOME`, the
/// fields' coarse levels, the heights' level 1 inside their level 0, `f` in `p`, the mips'
/// pyramid in `weight`) walked through two frames of `GpuSolver` (a cold one, a warm one, each
/// with further FCG iterations and publishes after `begin`), with what every plan step reads
/// and writes: no tenant reads a range after another tenant wrote it.
#[test]
fn aliased_ranges_are_not_read_after_another_tenant_wrote_them() {
    use Level0Buf::*;
    let params = crate::SolverParams::default();
    for n in [64, 256, 1024, 4096] {
        let levels = solve_levels(n);
        let heights = CycleShape::new(levels, &params);
        let field = |shift: usize| CycleShape {
            levels: levels - shift,
            shift,
            ..heights
        };
        let (grad, rough) = (field(1), field(2));
        let mut mem = Memory::default();
        // Persistent between frames: the heights' `h` (the texture) and roughness's own `h`.
        mem.write((Who::Heights, Buf::L0(H)));
        mem.write((Who::Rough, Buf::L0(H)));
        for cold in [true, false] {
            let what = format!("{n}^2, {} frame", if cold { "cold" } else { "warm" });
            // The rasteriser, one pass: the height problem, the band weight, the gradient
            // problem (`vy` with it) and the roughness problem.
            for t in [
                (Who::Heights, Buf::L0(Weight)),
                (Who::Heights, Buf::L0(Value)),
                (Who::Raster, Buf::Band),
                (Who::Grad, Buf::L0(Weight)),
                (Who::Grad, Buf::L0(Value)),
                (Who::Raster, Buf::Vy),
                (Who::Rough, Buf::L0(Weight)),
                (Who::Rough, Buf::L0(Value)),
            ] {
                mem.write(t);
            }
            // The gradient field: x (warm from `gx`), `vy` into its values, y (warm from
            // `gy`), the solution kept in `gx` / `gy` after each.
            let gh = (Who::Grad, Buf::L0(H));
            if !cold {
                mem.write(gh);
            }
            field_solve(
                &mut mem,
                Who::Grad,
                &grad,
                cold,
                &format!("{what}, gradient x"),
            );
            mem.read(gh, &what);
            mem.read((Who::Raster, Buf::Vy), &what);
            mem.write((Who::Grad, Buf::L0(Value)));
            if !cold {
                mem.write(gh);
            }
            field_solve(
                &mut mem,
                Who::Grad,
                &grad,
                cold,
                &format!("{what}, gradient y"),
            );
            mem.read(gh, &what);
            field_solve(
                &mut mem,
                Who::Rough,
                &rough,
                cold,
                &format!("{what}, roughness"),
            );
            field_solve(
                &mut mem,
                Who::Heights,
                &heights,
                cold,
                &format!("{what}, heights"),
            );
            // Publishing (the pyramid from `diag` and `h`), then more FCG, published again.
            for _ in 0..2 {
                mem.read((Who::Heights, Buf::L0(Diag)), &what);
                mem.read((Who::Heights, Buf::L0(H)), &what);
                mem.write((Who::Mips, Buf::Pyramid));
                mem.read((Who::Mips, Buf::Pyramid), &what);
                let more = plan::fcg_queued_iterations(&heights, false, 2);
                mem.run(Who::Heights, levels, &more, &format!("{what}, more FCG"));
            }
        }
    }
}

#[test]
fn limits_refuse_before_allocating() {
    let small = wgpu::Limits {
        max_storage_buffer_binding_size: 128 << 20,
        ..wgpu::Limits::default()
    };
    // 4096^2: level-0 buffers of 64 MiB (the largest), level-2 stencil records of 24 MiB.
    assert!(check_limits(4096, &small).is_ok());
    let e = check_limits(8192, &small).unwrap_err();
    assert!(matches!(e, GpuError::TooLarge { .. }), "{e}");
    assert!(e.to_string().contains("multigrid.weight.l0"), "{e}");
    assert!(matches!(
        check_limits(100, &small),
        Err(GpuError::BadSize { .. })
    ));
    assert!(matches!(
        check_limits(8, &small),
        Err(GpuError::BadSize { .. })
    ));
    // An adapter below WebGPU's defaults is told which limit it lacks.
    let no_storage_textures = wgpu::Limits {
        max_storage_textures_per_shader_stage: 2,
        ..wgpu::Limits::default()
    };
    let e = check_limits(256, &no_storage_textures).unwrap_err();
    assert!(
        e.to_string()
            .contains("max_storage_textures_per_shader_stage"),
        "{e}"
    );
}
