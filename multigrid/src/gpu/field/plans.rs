//! The plans a solver records once, and FCG's gate passes.

use super::*;

pub(super) struct Plans {
    pub(super) assemble: Vec<Step>,
    pub(super) assemble_cold: Vec<Step>,
    pub(super) lift: Vec<Step>,
    pub(super) fmg: Vec<Step>,
    pub(super) fcg_init: Vec<Step>,
    pub(super) fcg_first: Vec<Step>,
    pub(super) fcg_next: Vec<Step>,
    pub(super) residual: Vec<Step>,
    pub(super) fcg_first_direction: Vec<Step>,
}

impl Plans {
    /// The assembly plan; `cold` also sets `h = 0` on the free cells.
    pub(super) fn assemble(&self, cold: bool) -> &[Step] {
        if cold {
            &self.assemble_cold
        } else {
            &self.assemble
        }
    }

    pub(super) fn new(shape: &CycleShape) -> Plans {
        // FCG iterations driven by the CPU: each with the stop-test relaxation (gated by
        // `stop_rmax`, which `GpuFieldSolver::set_stop` writes) and its counts copied for the
        // work units.
        let mut fcg_first = plan::fcg_step();
        fcg_first.extend(plan::spike_relaxation());
        fcg_first.push(Step::CopySpike);
        let mut fcg_next = plan::fcg_direction(shape);
        fcg_next.extend(fcg_first.iter().copied());
        Plans {
            assemble: plan::assemble(shape, false),
            assemble_cold: plan::assemble(shape, true),
            lift: plan::lift(shape),
            fmg: plan::fmg(shape),
            fcg_init: plan::fcg_init(shape),
            fcg_first,
            fcg_next,
            residual: plan::residual(),
            fcg_first_direction: plan::fcg_first_direction(shape),
        }
    }
}

/// FCG's stop test on the GPU: the gate passes and the indirect arguments they write.
pub(super) struct Gate {
    pub(super) table: PassTable<Op>,
    /// Size classes of the gated passes ([`plan::gate_classes`]): class `c` has its arguments at
    /// byte `12 c` of `args`.
    pub(super) classes: Vec<[u32; 3]>,
    pub(super) args: wgpu::Buffer,
    _sizes: wgpu::Buffer,
    /// Estimated bytes of the gated passes of the first direction, the first iteration and a later
    /// one, per pass (counted once known to have run).
    pub(super) bytes: [Vec<(Kernel, u64)>; 3],
    /// Estimated bytes of the gated passes of one stop-test relaxation (its tiles are counted
    /// from their workgroups).
    pub(super) spike_bytes: Vec<(Kernel, u64)>,
}

impl Gate {
    /// The gate passes of a solver of side `n`: one size class per distinct workgroup count of the
    /// gated passes, their full counts in `sizes` (written once), `args` written by each gate.
    pub(super) fn new(
        ctx: &GpuContext,
        pipelines: &Pipelines,
        table: &PassTable<Op>,
        shape: &CycleShape,
        n: usize,
        bufs: &Buffers,
    ) -> Gate {
        let classes = plan::gate_classes(shape, n);
        let words: Vec<u32> = classes.iter().flatten().copied().collect();
        let buffer = |label: &str, usage: wgpu::BufferUsages| {
            ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: (4 * words.len()).max(12) as u64,
                usage: wgpu::BufferUsages::STORAGE | usage,
                mapped_at_creation: false,
            })
        };
        let sizes = buffer("multigrid.gate.sizes", wgpu::BufferUsages::COPY_DST);
        let args = buffer("multigrid.gate.args", wgpu::BufferUsages::INDIRECT);
        ctx.queue
            .write_buffer(&sizes, 0, bytemuck::cast_slice(&words));
        ctx.count_up(4 * words.len() as u64);
        let specs = plan::GATE_OPS
            .iter()
            .map(|&op| PassSpec {
                key: op,
                kernel: Kernel::FcgGate,
                params: Params {
                    n: classes.len() as u32,
                    mode: match op {
                        Op::Gate { count } => count as u32,
                        _ => 2,
                    },
                    ..Params::default()
                },
                resources: vec![
                    Res::Buffer(&sizes),
                    Res::Buffer(&bufs.scalars),
                    Res::Buffer(&args),
                ],
                workgroups: op.workgroups(n),
                label: op.label(shape.coarsest()),
            })
            .collect();
        let gate_table = PassTable::new(ctx, pipelines, "multigrid.gate.params", specs);
        let bytes_of = |steps: Vec<Step>| -> Vec<(Kernel, u64)> {
            steps
                .iter()
                .filter_map(|s| match s {
                    Step::Gated(op) => table.bytes_moved(op),
                    _ => None,
                })
                .collect()
        };
        let mut next = plan::gated(plan::fcg_direction(shape));
        next.extend(plan::gated(plan::fcg_step()));
        let bytes = [
            bytes_of(plan::gated(plan::fcg_first_direction(shape))),
            bytes_of(plan::gated(plan::fcg_step())),
            bytes_of(next),
        ];
        Gate {
            table: gate_table,
            classes,
            args,
            _sizes: sizes,
            bytes,
            spike_bytes: bytes_of(plan::spike_relaxation()),
        }
    }

    /// Byte offset in `args` of the class of `op`'s workgroups on a level-0 side `n`.
    pub(super) fn offset(&self, op: Op, n: usize) -> u64 {
        let w = op.workgroups(n);
        let c = self
            .classes
            .iter()
            .position(|&c| c == w)
            .unwrap_or_else(|| panic!("gated pass {op:?} has no size class"));
        12 * c as u64
    }
}
