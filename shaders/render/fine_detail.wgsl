// Functions (no entry point): the detail's octaves finer than a heightmap cell, display only, which
// the terrain fragment shader turns into shading when the camera is close. The CPU twin is
// `terrasketch_detail::fine_octaves` (same octave ladder, seeds, offsets and hashes; the rotations
// are the golden-angle steps of its table, here from cos/sin).
// Appended to `terrain.wgsl` (and to the test's compute shader) when the module is made.

const FINE_HASH_X: u32 = 0x27d4eb2du;
const FINE_HASH_Y: u32 = 0x165667b1u;
// Octave ladder: from 2^6 times the reference wavelength down to 2^-9 of it (`COARSE_OCTAVES`,
// `MAX_OCTAVES`).
const FINE_FIRST_OCTAVE: i32 = -6;
const FINE_END_OCTAVE: i32 = 10;
const GOLDEN_ANGLE: f32 = 2.3999632;
// `terrasketch_detail::noise::FINE_DEPTH`: how far below a cell the shading reaches.
const FINE_DEPTH: f32 = 8.0;

fn fine_pcg(v: u32) -> u32 {
    let s = v * 747796405u + 2891336453u;
    let w = ((s >> ((s >> 28u) + 4u)) ^ s) * 277803737u;
    return (w >> 22u) ^ w;
}

// The lattice point's diagonal gradient: bit 30 of its hash flips x, bit 31 flips y.
fn fine_corner(xa: u32, yb: u32, s: u32) -> vec2<f32> {
    let h0 = xa ^ yb ^ s;
    let h = (h0 ^ (h0 >> 15u)) * 0x2c1b3c6du;
    return vec2<f32>(
        select(1.0, -1.0, (h & 0x40000000u) != 0u),
        select(1.0, -1.0, (h & 0x80000000u) != 0u),
    );
}

// Perlin gradient noise (quintic fade) at lattice coordinates p for octave seed s: x its value, yz
// its gradient in lattice units.
fn fine_noise(p: vec2<f32>, s: u32) -> vec3<f32> {
    let pf = floor(p);
    let f = p - pf;
    let i = vec2<i32>(pf);
    let x0 = bitcast<u32>(i.x) * FINE_HASH_X;
    let y0 = bitcast<u32>(i.y) * FINE_HASH_Y;
    let x1 = x0 + FINE_HASH_X;
    let y1 = y0 + FINE_HASH_Y;
    let g00 = fine_corner(x0, y0, s);
    let g10 = fine_corner(x1, y0, s);
    let g01 = fine_corner(x0, y1, s);
    let g11 = fine_corner(x1, y1, s);
    let n00 = dot(g00, f);
    let n10 = dot(g10, f - vec2<f32>(1.0, 0.0));
    let n01 = dot(g01, f - vec2<f32>(0.0, 1.0));
    let n11 = dot(g11, f - vec2<f32>(1.0, 1.0));
    let u = f * f * f * (f * (f * 6.0 - 15.0) + 10.0);
    let du = 30.0 * f * f * (f - 1.0) * (f - 1.0);
    let k = n00 - n10 - n01 + n11;
    let value = n00 + u.x * (n10 - n00) + u.y * (n01 - n00) + u.x * u.y * k;
    let grad = g00 + u.x * (g10 - g00) + u.y * (g01 - g00) + u.x * u.y * (g00 - g10 - g01 + g11)
        + du * vec2<f32>(n10 - n00 + u.y * k, n01 - n00 + u.x * k);
    return vec3<f32>(value, grad);
}

// Sum at world point xy (metres) of the octaves a heightmap of `cell_m` cells leaves out, each
// weighted 2^(-H o) times `1 - clamp(wl / cell - 1, 0, 1)` (what the heights leave of it) times
// `clamp(FINE_DEPTH wl / cell - 1, 0, 1)` (down to a quarter of a cell, none from an eighth) times
// `clamp(wl / (2 footprint) - 1, 0, 1)` (none under two pixels of `footprint_m`, all from four):
// x the value per unit amplitude, yz its gradient in metres per metre. `shape`: Hurst exponent,
// reference wavelength (metres), the billow's mean |n|.
fn fine_detail(
    xy: vec2<f32>,
    cell_m: f32,
    footprint_m: f32,
    seed32: u32,
    shape: vec3<f32>,
) -> vec3<f32> {
    var sum = vec3<f32>(0.0);
    // Seen from afar nothing is left: every octave under two cells is under two pixels.
    if (footprint_m >= cell_m) {
        return sum;
    }
    // From the coarsest octave under two cells (one earlier at most, whose weight is 0) to the
    // finest one above an eighth of a cell and two pixels.
    let first = max(i32(floor(log2(shape.y / (2.0 * cell_m)))), FINE_FIRST_OCTAVE);
    let finest = max(cell_m / FINE_DEPTH, 2.0 * footprint_m);
    for (var oct = first; oct < FINE_END_OCTAVE; oct++) {
        let wl = shape.y * exp2(-f32(oct));
        if (wl <= finest) {
            break;
        }
        let left = (1.0 - clamp(wl / cell_m - 1.0, 0.0, 1.0))
            * clamp(FINE_DEPTH * wl / cell_m - 1.0, 0.0, 1.0);
        let shown = clamp(wl / (2.0 * footprint_m) - 1.0, 0.0, 1.0);
        let c = left * shown;
        if (c <= 0.0) {
            continue;
        }
        let w = c * exp2(-shape.x * f32(oct));
        let s = fine_pcg(seed32 + bitcast<u32>(oct));
        let off = vec2<f32>(
            f32(fine_pcg(s) & 0xffffu),
            f32(fine_pcg(s ^ 0x9e3779b9u) & 0xffffu),
        ) / 65536.0;
        let a = f32(oct & 15) * GOLDEN_ANGLE;
        let rot = vec2<f32>(cos(a), sin(a));
        let p = xy * (1.0 / wl);
        let q = vec2<f32>(rot.x * p.x - rot.y * p.y, rot.y * p.x + rot.x * p.y) + off;
        let n = fine_noise(q, s);
        // Billow: 2 (|n| - mean |n|).
        let sg = select(1.0, -1.0, n.x < 0.0);
        let value = 2.0 * (abs(n.x) - shape.z);
        let gl = 2.0 * sg * n.yz;
        let gm = vec2<f32>(rot.x * gl.x + rot.y * gl.y, -rot.y * gl.x + rot.x * gl.y) / wl;
        sum += w * vec3<f32>(value, gm);
    }
    return sum;
}
