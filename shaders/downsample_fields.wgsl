// Pass: downsample_fields: the gradient-field problem (f = 2) from the level-0 maps, exactly as
// `fields::downsample_weighted`: per coarse cell the mean weight over its f x f block (1 only when every
// fine cell is hard, else at most 0.999; `#import downsample`) and the weighted mean of one value plane
// (0 where the block has no weight); and the min / max of that plane over coarse cells with weight > 0
// (order-preserving u32 keys, atomics) for the problem's relief. Run once per plane (gx, then gy: the
// y pass, values_only = 1, writes only its values, into `vy`). With f = 1 nothing is written and only the
// value range of a problem already on its level is computed (the elevation constraints on level 0, the
// roughness problem the rasteriser wrote on level 2).
// Reads:  wsrc (weight), vsrc (value plane; level 0, or the problem's level with f = 1).
// Writes: out_w (unless values_only = 1), out_v (coarse, (n / f)^2; none with f = 1), stats[slot_or_cold .. slot_or_cold + 2].
// Params: n = side of the source level; mode = f; slot_or_cold = stats slot; values_only = 1: values only.
// Workgroup: 8 x 8, one thread per coarse cell.
#import params
#import downsample

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> wsrc: array<f32>;
@group(0) @binding(2) var<storage, read> vsrc: array<f32>;
@group(0) @binding(3) var<storage, read_write> out_w: array<f32>;
@group(0) @binding(4) var<storage, read_write> out_v: array<f32>;
@group(0) @binding(5) var<storage, read_write> stats: array<atomic<u32>>;

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
    var w: f32;
    var v: f32;
    if f == 1u {
        w = wsrc[jc * n + ic];
        v = vsrc[jc * n + ic];
    } else {
        var sw = 0.0;
        var s = 0.0;
        for (var j = jc * f; j < (jc + 1u) * f; j++) {
            for (var i = ic * f; i < (ic + 1u) * f; i++) {
                let idx = j * n + i;
                let wi = wsrc[idx];
                sw += wi;
                s += wi * vsrc[idx];
            }
        }
        w = ds_weight(sw, f);
        v = ds_value(s, sw);
        let c = jc * nc + ic;
        if params.values_only != 1u {
            out_w[c] = w;
        }
        out_v[c] = v;
    }
    if w > 0.0 {
        atomicMin(&stats[params.slot_or_cold], key(v));
        atomicMax(&stats[params.slot_or_cold + 1u], key(v));
    }
}
