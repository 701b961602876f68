//! Mesh export: a corner-sampled heightmap as triangles, written as glTF 2.0 binary (`.glb`) or
//! Wavefront OBJ (`.obj`).
//!
//! Coordinates (glTF is y-up, right-handed): `X` east and `Z` south in metres from the
//! extent's south-west corner (so `Z` runs from `-extent_y` at the north edge to 0), `Y` the
//! height in metres. Normals come from central differences of the heights.
//!
//! Without an error bound every cell of the sample grid is two triangles. With one, the
//! triangulation is a right-triangulated irregular network (RTIN) over the `2^k + 1` grid: a
//! triangle is split at its hypotenuse's midpoint while any grid sample inside it lies more than
//! the bound from its plane. Split decisions are shared through the midpoint's error (the
//! largest over both triangles on that hypotenuse and everything below them), which keeps the
//! mesh free of cracks.

use std::io::Write;

use anyhow::{Result, bail};
use terrasketch_raster::Heightmap;

/// Largest mesh side, samples (4097^2 vertices make a GLB of about 800 MB).
pub const MAX_MESH_SIDE: usize = 4097;

/// A triangle mesh in glTF's frame.
pub struct Mesh {
    /// `[x, y, z]` per vertex, metres.
    pub positions: Vec<[f32; 3]>,
    /// Unit normal per vertex.
    pub normals: Vec<[f32; 3]>,
    /// Three vertex indices per triangle, counter-clockwise seen from above.
    pub indices: Vec<u32>,
}

/// A grid vertex `(column, row)` of the north-up raster.
type Vertex = (usize, usize);

/// Builds the mesh of `map`, a corner-sampled north-up raster, as the full grid (`max_error_m`
/// `None`) or as an RTIN within `max_error_m` of every sample (the raster must be `2^k + 1`
/// square).
pub fn build(map: &Heightmap, max_error_m: Option<f64>) -> Result<Mesh> {
    let (w, h) = (map.width, map.height);
    if w < 2 || h < 2 || w > MAX_MESH_SIDE || h > MAX_MESH_SIDE {
        bail!("a mesh needs 2 to {MAX_MESH_SIDE} samples per side, got {w} x {h}");
    }
    let mut triangles: Vec<[Vertex; 3]> = Vec::new();
    match max_error_m {
        None => {
            for r in 0..h - 1 {
                for c in 0..w - 1 {
                    triangles.push([(c, r), (c, r + 1), (c + 1, r)]);
                    triangles.push([(c + 1, r), (c, r + 1), (c + 1, r + 1)]);
                }
            }
        }
        Some(eps) => {
            if w != h || !(w - 1).is_power_of_two() {
                bail!("--max-error needs a square grid of 2^k + 1 samples, got {w} x {h}");
            }
            let errors = rtin_errors(map);
            let t = w - 1;
            let roots = [[(0, 0), (t, t), (t, 0)], [(t, t), (0, 0), (0, t)]];
            for root in roots {
                emit(map.width, &errors, eps as f32, root, &mut triangles);
            }
        }
    }
    Ok(assemble(map, &triangles))
}

/// Whether a triangle with hypotenuse `a`-`b` has an integer midpoint (can be split).
fn splittable(a: Vertex, b: Vertex) -> bool {
    a.0.abs_diff(b.0).is_multiple_of(2) && a.1.abs_diff(b.1).is_multiple_of(2) && a != b
}

fn midpoint(a: Vertex, b: Vertex) -> Vertex {
    ((a.0 + b.0) / 2, (a.1 + b.1) / 2)
}

/// The two halves of triangle `[a, b, c]` (hypotenuse `a`-`b`, right angle at `c`).
fn children([a, b, c]: [Vertex; 3]) -> [[Vertex; 3]; 2] {
    let m = midpoint(a, b);
    [[c, a, m], [b, c, m]]
}

/// Largest vertical distance from the samples inside or on triangle `tri` to its plane.
fn plane_error(map: &Heightmap, tri: [Vertex; 3]) -> f32 {
    let z = |(c, r): Vertex| f64::from(map.data[r * map.width + c]);
    let [p0, p1, p2] = tri.map(|(c, r)| (c as i64, r as i64));
    let area = (p1.0 - p0.0) * (p2.1 - p0.1) - (p2.0 - p0.0) * (p1.1 - p0.1);
    if area == 0 {
        return 0.0;
    }
    let (z0, z1, z2) = (z(tri[0]), z(tri[1]), z(tri[2]));
    let (c_lo, c_hi) = (p0.0.min(p1.0).min(p2.0), p0.0.max(p1.0).max(p2.0));
    let (r_lo, r_hi) = (p0.1.min(p1.1).min(p2.1), p0.1.max(p1.1).max(p2.1));
    let mut worst = 0.0f64;
    for r in r_lo..=r_hi {
        for c in c_lo..=c_hi {
            // Barycentric weights times the doubled area; all of one sign inside.
            let w0 = (p1.0 - c) * (p2.1 - r) - (p2.0 - c) * (p1.1 - r);
            let w1 = (p2.0 - c) * (p0.1 - r) - (p0.0 - c) * (p2.1 - r);
            let w2 = area - w0 - w1;
            let inside = if area > 0 {
                w0 >= 0 && w1 >= 0 && w2 >= 0
            } else {
                w0 <= 0 && w1 <= 0 && w2 <= 0
            };
            if inside {
                let plane = (w0 as f64 * z0 + w1 as f64 * z1 + w2 as f64 * z2) / area as f64;
                worst = worst.max((z((c as usize, r as usize)) - plane).abs());
            }
        }
    }
    worst as f32
}

/// Per grid vertex, the error that decides whether the triangles whose hypotenuse it halves are
/// split: the largest plane error of those triangles and of every triangle below them.
/// Computed level by level from the smallest splittable triangles up, so that a midpoint's
/// error is complete (both sides of its hypotenuse) before its parents read it.
fn rtin_errors(map: &Heightmap) -> Vec<f32> {
    let n = map.width;
    let t = n - 1;
    let mut errors = vec![0.0f32; n * n];
    let depth_max = 2 * t.trailing_zeros() as usize;
    let roots = [[(0, 0), (t, t), (t, 0)], [(t, t), (0, 0), (0, t)]];
    for depth in (0..depth_max).rev() {
        let mut visit = |tri: [Vertex; 3]| {
            let [a, b, _] = tri;
            if !splittable(a, b) {
                return;
            }
            let m = midpoint(a, b);
            let mut e = plane_error(map, tri).max(errors[m.1 * n + m.0]);
            for child in children(tri) {
                if splittable(child[0], child[1]) {
                    let cm = midpoint(child[0], child[1]);
                    e = e.max(errors[cm.1 * n + cm.0]);
                }
            }
            errors[m.1 * n + m.0] = e;
        };
        for root in roots {
            at_depth(root, depth, &mut visit);
        }
    }
    errors
}

/// Calls `visit` on every triangle `depth` splits below `tri`.
fn at_depth(tri: [Vertex; 3], depth: usize, visit: &mut impl FnMut([Vertex; 3])) {
    if depth == 0 {
        visit(tri);
    } else if splittable(tri[0], tri[1]) {
        for child in children(tri) {
            at_depth(child, depth - 1, visit);
        }
    }
}

/// Emits `tri` or, when its midpoint's error exceeds `eps`, its halves.
fn emit(n: usize, errors: &[f32], eps: f32, tri: [Vertex; 3], out: &mut Vec<[Vertex; 3]>) {
    let [a, b, _] = tri;
    if splittable(a, b) {
        let m = midpoint(a, b);
        if errors[m.1 * n + m.0] > eps {
            for child in children(tri) {
                emit(n, errors, eps, child, out);
            }
            return;
        }
    }
    out.push(tri);
}

/// Numbers the vertices the triangles use, in first-use order, and orients every triangle
/// counter-clockwise seen from above (+Y).
fn assemble(map: &Heightmap, triangles: &[[Vertex; 3]]) -> Mesh {
    let (w, h) = (map.width, map.height);
    let [dx, dy] = map.cell_size_m;
    let z = |c: usize, r: usize| map.data[r * w + c];
    let mut index = vec![u32::MAX; w * h];
    let mut mesh = Mesh {
        positions: Vec::new(),
        normals: Vec::new(),
        indices: Vec::with_capacity(triangles.len() * 3),
    };
    let position = |(c, r): Vertex| {
        [
            (c as f64 * dx) as f32,
            z(c, r),
            -(((h - 1 - r) as f64) * dy) as f32,
        ]
    };
    for tri in triangles {
        // Columns run along X and rows along Z (south): the face normal (p1 - p0) x (p2 - p0)
        // points up (+Y) when the turn in (column, row) space is negative.
        let [p0, p1, p2] = tri.map(|(c, r)| (c as i64, r as i64));
        let turn = (p1.0 - p0.0) * (p2.1 - p0.1) - (p2.0 - p0.0) * (p1.1 - p0.1);
        let ordered = if turn < 0 {
            *tri
        } else {
            [tri[0], tri[2], tri[1]]
        };
        for v in ordered {
            let slot = &mut index[v.1 * w + v.0];
            if *slot == u32::MAX {
                *slot = mesh.positions.len() as u32;
                mesh.positions.push(position(v));
                mesh.normals.push(normal(map, v));
            }
            mesh.indices.push(*slot);
        }
    }
    mesh
}

/// The unit normal at grid vertex `v` from central differences (one-sided on the border).
fn normal(map: &Heightmap, (c, r): Vertex) -> [f32; 3] {
    let (w, h) = (map.width, map.height);
    let [dx, dy] = map.cell_size_m;
    let z = |c: usize, r: usize| f64::from(map.data[r * w + c]);
    let (c0, c1) = (c.saturating_sub(1), (c + 1).min(w - 1));
    let (r0, r1) = (r.saturating_sub(1), (r + 1).min(h - 1));
    // East slope, and north slope (rows run south).
    let gx = (z(c1, r) - z(c0, r)) / ((c1 - c0) as f64 * dx);
    let gy = (z(c, r0) - z(c, r1)) / ((r1 - r0) as f64 * dy);
    // The world normal (-gx, -gy, 1) with north = -Z.
    let (nx, ny, nz) = (-gx, 1.0, gy);
    let len = (nx * nx + ny * ny + nz * nz).sqrt();
    [(nx / len) as f32, (ny / len) as f32, (nz / len) as f32]
}

/// The mesh as a GLB file: one node, one triangle primitive with POSITION, NORMAL and u32
/// indices in one binary buffer.
pub fn to_glb(mesh: &Mesh) -> Result<Vec<u8>> {
    let mut bin = Vec::new();
    for p in &mesh.positions {
        p.iter()
            .for_each(|v| bin.extend_from_slice(&v.to_le_bytes()));
    }
    let normals_offset = bin.len();
    for n in &mesh.normals {
        n.iter()
            .for_each(|v| bin.extend_from_slice(&v.to_le_bytes()));
    }
    let indices_offset = bin.len();
    for i in &mesh.indices {
        bin.extend_from_slice(&i.to_le_bytes());
    }
    let bin_len = bin.len();
    let mut lo = [f32::INFINITY; 3];
    let mut hi = [f32::NEG_INFINITY; 3];
    for p in &mesh.positions {
        for k in 0..3 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    let vertices = mesh.positions.len();
    let json = serde_json::json!({
        "asset": { "version": "2.0", "generator": "terrasketch" },
        "scene": 0,
        "scenes": [ { "nodes": [0] } ],
        "nodes": [ { "mesh": 0, "name": "terrain" } ],
        "meshes": [ { "name": "terrain", "primitives": [ {
            "attributes": { "POSITION": 0, "NORMAL": 1 }, "indices": 2, "mode": 4 } ] } ],
        "buffers": [ { "byteLength": bin_len } ],
        "bufferViews": [
            { "buffer": 0, "byteOffset": 0, "byteLength": normals_offset, "target": 34962 },
            { "buffer": 0, "byteOffset": normals_offset,
              "byteLength": indices_offset - normals_offset, "target": 34962 },
            { "buffer": 0, "byteOffset": indices_offset,
              "byteLength": bin_len - indices_offset, "target": 34963 },
        ],
        "accessors": [
            { "bufferView": 0, "componentType": 5126, "count": vertices, "type": "VEC3",
              "min": lo, "max": hi },
            { "bufferView": 1, "componentType": 5126, "count": vertices, "type": "VEC3" },
            { "bufferView": 2, "componentType": 5125, "count": mesh.indices.len(),
              "type": "SCALAR" },
        ],
    });
    let mut json = serde_json::to_vec(&json)?;
    // Chunks are 4-byte aligned: JSON padded with spaces, binary with zeros.
    while !json.len().is_multiple_of(4) {
        json.push(b' ');
    }
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let total = 12 + 8 + json.len() + 8 + bin.len();
    let total = u32::try_from(total)
        .map_err(|_| anyhow::anyhow!("the mesh ({total} bytes) is too large for a GLB (4 GiB)"))?;
    let mut out = Vec::with_capacity(total as usize);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&total.to_le_bytes());
    for (kind, data) in [(b"JSON", &json), (b"BIN\0", &bin)] {
        out.extend_from_slice(&(data.len() as u32).to_le_bytes());
        out.extend_from_slice(kind);
        out.extend_from_slice(data);
    }
    Ok(out)
}

/// The mesh as Wavefront OBJ text (`v`, `vn`, `f a//a b//b c//c`, 1-based).
pub fn to_obj(mesh: &Mesh) -> Result<Vec<u8>> {
    let mut out = Vec::with_capacity(mesh.positions.len() * 64 + mesh.indices.len() * 12);
    writeln!(out, "# terrasketch terrain: x east, y up, z south, metres")?;
    for [x, y, z] in &mesh.positions {
        writeln!(out, "v {x} {y} {z}")?;
    }
    for [x, y, z] in &mesh.normals {
        writeln!(out, "vn {x} {y} {z}")?;
    }
    for t in mesh.indices.chunks_exact(3) {
        let [a, b, c] = [t[0] + 1, t[1] + 1, t[2] + 1];
        writeln!(out, "f {a}//{a} {b}//{b} {c}//{c}")?;
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn map(n: usize, f: impl Fn(f64, f64) -> f64) -> Heightmap {
        let mut data = Vec::new();
        for r in 0..n {
            for c in 0..n {
                data.push(f(c as f64, (n - 1 - r) as f64) as f32);
            }
        }
        Heightmap {
            width: n,
            height: n,
            data,
            cell_size_m: [2.0, 2.0],
        }
    }

    #[test]
    fn a_plane_needs_two_triangles_and_a_bump_more() {
        let plane = map(33, |x, y| 3.0 * x - y);
        let mesh = build(&plane, Some(0.01)).unwrap();
        assert_eq!(mesh.indices.len(), 6);
        assert_eq!(build(&plane, None).unwrap().indices.len(), 32 * 32 * 6);
        let bump = map(33, |x, y| {
            50.0 * (-((x - 16.0).powi(2) + (y - 16.0).powi(2)) / 20.0).exp()
        });
        let coarse = build(&bump, Some(5.0)).unwrap().indices.len();
        let fine = build(&bump, Some(0.1)).unwrap().indices.len();
        assert!(6 < coarse && coarse < fine, "{coarse} {fine}");
    }

    #[test]
    fn normals_of_a_plane_tilt_away_from_the_rise() {
        // Rises to the east at 45 degrees: the normal leans west (-X) and up.
        let plane = map(5, |x, _| 2.0 * x);
        let n = normal(&plane, (2, 2));
        let s = std::f32::consts::FRAC_1_SQRT_2;
        assert!((n[0] + s).abs() < 1e-6 && (n[1] - s).abs() < 1e-6 && n[2].abs() < 1e-6);
    }
}
