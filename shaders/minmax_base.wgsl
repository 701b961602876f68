// Pass: minmax_base: finest stored level of the min/max pyramid (side s = min(n, 64)): per cell, the exact
// min and max of the level-0 heights in its (n/s) x (n/s) footprint. One workgroup per cell.
// Reads:  h (level 0, n x n; `#import h_read`: a buffer, or mip 0 of the height texture).
// Writes: minmax[dst_offset + J * s + I] = vec2(min, max).
// Params: n = level-0 side, mode = s (side of the stored level), dst_offset.
// Workgroup: 16 x 16 (strided over the footprint), tree reduction in workgroup memory.
#import params
#import h_read

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(2) var<storage, read_write> minmax: array<vec2<f32>>;

var<workgroup> lo: array<f32, 256>;
var<workgroup> hi: array<f32, 256>;

@compute @workgroup_size(16, 16)
fn main(
    @builtin(local_invocation_id) lid: vec3<u32>,
    @builtin(local_invocation_index) li: u32,
    @builtin(workgroup_id) wid: vec3<u32>,
) {
    let n = params.n;
    let s = params.mode;
    let fp = n / s;
    var mn = 3.0e38;
    var mx = -3.0e38;
    for (var y = lid.y; y < fp; y += 16u) {
        for (var x = lid.x; x < fp; x += 16u) {
            let v = h_get(wid.x * fp + x, wid.y * fp + y);
            mn = min(mn, v);
            mx = max(mx, v);
        }
    }
    lo[li] = mn;
    hi[li] = mx;
    for (var k = 128u; k > 0u; k = k / 2u) {
        workgroupBarrier();
        if li < k {
            lo[li] = min(lo[li], lo[li + k]);
            hi[li] = max(hi[li], hi[li + k]);
        }
    }
    if li == 0u {
        minmax[params.dst_offset + wid.y * s + wid.x] = vec2<f32>(lo[0], hi[0]);
    }
}
