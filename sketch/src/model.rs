//! The sketch document: what the user drew, in world metres.
//!
//! Coordinates: x east, y north, origin at the south-west corner of the extent, z up, metres.
//! A stroke's *left* side is the left of its direction of travel (first point to last point),
//! seen from above.

/// What a stroke does to the land.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum StrokeKind {
    /// Raises: heights fall away from the curve at the stroke's slopes.
    Ridge,
    /// Digs: heights rise away from the curve at the stroke's slopes.
    Valley,
    /// Holds the curve's heights flat across `width_m` on each side.
    Plateau,
}

impl StrokeKind {
    /// The name used in the file format (`"ridge"`, `"valley"`, `"plateau"`).
    pub fn as_str(self) -> &'static str {
        match self {
            StrokeKind::Ridge => "ridge",
            StrokeKind::Valley => "valley",
            StrokeKind::Plateau => "plateau",
        }
    }

    /// Parses a file-format name; `None` for an unknown kind.
    pub fn parse(name: &str) -> Option<StrokeKind> {
        match name {
            "ridge" => Some(StrokeKind::Ridge),
            "valley" => Some(StrokeKind::Valley),
            "plateau" => Some(StrokeKind::Plateau),
            _ => None,
        }
    }

    /// Default slope on each side, degrees.
    pub fn default_slope_deg(self) -> f64 {
        match self {
            StrokeKind::Ridge => 25.0,
            StrokeKind::Valley => 20.0,
            StrokeKind::Plateau => 0.0,
        }
    }

    /// Default band width on each side of the curve, metres.
    pub fn default_width_m(self) -> f64 {
        match self {
            StrokeKind::Ridge => 1500.0,
            StrokeKind::Valley => 1000.0,
            StrokeKind::Plateau => 800.0,
        }
    }

    /// Default roughness in [0, 1].
    pub fn default_roughness(self) -> f64 {
        match self {
            StrokeKind::Ridge => 0.6,
            StrokeKind::Valley => 0.4,
            StrokeKind::Plateau => 0.2,
        }
    }
}

/// How a stroke's points become its curve (seen from above, and its heights along it).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum CurveKind {
    /// A centripetal Catmull-Rom curve through every point (heights interpolated smoothly, without
    /// overshooting the points' heights).
    #[default]
    Smooth,
    /// Straight segments between consecutive points, heights linear along each.
    Polyline,
}

impl CurveKind {
    /// The name used in the file format (`"smooth"`, `"polyline"`).
    pub fn as_str(self) -> &'static str {
        match self {
            CurveKind::Smooth => "smooth",
            CurveKind::Polyline => "polyline",
        }
    }

    /// Parses a file-format name; `None` for an unknown one.
    pub fn parse(name: &str) -> Option<CurveKind> {
        match name {
            "smooth" => Some(CurveKind::Smooth),
            "polyline" => Some(CurveKind::Polyline),
            _ => None,
        }
    }
}

/// How the prescribed slope of a ridge or valley fades from the curve to the band edge
/// (`u = distance / width_m`; the slope there is the stroke's slope times `profile(u)`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum Falloff {
    /// `(1 - u^2)^2`: a steep upper flank that eases into a long gentle foot, reaching a zero slope
    /// with zero curvature at the band edge.
    #[default]
    Foot,
    /// `1 - 3u^2 + 2u^3` (smoothstep): symmetric S, zero slope at the band edge.
    Sigmoid,
    /// Constant slope to the band edge, where it stops dead (a crease at the band edge).
    None,
}

impl Falloff {
    /// Every falloff, in the order the editor lists them.
    pub const ALL: [Falloff; 3] = [Falloff::Foot, Falloff::Sigmoid, Falloff::None];

    /// The name used in the file format (`"foot"`, `"sigmoid"`, `"none"`).
    pub fn as_str(self) -> &'static str {
        match self {
            Falloff::Foot => "foot",
            Falloff::Sigmoid => "sigmoid",
            Falloff::None => "none",
        }
    }

    /// Parses a file-format name; `None` for an unknown one.
    pub fn parse(name: &str) -> Option<Falloff> {
        Falloff::ALL.into_iter().find(|f| f.as_str() == name)
    }

    /// The profile as `1 + u^2 (c2 + u (c3 + u c4))`: `[c2, c3, c4]`, so that the rasterisers
    /// evaluate every falloff with one expression.
    pub fn coefficients(self) -> [f64; 3] {
        match self {
            Falloff::Foot => [-2.0, 0.0, 1.0],
            Falloff::Sigmoid => [-3.0, 2.0, 0.0],
            Falloff::None => [0.0, 0.0, 0.0],
        }
    }

    /// The profile at `u` (clamped to `[0, 1]`): 1 at the curve, the fraction of the slope kept.
    pub fn profile(self, u: f64) -> f64 {
        let u = u.clamp(0.0, 1.0);
        let [c2, c3, c4] = self.coefficients();
        (1.0 + u * u * (c2 + u * (c3 + u * c4))).clamp(0.0, 1.0)
    }
}

/// Default [`Stroke::height_tolerance_m`]: a few metres, 0.2 % of a 1000 m relief, so that
/// detail can play along a crest without the stroke's drawn heights moving visibly.
pub const DEFAULT_HEIGHT_TOLERANCE_M: f64 = 2.0;
/// Largest accepted [`Stroke::height_tolerance_m`], metres.
pub const MAX_HEIGHT_TOLERANCE_M: f64 = 10_000.0;

/// One sketched curve with its attributes.
#[derive(Debug, Clone, PartialEq)]
pub struct Stroke {
    /// What the stroke does.
    pub kind: StrokeKind,
    /// Control points `[x, y, z]` in metres; at least two (three when closed), all finite.
    pub points: Vec<[f64; 3]>,
    /// Slope on the left of the direction of travel, degrees in [0, 85].
    pub slope_left_deg: f64,
    /// Slope on the right of the direction of travel, degrees in [0, 85].
    pub slope_right_deg: f64,
    /// Band width on each side of the curve where the slope (or, for a plateau, the flat) holds, metres (> 0).
    pub width_m: f64,
    /// Roughness in [0, 1], diffused over the terrain for the realism pass.
    pub roughness: f64,
    /// How the points become a curve.
    pub curve: CurveKind,
    /// A loop: the curve also joins the last point to the first (smoothly for a smooth curve).
    pub closed: bool,
    /// How the slope fades towards the band edge (ridges and valleys).
    pub falloff: Falloff,
    /// How far the realism pass may move the stroke's heights, metres (>= 0; 0 = exactly).
    pub height_tolerance_m: f64,
}

impl Stroke {
    /// A stroke of `kind` through `points` with the kind's default attributes.
    pub fn new(kind: StrokeKind, points: Vec<[f64; 3]>) -> Stroke {
        Stroke {
            kind,
            points,
            slope_left_deg: kind.default_slope_deg(),
            slope_right_deg: kind.default_slope_deg(),
            width_m: kind.default_width_m(),
            roughness: kind.default_roughness(),
            curve: CurveKind::default(),
            closed: false,
            falloff: Falloff::default(),
            height_tolerance_m: DEFAULT_HEIGHT_TOLERANCE_M,
        }
    }
}

/// A whole sketch: the terrain's extent, its base elevation and the strokes, in drawing order.
#[derive(Debug, Clone, PartialEq)]
pub struct Sketch {
    /// Width (east-west) and height (north-south) of the terrain, metres (> 0).
    pub extent_m: [f64; 2],
    /// Elevation of an empty sketch, metres.
    pub base_elevation_m: f64,
    /// Seed of the procedural detail (optional in the file, 0 when absent): the same sketch and seed
    /// give the same terrain everywhere.
    pub seed: u64,
    /// The strokes, in drawing order (later strokes win where constraints overlap at equal distance).
    pub strokes: Vec<Stroke>,
}

impl Sketch {
    /// An empty sketch of the given extent at the given base elevation.
    pub fn empty(extent_m: [f64; 2], base_elevation_m: f64) -> Sketch {
        Sketch {
            extent_m,
            base_elevation_m,
            seed: 0,
            strokes: Vec::new(),
        }
    }
}
