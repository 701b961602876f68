// Shared include `#import lift`: the level-0 push-pull weight a_0 of the FMG lift (ALGORITHM.md "FMG lift").
// Must be kept in sync with `weight0` in multigrid/src/cpu/lift.rs (same formula, same summation order).
// The importing pass must declare `params` (n = level-0 side, ax, ay) and `diag` (level-0 diagonal).

// a_0 of level-0 cell (i, j): 1 on hard cells (diag == 0); on free cells s / (1 + s) with
// s = max(0, (diag - deg) / (2 ax + 2 ay)), deg = the cell's sum of in-domain edge weights.
fn lift_weight0(i: u32, j: u32) -> f32 {
    let n = params.n;
    let d = diag[j * n + i];
    if d == 0.0 {
        return 1.0;
    }
    var deg = 0.0;
    if i + 1u < n {
        deg += params.ax;
    }
    if i > 0u {
        deg += params.ax;
    }
    if j + 1u < n {
        deg += params.ay;
    }
    if j > 0u {
        deg += params.ay;
    }
    let s = max((d - deg) / (2.0 * params.ax + 2.0 * params.ay), 0.0);
    return s / (1.0 + s);
}
