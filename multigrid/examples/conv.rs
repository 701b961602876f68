//! Regression check of the CPU backend: solves fixed problems and saves (`save DIR`) or compares
//! (`check DIR`) every intermediate result that matters (per-step residual histories, FMG levels,
//! final fields), so kernel rewrites can be shown to change results only by round-off.
//!
//! `cargo run --release -p terrasketch-multigrid --example conv -- save /tmp/ref`
//! `cargo run --release -p terrasketch-multigrid --example conv -- check /tmp/ref`

use std::path::{Path, PathBuf};

use terrasketch_multigrid::{
    Budget, ConstraintMaps, CpuSolver, FieldProblem, Grid, SolverParams, cpu::Hierarchy,
};
use terrasketch_sketch::benchmark_sketch;

/// A synthetic problem with hard curves, soft patches and prescribed differences.
fn problem(n: usize) -> FieldProblem {
    let mut p = FieldProblem {
        n,
        ax: 0.5,
        ay: 2.0,
        weight: vec![0.0; n * n],
        value: vec![0.0; n * n],
        d_east: vec![0.0; n * n],
        d_north: vec![0.0; n * n],
    };
    for i in 0..n {
        let x = i as f32 / n as f32;
        let j = ((0.5 + 0.3 * (x * 6.0).sin()) * n as f32) as usize;
        p.weight[j * n + i] = 1.0;
        p.value[j * n + i] = 1000.0 * (x * 3.0).sin().abs();
        p.weight[(n / 5) * n + i] = 1.0;
        p.value[(n / 5) * n + i] = 200.0;
    }
    for j in 0..n {
        for i in 0..n {
            let idx = j * n + i;
            let (x, y) = (i as f32 / n as f32, j as f32 / n as f32);
            if (x - 0.7).powi(2) + (y - 0.8).powi(2) < 0.01 && p.weight[idx] < 1.0 {
                p.weight[idx] = 0.5;
                p.value[idx] = 700.0;
            }
            if (0.1..0.4).contains(&x) && (0.3..0.45).contains(&y) {
                p.d_east[idx] = 3.0 * (y * 20.0).sin();
                p.d_north[idx] = 2.0 * (x * 13.0).cos();
            }
        }
    }
    // A fully hard block (inactive coarse cells) touching the west border.
    for j in n / 16..n / 8 {
        for i in 0..n / 8 {
            p.weight[j * n + i] = 1.0;
            p.value[j * n + i] = 50.0;
        }
    }
    p
}

struct Out {
    dir: PathBuf,
    save: bool,
    worst: f64,
}

impl Out {
    fn field(&mut self, name: &str, v: &[f32]) {
        let path = self.dir.join(format!("{name}.f32"));
        if self.save {
            let bytes: Vec<u8> = v.iter().flat_map(|x| x.to_le_bytes()).collect();
            std::fs::write(path, bytes).unwrap();
            return;
        }
        let bytes = std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        let r: Vec<f32> = bytes
            .chunks(4)
            .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect();
        if r.len() != v.len() {
            println!("{name:>28}: length {} vs reference {}", v.len(), r.len());
        }
        let v = &v[..v.len().min(r.len())];
        let scale = r.iter().fold(0.0f32, |m, x| m.max(x.abs())).max(1e-30) as f64;
        let d = v
            .iter()
            .zip(&r)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0f32, f32::max) as f64
            / scale;
        self.worst = self
            .worst
            .max(if name.starts_with("hist") { 0.0 } else { d });
        println!("{name:>28}: max |diff| / max |ref| = {d:.2e}");
        if name.starts_with("hist") {
            let fmt = |x: &[f32]| {
                x.iter()
                    .map(|v| format!("{v:.3e}"))
                    .collect::<Vec<_>>()
                    .join(" ")
            };
            println!("{:>30}new {}\n{:>30}ref {}", "", fmt(v), "", fmt(&r));
        }
    }
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let (mode, dir) = match (args.get(1).map(|s| s.as_str()), args.get(2)) {
        (Some(m @ ("save" | "check")), Some(d)) => (m, PathBuf::from(d)),
        _ => {
            eprintln!("usage: conv save|check DIR");
            std::process::exit(2);
        }
    };
    std::fs::create_dir_all(&dir).unwrap();
    let mut out = Out {
        dir: dir.clone(),
        save: mode == "save",
        worst: 0.0,
    };
    hierarchy_checks(&mut out);
    for n in [64usize, 256, 1024] {
        solver_checks(&mut out, n);
    }
    if !out.save {
        println!("worst relative difference of a field: {:.2e}", out.worst);
    }
    let _ = Path::new(&dir);
}

fn hierarchy_checks(out: &mut Out) {
    for n in [64usize, 256, 1024] {
        let p = problem(n);
        let mut h = Hierarchy::new(n, p.ax, p.ay);
        h.assemble(&p);
        let params = SolverParams {
            tolerance: 1e-6,
            ..SolverParams::default()
        };
        let mut st = h.new_state();
        let mut k = h.fmg_start(&mut st, Vec::new(), &mut Vec::new());
        let kc = k + 1;
        out.field(&format!("h{n}_coarsest"), h.level_unknowns(&st, kc));
        while k >= 1 {
            h.fmg_level(k, &mut st, &params);
            out.field(&format!("h{n}_fmg_u{k}"), h.level_unknowns(&st, k));
            k -= 1;
        }
        h.fmg_finish(&mut st);
        out.field(&format!("h{n}_fmg_h"), &st.h);
        let r0 = h.residual(&st);
        let mut fcg = terrasketch_multigrid::cpu::Fcg::default();
        fcg.start(&h, &mut st, &params);
        let mut hist = vec![r0, fcg.residual];
        for _ in 0..8 {
            if let Some(s) = fcg.iterate(&h, &mut st, &params) {
                hist.push(s.residual);
            }
        }
        out.field(&format!("hist_h{n}_fcg"), &hist);
        out.field(&format!("h{n}_fcg_h"), &st.h);
        // Partial reassembly must agree with a full one.
        let mut p2 = p.clone();
        for i in 0..n {
            p2.weight[(n / 3) * n + i] = 1.0;
            p2.value[(n / 3) * n + i] = 400.0;
        }
        h.assemble_rows(&p2, n / 3..n / 3 + 1);
        let mut st2 = h.new_state();
        h.solve(&mut st2, &params);
        out.field(&format!("h{n}_partial_h"), &st2.h);
        // A partial reassembly must give exactly the operators of a full one: same bits out.
        let mut full = Hierarchy::new(n, p.ax, p.ay);
        full.assemble(&p2);
        let mut st3 = full.new_state();
        full.solve(&mut st3, &params);
        assert!(
            st2.h
                .iter()
                .zip(&st3.h)
                .all(|(a, b)| a.to_bits() == b.to_bits()),
            "partial != full assembly at {n}"
        );
        // Moving a small block of constraints (few dirty columns) and back.
        let mut p3 = p2.clone();
        for j in n / 2..n / 2 + 3 {
            for i in n / 4..n / 4 + 5 {
                p3.weight[j * n + i] = 1.0;
                p3.value[j * n + i] = 123.0;
            }
        }
        for (q, rows) in [
            (&p3, n / 2..n / 2 + 3),
            (&p2, n / 2..n / 2 + 3),
            (&p3, 0..n),
        ] {
            h.assemble_rows(q, rows);
            let mut fresh = Hierarchy::new(n, p.ax, p.ay);
            fresh.assemble(q);
            let (mut a, mut b) = (h.new_state(), fresh.new_state());
            h.solve(&mut a, &params);
            fresh.solve(&mut b, &params);
            assert!(
                a.h.iter()
                    .zip(&b.h)
                    .all(|(x, y)| x.to_bits() == y.to_bits()),
                "incremental != fresh at {n}"
            );
        }
    }
}

fn solver_checks(out: &mut Out, n: usize) {
    let mut sketch = benchmark_sketch();
    let grid = Grid::new(n, sketch.extent_m).unwrap();
    let mut s = CpuSolver::new(grid, SolverParams::default()).unwrap();
    s.set_sketch(&sketch);
    let mut hist = Vec::new();
    loop {
        let p = s.step(Budget::WorkUnits(1e-9));
        hist.push(p.residual.min(1e9));
        if p.converged {
            break;
        }
    }
    out.field(&format!("hist_s{n}_cold"), &hist);
    out.field(&format!("s{n}_heights"), s.heights());
    let (gx, gy) = s.gradient_field();
    out.field(&format!("s{n}_gx"), gx);
    out.field(&format!("s{n}_gy"), gy);
    out.field(&format!("s{n}_rough"), s.roughness());
    let mut hist = Vec::new();
    for _ in 0..3 {
        let old = ConstraintMaps::stroke_rows(&sketch, 0, &grid);
        for p in &mut sketch.strokes[0].points {
            p[0] += 6.0;
            p[1] += 4.0;
        }
        let new = ConstraintMaps::stroke_rows(&sketch, 0, &grid);
        s.update_sketch(&sketch, old.start.min(new.start)..old.end.max(new.end));
        loop {
            let p = s.step(Budget::WorkUnits(1e-9));
            hist.push(p.residual.min(1e9));
            if p.converged {
                break;
            }
        }
    }
    out.field(&format!("hist_s{n}_warm"), &hist);
    out.field(&format!("s{n}_warm_heights"), s.heights());
}
