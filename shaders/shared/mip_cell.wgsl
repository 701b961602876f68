// Shared include `#import mip_cell` (ALGORITHM.md "Mip chain"): one cell of mip level k >= 1 from
// its four children on level k-1, in the order (0,0), (1,0), (0,1), (1,1) (the CPU's order): the
// constraint pyramid's vec2(hard count, sum of E) and the displayed height
// m_k = W_k Ebar_k + (1 - W_k) avg(4 children of mip k-1).
// A level-0 child is hard exactly where diag == 0 (free cells have diag >= their in-domain edge
// weights > 0), and there h == E (the assembly sets it and no pass changes it).

struct MipCell {
    c: vec2<f32>,
    m: f32,
}

fn mip_combine(
    c00: vec2<f32>, c10: vec2<f32>, c01: vec2<f32>, c11: vec2<f32>,
    h00: f32, h10: f32, h01: f32, h11: f32,
) -> MipCell {
    let c = c00 + c10 + c01 + c11;
    var m: f32;
    if c.x > 0.0 {
        m = c.y / c.x;
    } else {
        m = 0.25 * (h00 + h10 + h01 + h11);
    }
    return MipCell(c, m);
}

// The constraint pair of a level-0 cell whose height is `h`.
fn mip_level0_pair(d: f32, h: f32) -> vec2<f32> {
    if d == 0.0 {
        return vec2<f32>(1.0, h);
    }
    return vec2<f32>(0.0, 0.0);
}
