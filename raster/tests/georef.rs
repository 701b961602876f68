//! GeoTIFF georeference: files made with the `tiff` crate as a GIS tool writes them (EPSG:3857
//! with pixel scale and tie point, EPSG:4326 with a model transformation and pixel-is-point,
//! south-up rows, GDAL_NODATA) read with their CRS, transform and no-data value, and written
//! back with the same.

mod common;

use std::io::Cursor;
use std::path::Path;

use common::ScratchDir;
use terrasketch_raster::{
    Georef, HorizontalUnits, RasterError, ReadOptions, SourceFormat, Transform, WriteOptions,
    read_raster, write_heightmap_with,
};
use tiff::decoder::Decoder;
use tiff::encoder::{TiffEncoder, colortype};
use tiff::tags::Tag;

const W: u32 = 6;
const H: u32 = 4;
const NODATA: i16 = -9999;

/// GeoKeys of EPSG:3857 (projected, pixel-is-area, metres) with a citation in the ASCII params.
const KEYS_3857: [u16; 20] = [
    1, 1, 0, 4, //
    1024, 0, 1, 1, // projected
    1025, 0, 1, 1, // pixel is area
    1026, 34737, 25, 0, // GTCitationGeoKey in GeoAsciiParams
    3072, 0, 1, 3857, // ProjectedCSTypeGeoKey
];
const ASCII_3857: &str = "WGS 84 / Pseudo-Mercator|";

/// GeoKeys of EPSG:4326 (geographic, pixel-is-point, degrees) with the semi-major axis in the
/// double params.
const KEYS_4326: [u16; 20] = [
    1, 1, 0, 4, //
    1024, 0, 1, 2, // geographic
    1025, 0, 1, 2, // pixel is point
    2048, 0, 1, 4326, // GeographicTypeGeoKey
    2057, 34736, 1, 0, // GeogSemiMajorAxisGeoKey in GeoDoubleParams
];

/// Heights `100 + 10 * row + column`, with the no-data value at (1, 2) in file order.
fn heights() -> Vec<i16> {
    (0..(W * H) as i16)
        .map(|i| {
            if i == W as i16 + 2 {
                NODATA
            } else {
                100 + 10 * (i / W as i16) + i % W as i16
            }
        })
        .collect()
}

/// Writes an int16 GeoTIFF with the given tags, as a GIS tool would.
fn write_gis_tiff(path: &Path, keys: &[u16], write_transform: impl Fn(&mut Writer)) {
    let mut bytes = Cursor::new(Vec::new());
    let mut encoder = TiffEncoder::new(&mut bytes).unwrap();
    let mut image = encoder.new_image::<colortype::GrayI16>(W, H).unwrap();
    let directory = image.encoder();
    write_transform(&mut Writer(directory));
    image
        .encoder()
        .write_tag(Tag::GeoKeyDirectoryTag, keys)
        .unwrap();
    image
        .encoder()
        .write_tag(Tag::GdalNodata, NODATA.to_string().as_str())
        .unwrap();
    image.write_data(&heights()).unwrap();
    std::fs::write(path, bytes.into_inner()).unwrap();
}

/// Writes tags into the image directory being built.
struct Writer<'a, 'b>(
    &'a mut tiff::encoder::DirectoryEncoder<
        'b,
        &'b mut Cursor<Vec<u8>>,
        tiff::encoder::TiffKindStandard,
    >,
);

fn read(path: &Path) -> terrasketch_raster::Raster {
    read_raster(path, &ReadOptions::default()).unwrap()
}

/// Writes `raster` back with its georeference and no-data value and checks that every tag a
/// GIS reads is the same, then that it reads back the same.
fn assert_written_back_unchanged(
    dir: &ScratchDir,
    name: &str,
    raster: &terrasketch_raster::Raster,
) {
    let georef = raster.source.georef.as_ref().unwrap();
    let mut map = raster.map.clone();
    for (height_m, hole) in map.data.iter_mut().zip(&raster.nodata_mask) {
        if *hole {
            *height_m = f32::from(NODATA);
        }
    }
    let out = dir.join(name);
    let options = WriteOptions {
        georef: Some(georef),
        nodata: raster.source.nodata,
        ..WriteOptions::default()
    };
    write_heightmap_with(&out, &map, &options).unwrap();
    let back = read(&out);
    assert_eq!(back.source.georef.as_ref(), Some(georef), "{name}");
    assert_eq!(back.source.nodata, raster.source.nodata, "{name}");
    assert_eq!(back.nodata_mask, raster.nodata_mask, "{name}");
    assert_eq!(back.map, raster.map, "{name}: heights and cell size");
}

#[test]
fn epsg_3857_scale_and_tiepoint_round_trip() {
    let dir = ScratchDir::new("georef-3857");
    let path = dir.join("mercator.tif");
    let tie = [0.0, 0.0, 0.0, 951_000.0, 6_003_000.0, 0.0];
    write_gis_tiff(&path, &KEYS_3857, |w| {
        w.0.write_tag(Tag::ModelPixelScaleTag, &[30.0, 30.0, 0.0][..])
            .unwrap();
        w.0.write_tag(Tag::ModelTiepointTag, &tie[..]).unwrap();
        w.0.write_tag(Tag::GeoAsciiParamsTag, ASCII_3857).unwrap();
    });
    let raster = read(&path);
    let geo = raster.source.georef.as_ref().unwrap();
    assert_eq!(geo.epsg(), Some(3857));
    assert_eq!(
        geo.transform,
        Transform::ScaleTiepoints {
            scale: [30.0, 30.0, 0.0],
            tiepoints: vec![tie]
        }
    );
    assert_eq!(geo.geo_keys, KEYS_3857);
    assert_eq!(geo.geo_ascii, ASCII_3857);
    assert_eq!(raster.source.nodata, Some(-9999.0));
    assert_eq!(raster.source.horizontal_units, HorizontalUnits::Metres);
    assert_eq!(raster.map.cell_size_m, [30.0, 30.0]);
    assert_eq!(raster.filled_cells(), 1);
    assert!(raster.nodata_mask[W as usize + 2]);
    assert_eq!(raster.map.data[0], 100.0);
    assert_written_back_unchanged(&dir, "mercator_out.tif", &raster);
}

#[test]
fn epsg_4326_transformation_and_pixel_is_point_round_trip() {
    let dir = ScratchDir::new("georef-4326");
    let path = dir.join("lonlat.tif");
    let step = 1.0 / 1200.0;
    let matrix = [
        step, 0.0, 0.0, 8.5, //
        0.0, -step, 0.0, 47.4, //
        0.0, 0.0, 0.0, 0.0, //
        0.0, 0.0, 0.0, 1.0,
    ];
    write_gis_tiff(&path, &KEYS_4326, |w| {
        w.0.write_tag(Tag::ModelTransformationTag, &matrix[..])
            .unwrap();
        w.0.write_tag(Tag::GeoDoubleParamsTag, &[6_378_137.0][..])
            .unwrap();
    });
    let raster = read(&path);
    let geo = raster.source.georef.as_ref().unwrap();
    assert_eq!(geo.epsg(), Some(4326));
    assert!(geo.pixel_is_point());
    assert_eq!(geo.transform, Transform::Matrix(matrix));
    assert_eq!(geo.geo_doubles, [6_378_137.0]);
    assert_eq!(raster.source.horizontal_units, HorizontalUnits::Degrees);
    // Centre latitude 47.4 - 1.5 steps (pixel-is-point: centres of rows 0..3).
    let lat: f64 = 47.4 - 1.5 * step;
    assert!((raster.source.centre_lat_deg.unwrap() - lat).abs() < 1e-12);
    let want_x = step * lat.to_radians().cos() * 111_320.0;
    assert!((raster.map.cell_size_m[0] - want_x).abs() < 1e-9);
    assert_written_back_unchanged(&dir, "lonlat_out.tif", &raster);
}

#[test]
fn south_up_rows_flip_with_their_transform() {
    let dir = ScratchDir::new("georef-south-up");
    let path = dir.join("south_up.tif");
    // Negative y scale: row 0 is the south edge at y = 1000.
    write_gis_tiff(&path, &KEYS_3857, |w| {
        w.0.write_tag(Tag::ModelPixelScaleTag, &[10.0, -10.0, 0.0][..])
            .unwrap();
        w.0.write_tag(
            Tag::ModelTiepointTag,
            &[0.0, 0.0, 0.0, 500.0, 1000.0, 0.0][..],
        )
        .unwrap();
    });
    let raster = read(&path);
    assert!(raster.source.rows_flipped);
    let geo = raster.source.georef.as_ref().unwrap();
    // Row 0 of the map is now the north row (file row 3): its top edge is y = 1040.
    assert_eq!(geo.model_xy(0.0, 0.0), [500.0, 1040.0]);
    assert_eq!(geo.model_xy(0.0, f64::from(H)), [500.0, 1000.0]);
    assert_eq!(raster.map.data[0], 130.0, "file row 3 first");
    assert_written_back_unchanged(&dir, "north_up.tif", &raster);
    // What a GIS sees in the written file: positive y scale, the same tie point model
    // coordinates now at raster row 4, so the north-west corner is at y = 1040.
    let bytes = std::fs::read(dir.join("north_up.tif")).unwrap();
    let mut decoder = Decoder::new(Cursor::new(bytes)).unwrap();
    let scale = decoder.get_tag_f64_vec(Tag::ModelPixelScaleTag).unwrap();
    assert_eq!(scale, [10.0, 10.0, 0.0]);
    let tie = decoder.get_tag_f64_vec(Tag::ModelTiepointTag).unwrap();
    assert_eq!(tie, [0.0, 4.0, 0.0, 500.0, 1000.0, 0.0]);
    assert_eq!(tie[4] + tie[1] * scale[1], 1040.0);
    assert_eq!(
        decoder.get_tag_ascii_string(Tag::GdalNodata).unwrap(),
        "-9999"
    );
}

#[test]
fn a_window_keeps_its_place() {
    let geo = Georef {
        transform: Transform::ScaleTiepoints {
            scale: [30.0, 30.0, 0.0],
            tiepoints: vec![[0.0, 0.0, 0.0, 951_000.0, 6_003_000.0, 0.0]],
        },
        geo_keys: KEYS_3857.to_vec(),
        geo_doubles: Vec::new(),
        geo_ascii: ASCII_3857.into(),
    };
    // Columns 2.., rows 1.. at half the resolution.
    let window = geo.remapped([2.0, 2.0], [1.0, 2.0]);
    assert_eq!(window.model_xy(0.0, 0.0), [951_060.0, 6_002_970.0]);
    assert_eq!(window.model_xy(1.0, 1.0), [951_120.0, 6_002_910.0]);
    assert_eq!(window.epsg(), Some(3857));
}

#[test]
fn a_failed_read_is_one_error_naming_the_format() {
    let dir = ScratchDir::new("georef-errors");
    let cases = [
        ("notes.tif", b"hello, not a raster".as_slice(), "as GeoTIFF"),
        ("notes.png", b"hello, not a raster".as_slice(), "as PNG"),
        ("notes.exr", b"hello, not a raster".as_slice(), "as OpenEXR"),
        (
            "notes.asc",
            b"hello, not a raster".as_slice(),
            "as ESRI ASCII grid",
        ),
        (
            "N10E020.hgt",
            b"hello, not a raster".as_slice(),
            "as SRTM .hgt",
        ),
        ("notes.r16", b"hello, not a raster".as_slice(), "as R16"),
        // Content wins over the extension: TIFF bytes named .png fail as GeoTIFF.
        ("tiff.png", b"II*\0\x08\0\0\0\0\0".as_slice(), "as GeoTIFF"),
    ];
    for (name, bytes, format) in cases {
        let path = dir.join(name);
        std::fs::write(&path, bytes).unwrap();
        let error = read_raster(&path, &ReadOptions::default()).unwrap_err();
        let message = error.to_string();
        assert!(
            matches!(error, RasterError::Decode { .. }),
            "{name}: {message}"
        );
        assert!(
            message.contains(format) && message.contains(name),
            "{message}"
        );
        assert!(!message.contains('\n'), "one line: {message:?}");
    }
    let path = dir.join("notes.txt");
    std::fs::write(&path, "hello").unwrap();
    let error = read_raster(&path, &ReadOptions::default()).unwrap_err();
    assert!(
        matches!(error, RasterError::UnknownFormat { .. }),
        "{error}"
    );
    // A grey PNG with no cell size anywhere: the one error says how to give one.
    let grey = dir.join("grey.png");
    let mut bytes = Vec::new();
    let mut encoder = png::Encoder::new(&mut bytes, 2, 2);
    encoder.set_color(png::ColorType::Grayscale);
    encoder.set_depth(png::BitDepth::Eight);
    let mut writer = encoder.write_header().unwrap();
    writer.write_image_data(&[1, 2, 3, 4]).unwrap();
    writer.finish().unwrap();
    std::fs::write(&grey, bytes).unwrap();
    let error = read_raster(&grey, &ReadOptions::default()).unwrap_err();
    assert!(
        matches!(error, RasterError::MissingCellSize { .. }),
        "{error}"
    );
    assert!(error.to_string().contains("as PNG"), "{error}");
    assert_eq!(
        read_raster(
            &grey,
            &ReadOptions {
                unit_cells_when_absent: true,
                ..Default::default()
            }
        )
        .unwrap()
        .source
        .format,
        SourceFormat::GreyPng
    );
}

#[test]
fn absurd_georeference_and_headers_are_refused_quickly() {
    let dir = ScratchDir::new("georef-hostile");
    // A non-finite tie point.
    let path = dir.join("nan.tif");
    write_gis_tiff(&path, &KEYS_3857, |w| {
        w.0.write_tag(Tag::ModelPixelScaleTag, &[30.0, 30.0, 0.0][..])
            .unwrap();
        w.0.write_tag(
            Tag::ModelTiepointTag,
            &[0.0, 0.0, 0.0, f64::NAN, 0.0, 0.0][..],
        )
        .unwrap();
    });
    let error = read_raster(&path, &ReadOptions::default()).unwrap_err();
    assert!(matches!(error, RasterError::Decode { .. }), "{error}");
    assert!(error.to_string().contains("as GeoTIFF"), "{error}");
    // An ASCII grid header claiming 9 * 10^8 cells in a few bytes: refused before allocating.
    let path = dir.join("huge.asc");
    std::fs::write(
        &path,
        "ncols 30000\nnrows 30000\nxllcorner 0\nyllcorner 0\ncellsize 1\n1 2 3\n",
    )
    .unwrap();
    let started = std::time::Instant::now();
    let error = read_raster(&path, &ReadOptions::default()).unwrap_err();
    assert!(error.to_string().contains("as ESRI ASCII grid"), "{error}");
    assert!(started.elapsed().as_secs_f64() < 0.5);
    // A PNG sidecar that is not a cell-size file.
    let png = dir.join("side.png");
    let mut bytes = Vec::new();
    let mut encoder = png::Encoder::new(&mut bytes, 2, 1);
    encoder.set_color(png::ColorType::Grayscale);
    encoder.set_depth(png::BitDepth::Sixteen);
    let mut writer = encoder.write_header().unwrap();
    writer.write_image_data(&[0, 1, 0, 2]).unwrap();
    writer.finish().unwrap();
    std::fs::write(&png, bytes).unwrap();
    std::fs::write(dir.join("side.json"), vec![b' '; (1 << 20) + 1]).unwrap();
    let error = read_raster(&png, &ReadOptions::default()).unwrap_err();
    assert!(error.to_string().contains("over 1 MiB"), "{error}");
    std::fs::write(dir.join("side.json"), r#"{"cell_size_m": -3}"#).unwrap();
    assert!(read_raster(&png, &ReadOptions::default()).is_err());
    std::fs::write(dir.join("side.json"), r#"{"cell_size_m": 2.5}"#).unwrap();
    let raster = read_raster(&png, &ReadOptions::default()).unwrap();
    assert_eq!(
        (raster.map.cell_size_m, raster.map.data.clone()),
        ([2.5, 2.5], vec![1.0, 2.0])
    );
}

#[test]
fn a_mirrored_orientation_mirrors_the_transform_too() {
    let dir = ScratchDir::new("georef-orientation");
    let path = dir.join("bottom_left.tif");
    // Orientation 4 (rows stored bottom to top) with a north-up transform of the stored rows,
    // as GDAL reads it: stored row 0 is the north row either way.
    write_gis_tiff(&path, &KEYS_3857, |w| {
        w.0.write_tag(Tag::Orientation, 4u16).unwrap();
        w.0.write_tag(Tag::ModelPixelScaleTag, &[10.0, 10.0, 0.0][..])
            .unwrap();
        w.0.write_tag(
            Tag::ModelTiepointTag,
            &[0.0, 0.0, 0.0, 500.0, 1000.0, 0.0][..],
        )
        .unwrap();
    });
    let raster = read(&path);
    let geo = raster.source.georef.as_ref().unwrap();
    assert_eq!(geo.model_xy(0.0, 0.0), [500.0, 1000.0]);
    assert_eq!(raster.map.data[0], 100.0, "stored row 0 is row 0");
    assert_written_back_unchanged(&dir, "oriented_out.tif", &raster);
}
