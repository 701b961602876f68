//! Helpers shared by the command-line test targets (`cli`, `export`): each uses a subset.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

pub fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_terrasketch"))
}

pub fn run(args: &[&str]) -> Output {
    bin()
        .args(args)
        .output()
        .expect("the terrasketch binary runs")
}

pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

pub fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

/// A valid sketch with one stroke of each kind.
pub const GOOD: &str = r#"{ "format": "terrasketch-sketch", "version": 1,
  "extent_m": [6400.0, 6400.0], "base_elevation_m": 100.0,
  "strokes": [
    { "kind": "ridge", "points": [[800, 3200, 900], [5600, 3300, 1100]], "slope_left_deg": 25, "slope_right_deg": 20, "width_m": 1200, "roughness": 0.5 },
    { "kind": "valley", "points": [[3000, 600, 300], [3100, 2400, 250]] },
    { "kind": "plateau", "points": [[1000, 5200, 600], [2000, 5400, 600]] } ] }"#;

/// Asserts a failed run: non-zero exit, no panic, and the message contains `needle`.
pub fn assert_fails_with(o: &Output, needle: &str) {
    let e = stderr(o);
    assert!(
        !o.status.success(),
        "expected failure, got success; stderr: {e}"
    );
    assert!(!e.contains("panicked"), "panicked: {e}");
    assert!(
        e.to_lowercase().contains(&needle.to_lowercase()),
        "message {e:?} lacks {needle:?}"
    );
}

/// Asserts a refused input: exit status 2, one line of error naming `field`, no output.
pub fn assert_refused(o: &Output, field: &str) {
    assert_fails_with(o, field);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(o));
    let errors: Vec<_> = stderr(o)
        .lines()
        .filter(|l| !l.starts_with("terrasketch: warning"))
        .map(str::to_owned)
        .collect();
    assert_eq!(errors.len(), 1, "one line of error: {}", stderr(o));
    assert!(errors[0].contains(field), "{errors:?} lacks {field:?}");
}

/// Heights of `examples/range.json` solved at `size` samples per side.
pub fn solve_example(dir: &Path, size: usize, ext: &str) -> terrasketch_raster::Heightmap {
    solve_example_with(dir, size, ext, &[])
}

/// [`solve_example`] with more arguments (e.g. `--detail off`).
pub fn solve_example_with(
    dir: &Path,
    size: usize,
    ext: &str,
    extra: &[&str],
) -> terrasketch_raster::Heightmap {
    let out = dir.join(format!("range{size}.{ext}"));
    let size = size.to_string();
    let mut args = vec![
        "solve",
        concat!(env!("CARGO_MANIFEST_DIR"), "/../examples/range.json"),
        "--size",
        &size,
        "-o",
        out.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    let o = run(&args);
    assert!(o.status.success(), "{size}: {}", stderr(&o));
    terrasketch_raster::read_heightmap(&out).unwrap()
}

/// GeoKeys of EPSG:3857 (projected, pixel-is-area) with a citation in the ASCII params.
pub const KEYS_3857: [u16; 20] = [
    1, 1, 0, 4, 1024, 0, 1, 1, 1025, 0, 1, 1, 1026, 34737, 25, 0, 3072, 0, 1, 3857,
];
/// GeoKeys of EPSG:4326 (geographic, pixel-is-point) with the semi-major axis in the doubles.
pub const KEYS_4326: [u16; 20] = [
    1, 1, 0, 4, 1024, 0, 1, 2, 1025, 0, 1, 2, 2048, 0, 1, 4326, 2057, 34736, 1, 0,
];

/// The georeference and no-data tags of a GeoTIFF, read with the `tiff` crate as a GIS would.
#[derive(Debug, PartialEq)]
pub struct GeoTags {
    pub scale: Option<Vec<f64>>,
    pub tiepoints: Option<Vec<f64>>,
    pub matrix: Option<Vec<f64>>,
    pub keys: Vec<u16>,
    pub doubles: Option<Vec<f64>>,
    pub ascii: Option<String>,
    pub nodata: String,
}

pub fn geo_tags(path: &Path) -> (GeoTags, Vec<f32>) {
    use tiff::tags::Tag;
    let file = std::io::BufReader::new(std::fs::File::open(path).unwrap());
    let mut d = tiff::decoder::Decoder::new(file).unwrap();
    let mut f64s = |tag| d.find_tag(tag).unwrap().map(|v| v.into_f64_vec().unwrap());
    let (scale, tiepoints, matrix, doubles) = (
        f64s(Tag::ModelPixelScaleTag),
        f64s(Tag::ModelTiepointTag),
        f64s(Tag::ModelTransformationTag),
        f64s(Tag::GeoDoubleParamsTag),
    );
    let tags = GeoTags {
        scale,
        tiepoints,
        matrix,
        doubles,
        keys: d.get_tag_u16_vec(Tag::GeoKeyDirectoryTag).unwrap(),
        ascii: d
            .find_tag(Tag::GeoAsciiParamsTag)
            .unwrap()
            .map(|v| v.into_string().unwrap()),
        nodata: d.get_tag_ascii_string(Tag::GdalNodata).unwrap(),
    };
    let data = match d.read_image().unwrap() {
        tiff::decoder::DecodingResult::F32(v) => v,
        tiff::decoder::DecodingResult::I16(v) => v.into_iter().map(f32::from).collect(),
        other => panic!("{other:?}"),
    };
    (tags, data)
}

/// An `n x n` int16 GeoTIFF of a tilted valley with one no-data cell at row 10, column 20.
pub fn write_gis_tiff(
    path: &Path,
    n: usize,
    keys: &[u16],
    transform: &[(tiff::tags::Tag, Vec<f64>)],
) {
    use tiff::tags::Tag;
    let heights: Vec<i16> = (0..n * n)
        .map(|i| {
            let (x, y) = ((i % n) as f64, (i / n) as f64);
            if (x, y) == (20.0, 10.0) {
                -9999
            } else {
                (400.0 + 3.0 * y + 0.08 * (x - 32.0).powi(2) + 6.0 * (0.4 * x).sin()) as i16
            }
        })
        .collect();
    let mut bytes = std::io::Cursor::new(Vec::new());
    let mut encoder = tiff::encoder::TiffEncoder::new(&mut bytes).unwrap();
    let mut image = encoder
        .new_image::<tiff::encoder::colortype::GrayI16>(n as u32, n as u32)
        .unwrap();
    for (tag, values) in transform {
        image.encoder().write_tag(*tag, &values[..]).unwrap();
    }
    let e = image.encoder();
    e.write_tag(Tag::GeoKeyDirectoryTag, keys).unwrap();
    if keys == KEYS_3857 {
        e.write_tag(Tag::GeoAsciiParamsTag, "WGS 84 / Pseudo-Mercator|")
            .unwrap();
    } else {
        e.write_tag(Tag::GeoDoubleParamsTag, &[6_378_137.0][..])
            .unwrap();
    }
    e.write_tag(Tag::GdalNodata, "-9999").unwrap();
    image.write_data(&heights).unwrap();
    std::fs::write(path, bytes.into_inner()).unwrap();
}
