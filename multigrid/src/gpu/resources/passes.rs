//! Each pass's parameters and bindings ([`pass_spec`]).

use super::{Buffers, Edges, Slice};
use crate::cycle::CycleShape;
use crate::gpu::kernels::{PassSpec, Res};
use crate::gpu::params::{Params, STAGE_PQ, STAGE_RZ, STAGE_Z};
use crate::gpu::plan::{self, Op};

/// A whole buffer or a [`Slice`] as a pass resource.
pub(super) fn bind<'a>(x: impl Into<Res<'a>>) -> Res<'a> {
    x.into()
}

/// Parameters and resources of one op (bindings in the order of the kernel's `.wgsl` declarations).
pub(crate) fn pass_spec<'a>(
    op: Op,
    n: usize,
    levels: usize,
    ax: f32,
    ay: f32,
    threshold: f32,
    b: &'a Buffers,
) -> PassSpec<'a, Op> {
    let kc = levels - 1;
    let side = |k: usize| (n >> k) as u32;
    let mut params = Params {
        n: n as u32,
        ax,
        ay,
        threshold,
        ..Params::default()
    };
    let resources = match op {
        Op::Assemble { cold } => assemble(&mut params, cold, b),
        Op::GalerkinCoarse { level } => {
            params.n = side(level - 1);
            vec![b.stencils(level - 1), bind(&b.stencil[level - 2])]
        }
        Op::SmoothLevel0 { colour } => {
            params.colour = colour;
            vec![bind(&b.z), bind(&b.r), bind(&b.diag), stub(&b.u[0])]
        }
        Op::ProlongSmoothLevel0 { colour } => {
            params.colour = colour;
            params.mode = 1;
            vec![bind(&b.z), bind(&b.r), bind(&b.diag), bind(&b.u[0])]
        }
        Op::SweepLevel0FromZero => {
            vec![bind(&b.z), bind(&b.r), bind(&b.diag), stub(&b.fc[0])]
        }
        Op::SweepRestrictLevel0FromZero => {
            params.mode = 1;
            vec![bind(&b.z), bind(&b.r), bind(&b.diag), bind(&b.fc[0])]
        }
        Op::SmoothCoarse { level, colour } => {
            params.n = side(level);
            params.colour = colour;
            vec![
                b.stencils(level),
                bind(&b.u[level - 1]),
                bind(&b.fc[level - 1]),
            ]
        }
        Op::SweepCoarse {
            level,
            colours,
            phases,
            from_zero,
            restrict,
        } => {
            params.n = side(level);
            params.colour = colours;
            params.mode = phases | if from_zero { 16 } else { 0 } | if restrict { 32 } else { 0 };
            let alt = &b.alt[level - 1];
            let out = &b.fc[level];
            vec![
                b.stencils(level),
                if from_zero { stub(alt) } else { bind(alt) },
                bind(&b.fc[level - 1]),
                bind(&b.u[level - 1]),
                if restrict { bind(out) } else { stub(out) },
            ]
        }
        Op::ResidualRestrictLevel0 { solution } => {
            let (x, rhs) = if solution {
                (b.h.res(), &b.f)
            } else {
                (bind(&b.z), &b.r)
            };
            vec![x, bind(rhs), bind(&b.diag), bind(&b.fc[0])]
        }
        Op::ResidualRestrictCoarse { level } => {
            params.n = side(level);
            vec![
                b.stencils(level),
                bind(&b.u[level - 1]),
                bind(&b.fc[level - 1]),
                bind(&b.fc[level]),
            ]
        }
        Op::ProlongLevel0 { solution } => {
            let x = if solution { b.h.res() } else { bind(&b.z) };
            vec![x, bind(&b.u[0]), bind(&b.diag)]
        }
        Op::ProlongCoarse { level, set } => {
            params.n = side(level);
            params.mode = set as u32;
            vec![b.stencils(level), bind(&b.u[level - 1]), bind(&b.u[level])]
        }
        Op::ProlongCoarseAlt { level, set } => {
            params.n = side(level);
            params.mode = set as u32;
            let u = if set {
                stub(&b.u[level - 1])
            } else {
                bind(&b.u[level - 1])
            };
            vec![
                b.stencils(level),
                u,
                bind(&b.u[level]),
                bind(&b.alt[level - 1]),
            ]
        }
        Op::RestrictSum { level } => {
            params.n = side(level);
            vec![bind(&b.fc[level - 1]), bind(&b.fc[level])]
        }
        Op::CoarsestSolve => {
            params.n = side(kc);
            vec![b.stencils(kc), bind(&b.fc[kc - 1]), bind(&b.u[kc - 1])]
        }
        Op::CoarseFused { shape, fmg } => coarse_fused(&mut params, op, shape, fmg, n, kc, b),
        Op::ApplyLevel0 => vec![b.h.res(), bind(&b.f), bind(&b.diag), bind(&b.r)],
        Op::RelaxMask { mode } => relax_mask(&mut params, mode, b),
        Op::RelaxTiles { sweeps, to_z } => {
            params.colour = sweeps;
            params.mode = u32::from(!to_z);
            // The mask is in `z`; `r` is the scratch copy (see `relax_mask`).
            vec![
                b.h.res(),
                bind(&b.f),
                bind(&b.diag),
                bind(&b.z),
                bind(&b.scalars),
                bind(&b.r),
            ]
        }
        // The stop-test relaxation: the correction from `r` (in `f`'s place) into `p` (as the
        // scratch), the mask in `z`; then `h += d`, `r -= A d` (`spike_update.wgsl`).
        Op::SpikeRelax { sweeps } => {
            params.colour = sweeps;
            params.mode = 2;
            vec![
                b.h.unread_res(),
                bind(&b.r),
                bind(&b.diag),
                bind(&b.z),
                bind(&b.scalars),
                bind(&b.p),
            ]
        }
        Op::SpikeUpdate => vec![
            b.h.res(),
            bind(&b.r),
            bind(&b.p),
            bind(&b.z),
            bind(&b.diag),
            bind(&b.scalars),
        ],
        Op::DotPartial { stage } => dot_partial(&mut params, stage, n, b),
        Op::SmoothDotLevel0 { stage, colour } => {
            params.colour = colour;
            let mut res = dot_partial(&mut params, stage, n, b);
            res[1] = bind(&b.z);
            res[3] = bind(&b.diag);
            res
        }
        Op::DotFinal { stage } => {
            params.mode = stage;
            params.partials = plan::partial_groups(n * n);
            vec![bind(&b.partials), bind(&b.scalars)]
        }
        // The gates bind the solver's own gate buffers (`field::Gate`), not these.
        Op::Gate { .. } | Op::SpikeGate => {
            unreachable!("gate passes are specified by their solver")
        }
        Op::FcgUpdate { mode } => fcg_update(&mut params, mode, n, b),
        Op::LiftPush { level } => lift_push(&mut params, level, n, b),
        Op::LiftPull { level } => lift_pull(&mut params, level, n, b),
    };
    PassSpec {
        key: op,
        kernel: op.kernel(kc, b.h.in_texture()),
        params,
        resources,
        workgroups: op.workgroups(n),
        label: op.label(kc),
    }
}

/// The first 256 bytes of `s` (a binding a pass declares but does not read).
pub(super) fn stub(s: &Slice) -> Res<'static> {
    Res::Owned(Slice {
        buffer: s.buffer.clone(),
        offset: s.offset,
        size: s.size.min(256),
    })
}

/// Lift levels `first ..= last` of the packed storage in `z` (weights) and the lift values, as
/// ranges from the level-`first` offset rounded down to 256 bytes (a valid binding offset on every
/// adapter): that rounded offset in elements and the two ranges.
fn lift_ranges(
    b: &Buffers,
    n: usize,
    first: usize,
    last: usize,
) -> (usize, Res<'static>, Res<'static>) {
    let base = plan::lift_offset(n, first) / 64 * 64;
    let end = plan::lift_offset(n, last) + (n >> last) * (n >> last);
    let range = |s: &Slice| {
        Res::Owned(Slice {
            buffer: s.buffer.clone(),
            offset: s.offset + 4 * base as u64,
            size: 4 * (end - base) as u64,
        })
    };
    (base, range(&b.z), range(b.lift_values()))
}

/// `Assemble`'s bindings. Mode 0 reads no edge differences and mode 1 no band: `weight` fills the
/// unread slots.
fn assemble<'a>(params: &mut Params, cold: bool, b: &'a Buffers) -> Vec<Res<'a>> {
    params.slot_or_cold = cold as u32;
    let (east, north, band) = match &b.edges {
        Edges::None => (bind(&b.weight), bind(&b.weight), bind(&b.weight)),
        Edges::Uploaded(de, dn) => {
            params.mode = 1;
            (bind(de), bind(dn), bind(&b.weight))
        }
        Edges::Gradient { gx, gy, cell_m } => {
            params.mode = 2;
            [params.dx, params.dy] = *cell_m;
            (bind(gx), bind(gy), bind(&b.r))
        }
    };
    vec![
        b.h.res(),
        bind(&b.weight),
        bind(&b.value),
        east,
        north,
        band,
        bind(&b.diag),
        bind(&b.f),
    ]
}

/// `CoarseFused`'s bindings: the program, the stencils of the fused levels and their `u`, `f`.
fn coarse_fused<'a>(
    params: &mut Params,
    op: Op,
    shape: CycleShape,
    fmg: bool,
    n: usize,
    kc: usize,
    b: &'a Buffers,
) -> Vec<Res<'a>> {
    let kf = shape
        .fused_from()
        .expect("a fused pass only on a shape with fused levels");
    params.n = (n >> kf) as u32;
    let cycle = plan::fused_program(Op::CoarseFused { shape, fmg: false }).len();
    params.src_offset = if fmg { cycle as u32 } else { 0 };
    params.dst_offset = plan::fused_program(op).len() as u32;
    let run = |v: &[Slice]| {
        Buffers::fused_run(v, kf).expect("the fused levels lie in one buffer, in order")
    };
    let program = b
        .fused_program
        .as_ref()
        .expect("the fused program is written before the passes are made");
    let mut res = vec![Res::Buffer(program)];
    for k in kf..kf + 4 {
        res.push(bind(&b.stencil[k.min(kc) - 2]));
    }
    res.push(Res::Owned(run(&b.u)));
    res.push(Res::Owned(run(&b.fc)));
    res
}

// `relax_mask.wgsl` copies a ring of at most `MAX_RADIUS` (8) cells around its tiles.
const _: () = assert!(crate::cpu::RADIUS <= 8);

/// `RelaxMask`'s bindings. The seeds come from `r`, the windows go into `z` (the mask), and the
/// relaxation's tile passes use `r` as their scratch copy: both are scratch until FCG's start,
/// which rewrites them.
fn relax_mask<'a>(params: &mut Params, mode: u32, b: &'a Buffers) -> Vec<Res<'a>> {
    params.mode = mode;
    params.radius = crate::cpu::RADIUS as u32;
    // The box passes (modes 1, 3) read only the scalars and the box.
    let cells = |s: &'a Slice| {
        if mode.is_multiple_of(2) {
            bind(s)
        } else {
            stub(s)
        }
    };
    vec![
        cells(&b.r),
        cells(&b.z),
        bind(&b.scalars),
        Res::Buffer(&b.relax_box),
    ]
}

/// `DotPartial`'s bindings. `q = A p` is recomputed from `p` and `diag` (no buffer holds it). Each
/// stage binds in full only what it reads (`p.q`: p, diag; `max |r|`: r; `r.z` alone: r, z), the
/// rest as stubs (the bindings are what the byte estimate counts).
fn dot_partial<'a>(params: &mut Params, stage: u32, n: usize, b: &'a Buffers) -> Vec<Res<'a>> {
    params.mode = stage;
    params.partials = plan::partial_groups(n * n);
    let reads = |s: &'a Slice, read: bool| if read { bind(s) } else { stub(s) };
    let (r, z) = (stage != STAGE_PQ, matches!(stage, STAGE_Z | STAGE_RZ));
    let pd = matches!(stage, STAGE_PQ | STAGE_Z);
    vec![
        reads(&b.r, r),
        reads(&b.z, z),
        reads(&b.p, pd),
        reads(&b.diag, pd),
        bind(&b.partials),
    ]
}

/// `FcgUpdate`'s bindings. Mode 0 (`h += alpha p`, `r -= alpha q`, the `max |r|` partials) reads no
/// `z`; modes 1 and 2 (`p = z + beta p`, `p = z`) read only the scalars, `z` and `p`, and write no
/// partials. What a mode does not touch is bound as a stub (the bindings are what the byte
/// estimate counts; the kernel never touches them).
fn fcg_update<'a>(params: &mut Params, mode: u32, n: usize, b: &'a Buffers) -> Vec<Res<'a>> {
    params.mode = mode;
    params.partials = plan::partial_groups(n * n);
    let step = mode == 0;
    let reads = |s: &'a Slice, read: bool| if read { bind(s) } else { stub(s) };
    vec![
        if step { b.h.res() } else { b.h.unread_res() },
        bind(&b.scalars),
        reads(&b.r, step),
        reads(&b.z, !step),
        bind(&b.p),
        reads(&b.diag, step),
        if step {
            bind(&b.partials)
        } else {
            stub(&Slice::whole(b.partials.clone()))
        },
    ]
}

/// `LiftPush`'s bindings. The lift's packed storage aliases level-0 `z` (weights W) and FCG's `p`
/// (values V, then g): both are dead during FMG, and FCG writes them before reading them (see
/// `Buffers`). The lift binds of its packed storage only the levels it touches, and of the level-0
/// buffers only a stub where it does not read them (the bindings are what the byte estimate counts).
fn lift_push<'a>(params: &mut Params, level: usize, n: usize, b: &'a Buffers) -> Vec<Res<'a>> {
    params.n = (n >> (level - 1)) as u32;
    params.mode = (level > 1) as u32;
    let (base, w, v) = lift_ranges(b, n, (level - 1).max(1), level);
    params.src_offset = if level > 1 {
        (plan::lift_offset(n, level - 1) - base) as u32
    } else {
        0
    };
    params.dst_offset = (plan::lift_offset(n, level) - base) as u32;
    let level0 = |s: &'a Slice| if level == 1 { bind(s) } else { stub(s) };
    vec![level0(&b.diag), level0(&b.value), w, v]
}

/// `LiftPull`'s bindings (as `LiftPush`'s; `h` too at level 0).
fn lift_pull<'a>(params: &mut Params, level: usize, n: usize, b: &'a Buffers) -> Vec<Res<'a>> {
    params.n = (n >> level) as u32;
    params.mode = (level == 0) as u32;
    let (base, w, v) = lift_ranges(b, n, level.max(1), level + 1);
    params.src_offset = (plan::lift_offset(n, level + 1) - base) as u32;
    params.dst_offset = if level > 0 {
        (plan::lift_offset(n, level) - base) as u32
    } else {
        0
    };
    let level0 = |s: &'a Slice| if level == 0 { bind(s) } else { stub(s) };
    let h = match b.h.buffer() {
        Some(h) if level > 0 => stub(h),
        _ => b.h.res(),
    };
    vec![h, level0(&b.diag), level0(&b.value), w, v]
}
