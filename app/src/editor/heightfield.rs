//! Height fields as the editor samples them: a copy of one mip (picking, the frozen depth map of a
//! stroke, probes), with bilinear sampling that matches the terrain vertex shader and a ray cast.

use glam::Vec3;

use super::camera::Ray;

/// A sampled copy of one mip (the frozen "depth map" of a stroke, or the live terrain for picking).
#[derive(Debug, Clone)]
pub struct HeightField {
    /// Cells per side.
    pub side: usize,
    /// Extent, metres.
    pub extent_m: [f32; 2],
    /// Heights, row 0 = south.
    pub data: Vec<f32>,
}

impl HeightField {
    /// Bilinear height at world `(x, y)` with texel centres at `(c + 0.5) / side`, clamped at the
    /// borders: the vertex shader's `sample_height`.
    pub fn height_at(&self, x_m: f32, y_m: f32) -> f32 {
        sample_bilinear(
            &self.data,
            self.side,
            x_m / self.extent_m[0],
            y_m / self.extent_m[1],
        )
    }

    /// First intersection of a ray with the height field inside the extent (march, then bisect).
    pub fn raycast(&self, ray: &Ray) -> Option<Vec3> {
        let [ex, ey] = self.extent_m;
        // Clip the ray to the extent's box in x and y.
        let (mut t0, mut t1) = (0.0f32, 1.0e7f32);
        for (o, d, hi) in [(ray.origin.x, ray.dir.x, ex), (ray.origin.y, ray.dir.y, ey)] {
            if d.abs() < 1e-9 {
                if o < 0.0 || o > hi {
                    return None;
                }
            } else {
                let (a, b) = ((0.0 - o) / d, (hi - o) / d);
                t0 = t0.max(a.min(b));
                t1 = t1.min(a.max(b));
            }
        }
        if t0 >= t1 {
            return None;
        }
        let step = 0.5 * ex.max(ey) / self.side as f32;
        let above = |t: f32| {
            let p = ray.origin + ray.dir * t;
            p.z - self.height_at(p.x, p.y)
        };
        let mut t = t0;
        let mut prev = above(t);
        if prev < 0.0 {
            return Some(ray.origin + ray.dir * t0);
        }
        let max_steps = 200_000;
        for _ in 0..max_steps {
            let next = (t + step).min(t1);
            let a = above(next);
            if a <= 0.0 {
                let (mut lo, mut hi) = (t, next);
                for _ in 0..30 {
                    let mid = 0.5 * (lo + hi);
                    if above(mid) > 0.0 {
                        lo = mid;
                    } else {
                        hi = mid;
                    }
                }
                let _ = prev;
                return Some(ray.origin + ray.dir * hi);
            }
            prev = a;
            t = next;
            if t >= t1 {
                break;
            }
        }
        None
    }
}

/// The four texels and weights of a bilinear sample (as `sample_bilinear`).
pub struct Corners {
    /// `(x0, y0), (x1, y0), (x0, y1), (x1, y1)`.
    pub texels: [[usize; 2]; 4],
    fx: f32,
    fy: f32,
}

impl Corners {
    /// The bilinear combination of the four texel values (same order as `texels`).
    pub fn combine(&self, h: [f32; 4]) -> f32 {
        let (fx, fy) = (self.fx, self.fy);
        let south = h[0] * (1.0 - fx) + h[1] * fx;
        let north = h[2] * (1.0 - fx) + h[3] * fx;
        south * (1.0 - fy) + north * fy
    }
}

/// Texels and weights of the bilinear sample at `(u, v)` (extent fractions, clamped at the borders).
pub fn bilinear_corners(side: usize, u: f32, v: f32) -> Corners {
    let s = side as f32;
    let px = (u * s - 0.5).clamp(0.0, s - 1.0);
    let py = (v * s - 0.5).clamp(0.0, s - 1.0);
    let (x0, y0) = (px.floor() as usize, py.floor() as usize);
    let (x1, y1) = ((x0 + 1).min(side - 1), (y0 + 1).min(side - 1));
    Corners {
        texels: [[x0, y0], [x1, y0], [x0, y1], [x1, y1]],
        fx: px - x0 as f32,
        fy: py - y0 as f32,
    }
}

/// Bilinear sample of a `side x side` grid at `(u, v)` in extent fractions, clamped at the borders.
pub fn sample_bilinear(data: &[f32], side: usize, u: f32, v: f32) -> f32 {
    let c = bilinear_corners(side, u, v);
    c.combine(c.texels.map(|t| data[t[1] * side + t[0]]))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn raycast_hits_a_flat_field() {
        let f = HeightField {
            side: 64,
            extent_m: [1000.0, 1000.0],
            data: vec![10.0; 64 * 64],
        };
        let ray = Ray {
            origin: Vec3::new(500.0, -100.0, 500.0),
            dir: Vec3::new(0.0, 1.0, -1.0).normalize(),
        };
        let p = f.raycast(&ray).unwrap();
        assert!(
            (p.z - 10.0).abs() < 0.01 && (p.y - 390.0).abs() < 0.1,
            "{p}"
        );
    }
}
