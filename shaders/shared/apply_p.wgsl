// Shared include `#import apply_p`: the level-0 operator applied to a vector `p` at one free cell:
// FCG's q = A p for the passes that read it (dot_partial, fcg_update: the GPU keeps no q vector and
// recomputes it where it is read), and A h for the residual (apply_level0, whose `p` is h).
// Neighbour order as `neighbour_sum` in cpu/level0.rs.
// The importing pass must declare `params` (n = level-0 side, ax, ay) and `fn p_get(i, j) -> f32`
// (the vector at level-0 cell (i, j)); `q_at` also needs `p` and `diag` buffers. The caller handles
// hard cells (diag d == 0: q = 0) and passes d = diag of cell (i, j).

fn apply_p(i: u32, j: u32, d: f32) -> f32 {
    let n = params.n;
    var s = 0.0;
    if i > 0u {
        s += params.ax * p_get(i - 1u, j);
    }
    if i + 1u < n {
        s += params.ax * p_get(i + 1u, j);
    }
    if j > 0u {
        s += params.ay * p_get(i, j - 1u);
    }
    if j + 1u < n {
        s += params.ay * p_get(i, j + 1u);
    }
    return d * p_get(i, j) - s;
}

// q = A p at level-0 cell idx (0 on hard cells), from p and diag (the pass declares `diag` too).
fn q_at(idx: u32) -> f32 {
    let d = diag[idx];
    if d == 0.0 {
        return 0.0;
    }
    return apply_p(idx % params.n, idx / params.n, d);
}
