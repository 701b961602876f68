//! GeoTIFF georeference as stored in the file: the raster-to-model transform (pixel scale and
//! tie points, or a 4 x 4 model transformation) and the coordinate reference system (the GeoKey
//! directory with its double and ASCII parameters), kept verbatim so that a file can be written
//! back with the same place.

/// GeoKey: model type (projected, geographic, geocentric).
pub(crate) const KEY_MODEL_TYPE: u16 = 1024;
/// GeoKey: raster type (pixel is area or point).
pub(crate) const KEY_RASTER_TYPE: u16 = 1025;
/// GeoKey: EPSG code of a geographic CRS.
pub(crate) const KEY_GEOGRAPHIC_TYPE: u16 = 2048;
/// GeoKey: EPSG code of a projected CRS.
pub(crate) const KEY_PROJECTED_CS_TYPE: u16 = 3072;
/// GeoKey: linear unit of a projected CRS.
pub(crate) const KEY_PROJ_LINEAR_UNITS: u16 = 3076;
/// GeoKey: vertical unit.
pub(crate) const KEY_VERTICAL_UNITS: u16 = 4099;
/// GeoKey value: projected model.
pub(crate) const MODEL_TYPE_PROJECTED: u16 = 1;
/// GeoKey value: geographic model.
pub(crate) const MODEL_TYPE_GEOGRAPHIC: u16 = 2;
/// GeoKey value: pixel is point.
pub(crate) const RASTER_PIXEL_IS_POINT: u16 = 2;
/// GeoKey value: user-defined (no EPSG code).
const USER_DEFINED: u16 = 32767;

/// How raster coordinates map to model (CRS) coordinates.
#[derive(Debug, Clone, PartialEq)]
pub enum Transform {
    /// `ModelPixelScaleTag` `[sx, sy, sz]` with `ModelTiepointTag` tie points
    /// `(i, j, k, x, y, z)`: `x = (i - I) * sx + X`, `y = Y - (j - J) * sy`.
    ScaleTiepoints {
        /// Pixel scale, model units per pixel.
        scale: [f64; 3],
        /// Tie points, six numbers each (at least one).
        tiepoints: Vec<[f64; 6]>,
    },
    /// `ModelTransformationTag`: a row-major 4 x 4 matrix taking `(i, j, 0, 1)` to the model.
    Matrix([f64; 16]),
}

/// A GeoTIFF georeference, as read from (or to be written to) a file. It describes the raster as
/// held in memory: row 0 north, column 0 west (rows stored south-up were flipped on reading and
/// the transform with them).
#[derive(Debug, Clone, PartialEq)]
pub struct Georef {
    /// Raster to model transform.
    pub transform: Transform,
    /// `GeoKeyDirectoryTag`, verbatim (header and keys); empty when the file has none.
    pub geo_keys: Vec<u16>,
    /// `GeoDoubleParamsTag`, verbatim.
    pub geo_doubles: Vec<f64>,
    /// `GeoAsciiParamsTag`, verbatim without the final NUL.
    pub geo_ascii: String,
}

impl Georef {
    /// The value of GeoKey `id` when stored inline (TIFF tag location 0).
    pub fn key(&self, id: u16) -> Option<u16> {
        self.geo_keys
            .get(4..)?
            .chunks_exact(4)
            .find(|k| k[0] == id && k[1] == 0)
            .map(|k| k[3])
    }

    /// The EPSG code of the CRS: the projected CRS's if there is one, else the geographic CRS's;
    /// `None` for a user-defined or absent CRS.
    pub fn epsg(&self) -> Option<u16> {
        [KEY_PROJECTED_CS_TYPE, KEY_GEOGRAPHIC_TYPE]
            .into_iter()
            .filter_map(|id| self.key(id))
            .find(|&code| code != 0 && code != USER_DEFINED)
    }

    /// Whether the raster type key says pixel-is-point (sample values at pixel centres' raster
    /// coordinates `(i, j)`), rather than pixel-is-area (pixel `i` spans `[i, i + 1]`).
    pub fn pixel_is_point(&self) -> bool {
        self.key(KEY_RASTER_TYPE) == Some(RASTER_PIXEL_IS_POINT)
    }

    /// The georeference of a new raster whose pixel `(i', j')` covers, in this raster's
    /// pixel-is-area coordinates, `[ax + bx * i', ax + bx * (i' + 1)]` by
    /// `[ay + by * j', ay + by * (j' + 1)]`: a window (`b = 1`), a resampling (`b` = old pixels
    /// per new pixel) or a flip (`a = side`, `b = -1`). The model coordinates are unchanged;
    /// identity (`a = 0`, `b = 1`) gives the same numbers bit for bit.
    pub fn remapped(&self, [ax, bx]: [f64; 2], [ay, by]: [f64; 2]) -> Georef {
        // Pixel-is-point coordinates count pixel centres: old centre of new pixel k is
        // a + b (k + 1/2) - 1/2.
        let (ax, ay) = if self.pixel_is_point() {
            (ax + 0.5 * bx - 0.5, ay + 0.5 * by - 0.5)
        } else {
            (ax, ay)
        };
        let transform = match &self.transform {
            Transform::ScaleTiepoints { scale, tiepoints } => Transform::ScaleTiepoints {
                scale: [scale[0] * bx, scale[1] * by, scale[2]],
                tiepoints: tiepoints
                    .iter()
                    .map(|t| {
                        let mut t = *t;
                        t[0] = remap_axis(t[0], ax, bx);
                        t[1] = remap_axis(t[1], ay, by);
                        t
                    })
                    .collect(),
            },
            Transform::Matrix(m) => {
                let mut m = *m;
                for row in 0..4 {
                    let (mx, my) = (m[row * 4], m[row * 4 + 1]);
                    m[row * 4 + 3] += mx * ax + my * ay;
                    m[row * 4] = mx * bx;
                    m[row * 4 + 1] = my * by;
                }
                Transform::Matrix(m)
            }
        };
        Georef {
            transform,
            ..self.clone()
        }
    }

    /// Model coordinates `(x, y)` of raster coordinates `(i, j)` (pixel-is-area: the outer
    /// corner of pixel `(0, 0)` is `(0, 0)`; pixel-is-point: its centre is).
    pub fn model_xy(&self, i: f64, j: f64) -> [f64; 2] {
        match &self.transform {
            Transform::ScaleTiepoints { scale, tiepoints } => {
                let t = tiepoints.first().copied().unwrap_or([0.0; 6]);
                [(i - t[0]) * scale[0] + t[3], t[4] - (j - t[1]) * scale[1]]
            }
            Transform::Matrix(m) => [m[0] * i + m[1] * j + m[3], m[4] * i + m[5] * j + m[7]],
        }
    }
}

/// A tie point's raster coordinate in the new raster: old `t = a + b * new`.
fn remap_axis(t: f64, a: f64, b: f64) -> f64 {
    if a == 0.0 && b == 1.0 { t } else { (t - a) / b }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn keys(raster_type: u16) -> Vec<u16> {
        vec![
            1,
            1,
            0,
            3,
            1024,
            0,
            1,
            1,
            1025,
            0,
            1,
            raster_type,
            3072,
            0,
            1,
            3857,
        ]
    }

    #[test]
    fn remapping_keeps_the_model_place_of_every_pixel() {
        for raster_type in [1, 2] {
            for transform in [
                Transform::ScaleTiepoints {
                    scale: [30.0, 20.0, 0.0],
                    tiepoints: vec![[2.0, 3.0, 0.0, 1000.0, 5000.0, 0.0]],
                },
                Transform::Matrix([
                    30.0, 0.0, 0.0, 1000.0, 0.0, -20.0, 0.0, 5000.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0,
                    0.0, 1.0,
                ]),
            ] {
                let geo = Georef {
                    transform,
                    geo_keys: keys(raster_type),
                    geo_doubles: Vec::new(),
                    geo_ascii: String::new(),
                };
                assert_eq!(geo.epsg(), Some(3857));
                assert_eq!(geo.remapped([0.0, 1.0], [0.0, 1.0]), geo);
                // New pixel (3, 4) of a window at (5, 7) resampled by 2.5, flipped in y.
                let (ax, bx, ay, by) = (5.0, 2.5, 40.0, -2.5);
                let new = geo.remapped([ax, bx], [ay, by]);
                let centre = |g: &Georef, i: f64, j: f64| {
                    let off = if g.pixel_is_point() { 0.0 } else { 0.5 };
                    g.model_xy(i + off, j + off)
                };
                let old_i = ax + bx * 3.5 - 0.5;
                let old_j = ay + by * 4.5 - 0.5;
                let want = centre(&geo, old_i, old_j);
                let got = centre(&new, 3.0, 4.0);
                assert!(
                    (want[0] - got[0]).abs() < 1e-9 && (want[1] - got[1]).abs() < 1e-9,
                    "{raster_type}: {want:?} vs {got:?}"
                );
            }
        }
    }
}
