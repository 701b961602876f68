// Shared include `#import stencil`: how a coarse level's Galerkin operator is stored (levels >= 2;
// level 1's stencils are computed where they are read, `shared/coarse_level1.wgsl`).
// A cell's 9 coefficients c[oy * 3 + ox] (oy = 0: south row; 0 toward cells outside the level) are kept
// as a record of STENCIL_WORDS u32 at STENCIL_WORDS * idx:
//   words 0..4: the 8 off-centre coefficients divided by the cell's scale, in [-1, 1], as 16-bit snorm
//               pairs (pack2x16snorm: round(32767 v)) (c0, c1), (c2, c3), (c5, c6), (c7, c8);
//   word 4:     the row sum s = c4 + the 8 off-centre coefficients (f32 bits);
//   word 5:     the scale, the largest |off-centre coefficient| (f32 bits).
// The centre is s minus the 8 stored off-centre coefficients, so every row keeps its sum to f32
// accuracy (the sums decide the operator's near-constant modes) while each off-centre coefficient
// moves by at most 1 / 65534 of the row's largest one: the coarse operators only precondition FCG on
// the exact level-0 operator. (snorm rather than binary16: as accurate in the largest coefficients,
// which dominate, and core WGSL on every adapter; pack2x16float needs the SHADER_F16_IN_F32
// capability, which llvmpipe grants only with native f16.) An inactive cell (centre <= threshold at
// assembly) has an all-zero record, whose centre decodes to exactly 0.
// Must be kept in sync with STENCIL_WORDS in multigrid/src/gpu/params.rs and `unpack_stencils` in
// multigrid/src/gpu/field.rs. Passes that read records import `coarse` (`shared/coarse_records.wgsl`).

const STENCIL_WORDS: u32 = 6u;

// The 9 coefficients of a record.
fn st_decode(w: array<u32, 6>) -> array<f32, 9> {
    let scale = bitcast<f32>(w[5]);
    let p0 = unpack2x16snorm(w[0]) * scale;
    let p1 = unpack2x16snorm(w[1]) * scale;
    let p2 = unpack2x16snorm(w[2]) * scale;
    let p3 = unpack2x16snorm(w[3]) * scale;
    let off = ((p0.x + p0.y) + (p1.x + p1.y)) + ((p2.x + p2.y) + (p3.x + p3.y));
    let centre = bitcast<f32>(w[4]) - off;
    return array<f32, 9>(p0.x, p0.y, p1.x, p1.y, centre, p2.x, p2.y, p3.x, p3.y);
}

// The record of a cell with coefficients c (all zero unless active).
fn st_record(c: array<f32, 9>, is_active: bool) -> array<u32, 6> {
    let scale = max(max(max(abs(c[0]), abs(c[1])), max(abs(c[2]), abs(c[3]))),
        max(max(abs(c[5]), abs(c[6])), max(abs(c[7]), abs(c[8]))));
    if !is_active {
        return array<u32, 6>(0u, 0u, 0u, 0u, 0u, 0u);
    }
    let sum = c[4] + (((c[0] + c[1]) + (c[2] + c[3])) + ((c[5] + c[6]) + (c[7] + c[8])));
    let inv = select(0.0, 1.0 / scale, scale > 0.0);
    return array<u32, 6>(
        pack2x16snorm(vec2<f32>(c[0], c[1]) * inv),
        pack2x16snorm(vec2<f32>(c[2], c[3]) * inv),
        pack2x16snorm(vec2<f32>(c[5], c[6]) * inv),
        pack2x16snorm(vec2<f32>(c[7], c[8]) * inv),
        bitcast<u32>(sum),
        bitcast<u32>(scale),
    );
}
