// Pass: downsample_fields: the gradient-field (f = 2) or roughness (f = 4) problem from the level-0
// maps, exactly as `fields::downsample_weighted`: per coarse cell the mean weight over its f x f block
// (1 only when every fine cell is hard, else at most 0.999) and the weighted means of one or two value
// planes (0 where the block has no weight); and per value plane the min / max over coarse cells with
// weight > 0 (order-preserving u32 keys, atomics) for the problem's relief. With f = 1 only the
// value range of plane 0 is computed (the elevation constraints'): nothing else is written.
// Reads:  wsrc (weight), v0src, v1src (value planes; level 0); with pad2 = 1 (roughness), wsrc holds
//         weight and value as pack2x16unorm words (v0src, v1src unread).
// Writes: out_w, out_v0, out_v1 (coarse, (n / f)^2; out_v1 only with two planes; none with f = 1),
//         stats[pad0 .. pad0 + 2] (plane 0) and stats[pad1 .. pad1 + 2] (plane 1).
// Params: n = level-0 side; mode = f; partials = number of value planes (1 or 2); pad0, pad1 = stats
//         slots.
// Workgroup: 8 x 8, one thread per coarse cell.
#import params

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> wsrc: array<f32>;
@group(0) @binding(2) var<storage, read> v0src: array<f32>;
@group(0) @binding(3) var<storage, read> v1src: array<f32>;
@group(0) @binding(4) var<storage, read_write> out_w: array<f32>;
@group(0) @binding(5) var<storage, read_write> out_v0: array<f32>;
@group(0) @binding(6) var<storage, read_write> out_v1: array<f32>;
@group(0) @binding(7) var<storage, read_write> stats: array<atomic<u32>>;

fn key(v: f32) -> u32 {
    let b = bitcast<u32>(v);
    if (b & 0x80000000u) != 0u {
        return ~b;
    }
    return b | 0x80000000u;
}

@compute @workgroup_size(8, 8)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let n = params.n;
    let f = params.mode;
    let nc = n / f;
    let ic = gid.x;
    let jc = gid.y;
    if ic >= nc || jc >= nc {
        return;
    }
    let two = params.partials > 1u;
    var sw = 0.0;
    var s0 = 0.0;
    var s1 = 0.0;
    for (var j = jc * f; j < (jc + 1u) * f; j++) {
        for (var i = ic * f; i < (ic + 1u) * f; i++) {
            let idx = j * n + i;
            var w = wsrc[idx];
            var v0 = v0src[idx];
            if params.pad2 == 1u {
                let wv = unpack2x16unorm(bitcast<u32>(w));
                w = wv.x;
                v0 = wv.y;
            }
            sw += w;
            s0 += w * v0;
            if two {
                s1 += w * v1src[idx];
            }
        }
    }
    var w = sw * (1.0 / f32(f * f));
    if sw >= f32(f * f) {
        w = 1.0;
    } else {
        w = min(w, 0.999);
    }
    var v0 = 0.0;
    var v1 = 0.0;
    if sw > 0.0 {
        v0 = s0 / sw;
        v1 = s1 / sw;
    } else {
        w = 0.0;
    }
    if f == 1u {
        w = wsrc[jc * n + ic];
        v0 = v0src[jc * n + ic];
    } else {
        let c = jc * nc + ic;
        out_w[c] = w;
        out_v0[c] = v0;
        if two {
            out_v1[c] = v1;
        }
    }
    if w > 0.0 {
        atomicMin(&stats[params.pad0], key(v0));
        atomicMax(&stats[params.pad0 + 1u], key(v0));
        if two {
            atomicMin(&stats[params.pad1], key(v1));
            atomicMax(&stats[params.pad1 + 1u], key(v1));
        }
    }
}
