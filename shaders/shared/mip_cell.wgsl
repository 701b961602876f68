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

// The constraint pair of cell (i, j) of level k-1 whose height is `h`: from the level-0 diagonal
// (mode 0, k = 1) or from level k-1 of the pyramid (mode 1, at params.src_offset).
fn mip_pair(i: u32, j: u32, h: f32) -> vec2<f32> {
    if params.mode == 0u {
        if diag[j * params.n + i] == 0.0 {
            return vec2<f32>(1.0, h);
        }
        return vec2<f32>(0.0, 0.0);
    }
    return pyramid[params.src_offset + j * params.n + i];
}

// Cell (i, j) of level k from level k-1 in memory: the children's pairs (`mip_pair`), their
// heights from `src` (mip k-1). The including pass declares `params` (n = side of level k-1,
// mode, src_offset), `src`, `diag` and `pyramid`.
fn mip_cell_from(i: u32, j: u32) -> MipCell {
    let h00 = textureLoad(src, vec2<u32>(2u * i, 2u * j), 0).x;
    let h10 = textureLoad(src, vec2<u32>(2u * i + 1u, 2u * j), 0).x;
    let h01 = textureLoad(src, vec2<u32>(2u * i, 2u * j + 1u), 0).x;
    let h11 = textureLoad(src, vec2<u32>(2u * i + 1u, 2u * j + 1u), 0).x;
    return mip_combine(
        mip_pair(2u * i, 2u * j, h00), mip_pair(2u * i + 1u, 2u * j, h10),
        mip_pair(2u * i, 2u * j + 1u, h01), mip_pair(2u * i + 1u, 2u * j + 1u, h11),
        h00, h10, h01, h11,
    );
}
