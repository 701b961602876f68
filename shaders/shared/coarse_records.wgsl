// Shared include `#import coarse` for a pass on a level >= 2 (the default; `coarse_level1.wgsl` is
// the level-1 variant, with the same functions): the level's Galerkin stencils, read from the records
// of `#import stencil` bound at binding 1.
// The importing pass must import `stencil` and read the stencils of the level whose side is
// params.n.

@group(0) @binding(1) var<storage, read> stencil: array<u32>;

// Whether cell `idx` is active: inactive records are all zero (an active one has a non-zero scale
// or, without off-centre coefficients, a row sum equal to its positive centre). Reads 2 words.
fn st_active(idx: u32) -> bool {
    let b = STENCIL_WORDS * idx;
    return stencil[b + 4u] != 0u || stencil[b + 5u] != 0u;
}

// Whether cell `idx` is active and, if so, its 9 coefficients c[oy * 3 + ox] in `row` (untouched
// otherwise).
fn st_get(idx: u32, row: ptr<function, array<f32, 9>>) -> bool {
    if !st_active(idx) {
        return false;
    }
    let b = STENCIL_WORDS * idx;
    *row = st_decode(array<u32, 6>(stencil[b], stencil[b + 1u], stencil[b + 2u], stencil[b + 3u],
        stencil[b + 4u], stencil[b + 5u]));
    return true;
}
