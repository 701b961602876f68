//! Files written by the tests: `.hgt`, `.asc`, PNG and GeoTIFF variants with known content and
//! holes, and hostile headers that must be refused before allocation.

mod common;

use std::path::Path;
use std::time::Instant;

use common::{ScratchDir, crc32, tiff_bytes, tiff_payload_offset, write_png};
use terrasketch_synthesis::{
    DemError, DemFormat, HorizontalUnits, LoadOptions, load_dem, load_exemplar_dir,
};
use tiff::encoder::{TiffEncoder, colortype};
use tiff::tags::Tag;

fn load(path: &Path) -> Result<terrasketch_synthesis::Dem, DemError> {
    load_dem(path, &LoadOptions::default())
}

#[test]
fn hgt_with_voids_loads_north_up_and_fills_them() {
    let scratch = ScratchDir::new("hgt");
    let n = 1201;
    let value = |x: usize, y: usize| (1000 + x / 4) as i16 - (y / 8) as i16;
    let mut bytes = Vec::with_capacity(n * n * 2);
    for y in 0..n {
        for x in 0..n {
            let void = (500..510).contains(&x) && (300..306).contains(&y);
            let h = if void { -32768 } else { value(x, y) };
            bytes.extend_from_slice(&h.to_be_bytes());
        }
    }
    let path = scratch.path("S10E020.hgt");
    std::fs::write(&path, &bytes).unwrap();
    let dem = load(&path).unwrap();
    assert_eq!((dem.width, dem.height), (n, n));
    assert_eq!(dem.source.format, DemFormat::SrtmHgt);
    assert_eq!(dem.filled_nodata, 60);
    assert_eq!(
        dem.at(0, 0),
        f32::from(value(0, 0)),
        "row 0 is the first (northern) row"
    );
    assert_eq!(dem.at(1200, 1200), f32::from(value(1200, 1200)));
    // Tile S10: 10..9 S, centre 9.5 S.
    let lat = -9.5f64;
    let expected = [
        lat.to_radians().cos() * 111_320.0 / 1200.0,
        110_574.0 / 1200.0,
    ];
    assert!(
        (dem.cell_size_m[0] - expected[0]).abs() < 1e-6
            && (dem.cell_size_m[1] - expected[1]).abs() < 1e-6
    );
    for y in 300..306 {
        for x in 500..510 {
            let (got, want) = (dem.at(x, y), f32::from(value(x, y)));
            assert!((got - want).abs() < 4.0, "filled ({x},{y}) {got} vs {want}");
        }
    }
    assert!(
        dem.heights_m
            .iter()
            .all(|&h| h.is_finite() && h != -32768.0)
    );

    let short = scratch.path("N10E020.hgt");
    std::fs::write(&short, &bytes[..bytes.len() - 2]).unwrap();
    assert!(matches!(load(&short), Err(DemError::Decode { .. })));
    let unnamed = scratch.path("tile.hgt");
    std::fs::write(&unnamed, &bytes).unwrap();
    assert!(matches!(
        load(&unnamed),
        Err(DemError::MissingCellSize { .. })
    ));
    let with_cell = LoadOptions {
        cell_size_m: Some(30.0),
        ..LoadOptions::default()
    };
    assert_eq!(
        load_dem(&unnamed, &with_cell).unwrap().cell_size_m,
        [30.0, 30.0]
    );
}

const ASC: &str = "ncols 5\nNROWS 4\nxllcorner 1000.0\nyllcorner 2000.0\ncellsize 30\nNODATA_value -9999\n\
    10 11 12 13 14\n20 21 -9999 23 24\n30 31 32 33 34\n40 41 42 43 44\n";

#[test]
fn ascii_grid_loads_with_holes_filled() {
    let scratch = ScratchDir::new("asc");
    let path = scratch.path("small.asc");
    std::fs::write(&path, ASC).unwrap();
    let dem = load(&path).unwrap();
    assert_eq!((dem.width, dem.height), (5, 4));
    assert_eq!(dem.cell_size_m, [30.0, 30.0]);
    assert_eq!(dem.filled_nodata, 1);
    assert_eq!(dem.source.nodata, Some(-9999.0));
    assert_eq!((dem.at(0, 0), dem.at(4, 3)), (10.0, 44.0));
    let filled = dem.at(2, 1);
    assert!((15.0..=35.0).contains(&filled), "filled {filled}");

    // The same numbers as degrees: converted at the centre latitude (yllcorner + 2 rows).
    let deg = scratch.path("deg.asc");
    std::fs::write(
        &deg,
        ASC.replace("2000.0", "45.0")
            .replace("cellsize 30", "cellsize 0.5"),
    )
    .unwrap();
    let opts = LoadOptions {
        asc_units: HorizontalUnits::Degrees,
        ..LoadOptions::default()
    };
    let dem = load_dem(&deg, &opts).unwrap();
    assert_eq!(dem.source.centre_lat_deg, Some(46.0));
    assert!((dem.cell_size_m[0] - 0.5 * 46f64.to_radians().cos() * 111_320.0).abs() < 1e-6);
    assert!((dem.cell_size_m[1] - 0.5 * 110_574.0).abs() < 1e-6);
}

#[test]
fn bad_ascii_grids_are_errors() {
    let scratch = ScratchDir::new("asc-bad");
    let cases = [
        ("truncated", ASC.replace("40 41 42 43 44\n", "40 41")),
        ("extra", format!("{ASC}99\n")),
        ("word", ASC.replace("33", "abc")),
        ("no-cellsize", ASC.replace("cellsize 30\n", "")),
        (
            "all-nodata",
            "ncols 2\nnrows 1\nxllcorner 0\nyllcorner 0\ncellsize 1\nnodata_value -1\n-1 -1\n"
                .into(),
        ),
        ("header-only", "ncols 2\nnrows 2\n".into()),
    ];
    for (name, text) in cases {
        let path = scratch.path(&format!("{name}.asc"));
        std::fs::write(&path, text).unwrap();
        let result = load(&path);
        match name {
            "all-nodata" => assert!(
                matches!(result, Err(DemError::AllNoData { .. })),
                "{result:?}"
            ),
            _ => assert!(
                matches!(result, Err(DemError::Decode { .. })),
                "{name}: {result:?}"
            ),
        }
    }
}

#[test]
fn grey_png_needs_a_cell_size() {
    let scratch = ScratchDir::new("png16");
    let path = scratch.path("heights.png");
    let (w, h) = (8u32, 6u32);
    let data: Vec<u8> = (0..w * h)
        .flat_map(|i| (1000 + 7 * i as u16).to_be_bytes())
        .collect();
    write_png(
        &path,
        w,
        h,
        png::ColorType::Grayscale,
        png::BitDepth::Sixteen,
        &data,
    );
    let err = load(&path).unwrap_err();
    assert!(matches!(err, DemError::MissingCellSize { .. }), "{err:?}");
    assert!(err.to_string().contains("cell_size_m"), "{err}");

    let opts = LoadOptions {
        cell_size_m: Some(10.0),
        png_metres_per_level: 0.5,
        ..LoadOptions::default()
    };
    let dem = load_dem(&path, &opts).unwrap();
    assert_eq!(
        (dem.width, dem.height, dem.cell_size_m),
        (8, 6, [10.0, 10.0])
    );
    assert_eq!(
        (dem.at(0, 0), dem.at(1, 0), dem.at(0, 1)),
        (500.0, 503.5, 528.0)
    );
    assert_eq!(dem.source.sample_type, "uint16");

    std::fs::write(
        scratch.path("heights.json"),
        r#"{"cell_size_m": 2.5, "note": "x"}"#,
    )
    .unwrap();
    assert_eq!(load(&path).unwrap().cell_size_m, [2.5, 2.5]);
    std::fs::write(scratch.path("heights.json"), r#"{"cell": 2.5}"#).unwrap();
    assert!(matches!(load(&path), Err(DemError::Decode { .. })));
}

#[test]
fn terrarium_is_decoded_when_named_or_asked() {
    let scratch = ScratchDir::new("terrarium");
    // h = R * 256 + G + B / 256 - 32768: 100.5 m and -20 m.
    let pixels: [[u8; 3]; 2] = [[128, 100, 128], [127, 236, 0]];
    let data: Vec<u8> = pixels.iter().flatten().copied().collect();
    let plain = scratch.path("tile.png");
    write_png(
        &plain,
        2,
        1,
        png::ColorType::Rgb,
        png::BitDepth::Eight,
        &data,
    );
    let with_cell = LoadOptions {
        cell_size_m: Some(5.0),
        ..LoadOptions::default()
    };
    assert!(matches!(
        load_dem(&plain, &with_cell),
        Err(DemError::Decode { .. })
    ));
    let asked = LoadOptions {
        terrarium: true,
        ..with_cell.clone()
    };
    let dem = load_dem(&plain, &asked).unwrap();
    assert_eq!(dem.heights_m, [100.5, -20.0]);
    let named = scratch.path("my_Terrarium_tile.png");
    std::fs::copy(&plain, &named).unwrap();
    assert_eq!(
        load_dem(&named, &with_cell).unwrap().source.format,
        DemFormat::TerrariumPng
    );
}

/// GeoTIFF tags for [`write_geotiff`].
struct Geo<'a> {
    scale: [f64; 3],
    tiepoint: [f64; 6],
    keys: Option<&'a [u16]>,
    nodata: Option<&'a str>,
}

/// Writes a one-band GeoTIFF with the `tiff` encoder plus GeoTIFF tags.
fn write_geotiff<C: colortype::ColorType>(
    path: &Path,
    size: (u32, u32),
    data: &[C::Inner],
    encoder: impl FnOnce(TiffEncoder<std::fs::File>) -> TiffEncoder<std::fs::File>,
    geo: Geo,
) where
    [C::Inner]: tiff::encoder::TiffValue,
{
    let mut tiff = encoder(TiffEncoder::new(std::fs::File::create(path).unwrap()).unwrap());
    let mut image = tiff.new_image::<C>(size.0, size.1).unwrap();
    let dir = image.encoder();
    dir.write_tag(Tag::ModelPixelScaleTag, &geo.scale[..])
        .unwrap();
    dir.write_tag(Tag::ModelTiepointTag, &geo.tiepoint[..])
        .unwrap();
    if let Some(keys) = geo.keys {
        dir.write_tag(Tag::GeoKeyDirectoryTag, keys).unwrap();
    }
    if let Some(nodata) = geo.nodata {
        dir.write_tag(Tag::GdalNodata, nodata).unwrap();
    }
    image.write_data(data).unwrap();
}

/// GeoKeys: version 1.1.0, 2 keys: GTModelType = geographic, GeographicType = EPSG:4326.
const GEOGRAPHIC_KEYS: [u16; 12] = [1, 1, 0, 2, 1024, 0, 1, 2, 2048, 0, 1, 4326];

#[test]
fn geotiff_variants_predictor_compression_sample_types_and_flip() {
    use tiff::encoder::{Compression, DeflateLevel};
    use tiff::tags::Predictor;
    let scratch = ScratchDir::new("geotiff");
    let (w, h) = (37u32, 23u32);
    let value = |i: usize| 300.0 + (i % w as usize) as f32 * 3.0 - (i / w as usize) as f32 * 2.0;
    let n = (w * h) as usize;
    let hole = 5 * w as usize + 7;

    // int16, deflate + horizontal predictor, geographic, no-data -32767, south-up (negative y scale).
    let i16s: Vec<i16> = (0..n)
        .map(|i| if i == hole { -32767 } else { value(i) as i16 })
        .collect();
    let path = scratch.path("south_up.tif");
    let deflate = |t: TiffEncoder<_>| {
        t.with_compression(Compression::Deflate(DeflateLevel::Balanced))
            .with_predictor(Predictor::Horizontal)
    };
    write_geotiff::<colortype::GrayI16>(
        &path,
        (w, h),
        &i16s,
        deflate,
        Geo {
            scale: [1.0 / 1200.0, -1.0 / 1200.0, 0.0],
            tiepoint: [0.0, 0.0, 0.0, 10.0, 45.0, 0.0],
            keys: Some(&GEOGRAPHIC_KEYS),
            nodata: Some("-32767"),
        },
    );
    let dem = load(&path).unwrap();
    assert_eq!(
        dem.source.format,
        DemFormat::GeoTiff {
            compression: "deflate",
            tiled: false,
            predictor: true
        }
    );
    assert!(dem.source.rows_flipped);
    assert_eq!(dem.filled_nodata, 1);
    assert_eq!(
        dem.at(0, 0),
        value((h as usize - 1) * w as usize),
        "last stored row is north"
    );
    // Stored south-up from 45 N: the centre is h/2 rows north of it.
    let lat = 45.0 + f64::from(h) / 2.0 / 1200.0;
    assert!((dem.source.centre_lat_deg.unwrap() - lat).abs() < 1e-9);
    assert!((dem.cell_size_m[1] - 110_574.0 / 1200.0).abs() < 1e-6);

    // uint16, LZW + predictor, projected by the pixel-scale rule (no keys), no no-data.
    let u16s: Vec<u16> = (0..n).map(|i| value(i) as u16).collect();
    let path = scratch.path("u16.tif");
    let lzw = |t: TiffEncoder<_>| {
        t.with_compression(Compression::Lzw)
            .with_predictor(Predictor::Horizontal)
    };
    write_geotiff::<colortype::Gray16>(
        &path,
        (w, h),
        &u16s,
        lzw,
        Geo {
            scale: [10.0, 10.0, 0.0],
            tiepoint: [0.0; 6],
            keys: None,
            nodata: None,
        },
    );
    let dem = load(&path).unwrap();
    assert_eq!(
        (dem.cell_size_m, dem.filled_nodata, dem.source.sample_type),
        ([10.0, 10.0], 0, "uint16")
    );
    assert_eq!(
        dem.heights_m,
        u16s.iter().map(|&v| f32::from(v)).collect::<Vec<_>>()
    );

    // float32 with NaN holes and a no-data value, no CRS and a tiny scale: degrees, with a warning.
    let f32s: Vec<f32> = (0..n)
        .map(|i| match i {
            3 => f32::NAN,
            9 => -9999.0,
            _ => value(i) + 0.25,
        })
        .collect();
    let path = scratch.path("f32.tif");
    write_geotiff::<colortype::Gray32Float>(
        &path,
        (w, h),
        &f32s,
        |t| t,
        Geo {
            scale: [0.001, 0.001, 0.0],
            tiepoint: [0.0, 0.0, 0.0, 5.0, 60.0, 0.0],
            keys: None,
            nodata: Some("-9999"),
        },
    );
    let dem = load(&path).unwrap();
    assert_eq!((dem.filled_nodata, dem.source.sample_type), (2, "float32"));
    assert_eq!(dem.source.horizontal_units, HorizontalUnits::Degrees);
    assert_eq!(dem.source.warnings.len(), 1, "{:?}", dem.source.warnings);
    assert_eq!(dem.at(1, 1), value(w as usize + 1) + 0.25);
    let lat = 60.0 - f64::from(h) / 2.0 * 0.001;
    assert!((dem.cell_size_m[0] - 0.001 * lat.to_radians().cos() * 111_320.0).abs() < 1e-6);
}

#[test]
fn all_nodata_tiff_is_an_error() {
    let scratch = ScratchDir::new("tiff-empty");
    let path = scratch.path("empty.tif");
    write_geotiff::<colortype::GrayI16>(
        &path,
        (4, 4),
        &[0i16; 16],
        |t| t,
        Geo {
            scale: [25.0, 25.0, 0.0],
            tiepoint: [0.0; 6],
            keys: None,
            nodata: Some("0"),
        },
    );
    assert!(matches!(load(&path), Err(DemError::AllNoData { .. })));
}

#[test]
fn huge_tiff_header_is_refused_before_allocating() {
    let scratch = ScratchDir::new("tiff-huge");
    let side = 1_000_000u32;
    // A complete, consistent header (one strip) claiming 10^6 x 10^6 int16 cells; no pixel data.
    let entries = [
        (256, 4, 1, side),                    // ImageWidth
        (257, 4, 1, side),                    // ImageLength
        (258, 3, 1, 16),                      // BitsPerSample
        (259, 3, 1, 1),                       // Compression: none
        (262, 3, 1, 1),                       // Photometric: BlackIsZero
        (273, 4, 1, tiff_payload_offset(11)), // StripOffsets
        (277, 3, 1, 1),                       // SamplesPerPixel
        (278, 4, 1, side),                    // RowsPerStrip
        (279, 4, 1, u32::MAX),                // StripByteCounts
        (284, 3, 1, 1),                       // PlanarConfiguration
        (339, 3, 1, 2),                       // SampleFormat: int
    ];
    let path = scratch.path("huge.tif");
    std::fs::write(&path, tiff_bytes(&entries, &[0; 64])).unwrap();
    let started = Instant::now();
    match load(&path) {
        Err(DemError::TooLarge { width, height, .. }) => {
            assert_eq!((width, height), (1_000_000, 1_000_000))
        }
        other => panic!("expected TooLarge, got {other:?}"),
    }
    assert!(
        started.elapsed().as_secs_f64() < 0.5,
        "{:?}",
        started.elapsed()
    );

    // One side over the limit is refused too, even when the cell count would fit.
    let mut wide = entries;
    wide[0].3 = 70_000;
    wide[1].3 = 2;
    wide[7].3 = 2;
    std::fs::write(&path, tiff_bytes(&wide, &[0; 64])).unwrap();
    assert!(matches!(load(&path), Err(DemError::TooLarge { .. })));
}

#[test]
fn huge_tag_value_count_is_refused_quickly() {
    let scratch = ScratchDir::new("tiff-tag");
    let payload_at = tiff_payload_offset(12);
    let entries = [
        (256, 3, 1, 2),                      // ImageWidth
        (257, 3, 1, 2),                      // ImageLength
        (258, 3, 1, 16),                     // BitsPerSample
        (259, 3, 1, 1),                      // Compression: none
        (262, 3, 1, 1),                      // Photometric: BlackIsZero
        (273, 4, 1, payload_at),             // StripOffsets
        (277, 3, 1, 1),                      // SamplesPerPixel
        (278, 3, 1, 2),                      // RowsPerStrip
        (279, 4, 1, 8),                      // StripByteCounts
        (284, 3, 1, 1),                      // PlanarConfiguration
        (339, 3, 1, 2),                      // SampleFormat: int
        (42113, 2, 0x7000_0000, payload_at), // GDAL_NODATA claiming 1.8 GB of text
    ];
    let path = scratch.path("tag.tif");
    std::fs::write(&path, tiff_bytes(&entries, &[1, 0, 2, 0, 3, 0, 4, 0])).unwrap();
    let started = Instant::now();
    assert!(matches!(load(&path), Err(DemError::Decode { .. })));
    assert!(started.elapsed().as_secs_f64() < 0.5);
    // The same file with a sane GDAL_NODATA count loads.
    let mut sane = entries;
    sane[11] = (42113, 2, 2, u32::from_le_bytes(*b"4\0\0\0"));
    std::fs::write(&path, tiff_bytes(&sane, &[1, 0, 2, 0, 3, 0, 4, 0])).unwrap();
    // Without georeference tags the cell size must be given.
    assert!(matches!(load(&path), Err(DemError::MissingCellSize { .. })));
    let dem = load_dem(
        &path,
        &LoadOptions {
            cell_size_m: Some(1.0),
            ..LoadOptions::default()
        },
    )
    .unwrap();
    assert_eq!((dem.source.nodata, dem.filled_nodata), (Some(4.0), 1));
}

#[test]
fn huge_png_and_ascii_headers_are_refused() {
    let scratch = ScratchDir::new("huge-headers");
    let mut png = b"\x89PNG\r\n\x1a\n".to_vec();
    let mut ihdr = b"IHDR".to_vec();
    ihdr.extend_from_slice(&1_000_000u32.to_be_bytes());
    ihdr.extend_from_slice(&1_000_000u32.to_be_bytes());
    ihdr.extend_from_slice(&[16, 0, 0, 0, 0]); // 16-bit grey
    png.extend_from_slice(&13u32.to_be_bytes());
    png.extend_from_slice(&ihdr);
    png.extend_from_slice(&crc32(&ihdr).to_be_bytes());
    let path = scratch.path("huge.png");
    std::fs::write(&path, &png).unwrap();
    let opts = LoadOptions {
        cell_size_m: Some(1.0),
        ..LoadOptions::default()
    };
    assert!(matches!(
        load_dem(&path, &opts),
        Err(DemError::TooLarge { .. })
    ));

    let path = scratch.path("huge.asc");
    std::fs::write(
        &path,
        "ncols 1000000\nnrows 1000000\nxllcorner 0\nyllcorner 0\ncellsize 1\n1 2 3\n",
    )
    .unwrap();
    let started = Instant::now();
    assert!(matches!(load(&path), Err(DemError::TooLarge { .. })));
    assert!(started.elapsed().as_secs_f64() < 0.5);
}

#[test]
fn unknown_and_mislabelled_files() {
    let scratch = ScratchDir::new("unknown");
    let txt = scratch.path("notes.txt");
    std::fs::write(&txt, "hello").unwrap();
    assert!(matches!(load(&txt), Err(DemError::UnknownFormat { .. })));
    let fake = scratch.path("fake.tif");
    std::fs::write(&fake, "hello").unwrap();
    assert!(matches!(load(&fake), Err(DemError::Decode { .. })));
    let empty = scratch.path("empty.png");
    std::fs::write(&empty, "").unwrap();
    assert!(matches!(load(&empty), Err(DemError::Decode { .. })));
    assert!(matches!(
        load(&scratch.path("missing.asc")),
        Err(DemError::Io { .. })
    ));
    // A content sniff wins over the extension: an ASCII grid named .dem loads.
    let asc = scratch.path("grid.dem");
    std::fs::write(&asc, ASC).unwrap();
    assert_eq!(load(&asc).unwrap().source.format, DemFormat::EsriAsciiGrid);
}

#[test]
fn exemplar_folder_reports_bad_files_and_keeps_good_ones() {
    let scratch = ScratchDir::new("folder");
    std::fs::create_dir(scratch.path("sub")).unwrap();
    std::fs::write(scratch.path("sub/b.asc"), ASC).unwrap();
    std::fs::write(scratch.path("a.asc"), ASC).unwrap();
    std::fs::write(scratch.path("broken.tif"), "not a tiff").unwrap();
    std::fs::write(scratch.path("readme.txt"), "ignored").unwrap();
    std::fs::write(scratch.path(".hidden.asc"), "ignored").unwrap();
    let (dems, failures) = load_exemplar_dir(&scratch.0);
    let names: Vec<&str> = dems.iter().map(|d| d.name.as_str()).collect();
    assert_eq!(names, ["a", "b"]);
    assert_eq!(failures.len(), 1);
    assert!(failures[0].0.ends_with("broken.tif"));
    let (dems, failures) = load_exemplar_dir(&scratch.path("no-such-folder"));
    assert!(dems.is_empty() && matches!(failures[..], [(_, DemError::Io { .. })]));
}
