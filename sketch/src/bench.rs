//! Built-in sketches: the benchmark the solver is measured on, and the editor's opening scene.
//!
//! Both are made from sines only (no randomness), so every call returns the same sketch.

use std::f64::consts::{PI, TAU};

use crate::model::{Sketch, Stroke, StrokeKind};

/// Side of the benchmark's square extent, metres.
pub const BENCHMARK_EXTENT_M: f64 = 20480.0;
/// Side of the example scene's square extent, metres.
pub const EXAMPLE_EXTENT_M: f64 = 10240.0;

/// The solver benchmark: a 20480 m x 20480 m extent at base elevation 0 with four long wiggly
/// ridges that cross one another at different crest heights (900 m to 1800 m), one long valley
/// falling from 300 m to 100 m across them, and a flat plateau at 600 m. Every point lies at least
/// 1000 m inside the extent; the sketch validates without warnings.
pub fn benchmark_sketch() -> Sketch {
    let mut sketch = Sketch::empty([BENCHMARK_EXTENT_M; 2], 0.0);
    let ridge = |points| Stroke::new(StrokeKind::Ridge, points);
    // South-west to north-east, the highest: crest 1200..1800 m.
    let path = Wiggle {
        start: [2500.0, 3000.0],
        end: [18000.0, 17500.0],
        count: 48,
        amplitude_m: 700.0,
        waves: 2.5,
    };
    sketch.strokes.push(ridge(
        path.points(|t| 1500.0 + 300.0 * (TAU * 1.5 * t).sin()),
    ));
    // North-west to south-east, the lowest: crest 900..1100 m.
    let path = Wiggle {
        start: [2500.0, 17500.0],
        end: [18000.0, 3000.0],
        count: 40,
        amplitude_m: 500.0,
        waves: 2.0,
    };
    sketch.strokes.push(ridge(
        path.points(|t| 1000.0 + 100.0 * (TAU * 2.0 * t).sin()),
    ));
    // South to north: crest 1100..1500 m.
    let path = Wiggle {
        start: [9000.0, 1800.0],
        end: [11500.0, 18700.0],
        count: 56,
        amplitude_m: 900.0,
        waves: 3.0,
    };
    sketch
        .strokes
        .push(ridge(path.points(|t| 1300.0 + 200.0 * (TAU * t).cos())));
    // West to east: crest 1550..1750 m.
    let path = Wiggle {
        start: [1800.0, 12500.0],
        end: [18700.0, 11000.0],
        count: 32,
        amplitude_m: 400.0,
        waves: 1.5,
    };
    sketch.strokes.push(ridge(
        path.points(|t| 1650.0 + 100.0 * (TAU * 2.5 * t).sin()),
    ));
    // A valley across three of the ridges, falling steadily from 300 m to 100 m.
    let path = Wiggle {
        start: [1500.0, 7000.0],
        end: [19000.0, 5500.0],
        count: 36,
        amplitude_m: 600.0,
        waves: 1.0,
    };
    sketch.strokes.push(Stroke::new(
        StrokeKind::Valley,
        path.points(|t| 300.0 - 200.0 * t),
    ));
    // A flat plateau between the valley and the west-east ridge.
    let path = Wiggle {
        start: [2500.0, 9000.0],
        end: [6000.0, 9800.0],
        count: 20,
        amplitude_m: 250.0,
        waves: 1.0,
    };
    sketch
        .strokes
        .push(Stroke::new(StrokeKind::Plateau, path.points(|_| 600.0)));
    sketch
}

/// The editor's opening scene on a 10240 m x 10240 m extent at base elevation 0: a mountain
/// range across the north (crest up to about 1200 m) with a spur running south-east from it, a
/// meandering river valley falling from 380 m to 120 m towards the east, and a plateau at 450 m
/// in the south-west. Validates without warnings.
pub fn example_sketch() -> Sketch {
    let mut sketch = Sketch::empty([EXAMPLE_EXTENT_M; 2], 0.0);
    let path = Wiggle {
        start: [1500.0, 7800.0],
        end: [8800.0, 8600.0],
        count: 36,
        amplitude_m: 350.0,
        waves: 2.0,
    };
    let range = path.points(|t| 700.0 + 500.0 * (PI * t).sin() + 80.0 * (TAU * 3.0 * t).sin());
    // The spur leaves the range at one of its points, at that point's height, and falls to 550 m.
    let [spur_x, spur_y, spur_z] = range[16];
    let path = Wiggle {
        start: [spur_x, spur_y],
        end: [7600.0, 5200.0],
        count: 20,
        amplitude_m: 200.0,
        waves: 1.5,
    };
    let spur = path.points(|t| spur_z + (550.0 - spur_z) * t);
    let path = Wiggle {
        start: [600.0, 5200.0],
        end: [9600.0, 1800.0],
        count: 48,
        amplitude_m: 500.0,
        waves: 3.0,
    };
    let river = path.points(|t| 380.0 - 260.0 * t);
    let path = Wiggle {
        start: [1400.0, 1500.0],
        end: [4000.0, 2100.0],
        count: 16,
        amplitude_m: 150.0,
        waves: 1.0,
    };
    let plateau = path.points(|_| 450.0);

    sketch.strokes.push(Stroke {
        width_m: 1200.0,
        ..Stroke::new(StrokeKind::Ridge, range)
    });
    sketch.strokes.push(Stroke {
        slope_left_deg: 30.0,
        slope_right_deg: 18.0,
        width_m: 900.0,
        roughness: 0.5,
        ..Stroke::new(StrokeKind::Ridge, spur)
    });
    sketch.strokes.push(Stroke {
        width_m: 700.0,
        roughness: 0.3,
        ..Stroke::new(StrokeKind::Valley, river)
    });
    sketch
        .strokes
        .push(Stroke::new(StrokeKind::Plateau, plateau));
    sketch
}

/// A polyline in plan: `count` points from `start` to `end` (both `[x, y]`, metres), pushed
/// sideways by `amplitude_m * sin(2 pi waves t)` perpendicular to the straight line, so both ends
/// lie on it (`t` runs from 0 at `start` to 1 at `end`).
struct Wiggle {
    start: [f64; 2],
    end: [f64; 2],
    count: usize,
    amplitude_m: f64,
    waves: f64,
}

impl Wiggle {
    /// The points, with height `z(t)`.
    fn points(&self, z: impl Fn(f64) -> f64) -> Vec<[f64; 3]> {
        let (start, end) = (self.start, self.end);
        let (dx, dy) = (end[0] - start[0], end[1] - start[1]);
        let length = dx.hypot(dy);
        // Unit normal to the left of the direction of travel.
        let (nx, ny) = (-dy / length, dx / length);
        let last = self.count.saturating_sub(1).max(1) as f64;
        (0..self.count)
            .map(|i| {
                let t = i as f64 / last;
                let offset = self.amplitude_m * (TAU * self.waves * t).sin();
                [
                    start[0] + dx * t + nx * offset,
                    start[1] + dy * t + ny * offset,
                    z(t),
                ]
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn path_ends_on_its_line() {
        let wiggle = Wiggle {
            start: [0.0, 0.0],
            end: [100.0, 0.0],
            count: 5,
            amplitude_m: 10.0,
            waves: 1.0,
        };
        let path = wiggle.points(|t| t);
        assert_eq!(path.len(), 5);
        assert_eq!(path[0], [0.0, 0.0, 0.0]);
        assert!((path[4][0] - 100.0).abs() < 1e-9 && path[4][1].abs() < 1e-9);
        // A quarter wave in: pushed 10 m to the left (north) of an eastward line.
        assert!((path[1][1] - 10.0).abs() < 1e-9);
    }
}
