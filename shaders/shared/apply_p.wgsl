// Shared include `#import apply_p`: the level-0 operator applied to `p` at one free cell: FCG's
// q = A p for the passes that read it (dot_partial, fcg_update: the GPU keeps no q vector and
// recomputes it where it is read), and A h for the residual (apply_level0, which binds h as `p`).
// Neighbour order as `neighbour_sum` in cpu/level0.rs.
// The importing pass must declare `params` (n = level-0 side, ax, ay) and `p` (level 0, 0 on hard
// cells); the caller handles hard cells (diag d == 0: q = 0) and passes d = diag of cell (i, j).

fn apply_p(i: u32, j: u32, d: f32) -> f32 {
    let n = params.n;
    let idx = j * n + i;
    var s = 0.0;
    if i > 0u {
        s += params.ax * p[idx - 1u];
    }
    if i + 1u < n {
        s += params.ax * p[idx + 1u];
    }
    if j > 0u {
        s += params.ay * p[idx - n];
    }
    if j + 1u < n {
        s += params.ay * p[idx + n];
    }
    return d * p[idx] - s;
}

// q = A p at level-0 cell idx (0 on hard cells), from p and diag (the pass declares `diag` too).
fn q_at(idx: u32) -> f32 {
    let d = diag[idx];
    if d == 0.0 {
        return 0.0;
    }
    return apply_p(idx % params.n, idx / params.n, d);
}
