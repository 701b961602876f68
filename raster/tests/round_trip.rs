//! Writing then reading each format gives the map back: exactly for float formats, within the
//! 16-bit quantisation bound for PNG and R16; metadata (cell size, stretch, GeoTIFF tags) is
//! present and readable by the format's own crate.

mod common;

use std::fs;
use std::io::Cursor;
use std::path::Path;

use common::{ScratchDir, assert_within_quantisation, constant, ramp_sine};
use terrasketch_raster::{
    Format, RasterError, Stretch, encode_heightmap, read_heightmap, read_r16, write_heightmap,
};

const WIDTH: usize = 37;
const HEIGHT: usize = 23;

#[test]
fn exr_round_trip_is_exact() {
    let dir = ScratchDir::new("exr-exact");
    let map = ramp_sine(WIDTH, HEIGHT);
    let path = dir.join("map.exr");
    let info = write_heightmap(&path, &map).unwrap();
    assert_eq!(info.format, Format::Exr);
    assert_eq!(info.stretch, None);
    assert_eq!(read_heightmap(&path).unwrap(), map);
}

#[test]
fn tiff_round_trip_is_exact_for_both_extensions() {
    let dir = ScratchDir::new("tiff-exact");
    let map = ramp_sine(WIDTH, HEIGHT);
    for name in ["map.tif", "map.TIFF"] {
        let path = dir.join(name);
        let info = write_heightmap(&path, &map).unwrap();
        assert_eq!(info.format, Format::Tiff);
        assert_eq!(info.stretch, None);
        assert_eq!(read_heightmap(&path).unwrap(), map, "{name}");
    }
}

#[test]
fn png_round_trip_is_within_the_quantisation_bound() {
    let dir = ScratchDir::new("png-quantised");
    let map = ramp_sine(WIDTH, HEIGHT);
    let path = dir.join("map.png");
    let info = write_heightmap(&path, &map).unwrap();
    assert_eq!(info.format, Format::Png16);
    let stretch = info.stretch.expect("png reports its stretch");
    assert_eq!(
        stretch.min_m,
        map.data.iter().copied().fold(f32::INFINITY, f32::min)
    );
    assert_eq!(
        stretch.max_m,
        map.data.iter().copied().fold(f32::NEG_INFINITY, f32::max)
    );

    let back = read_heightmap(&path).unwrap();
    assert_eq!(back.cell_size_m, map.cell_size_m);
    assert_within_quantisation(&map, &back);
}

#[test]
fn r16_round_trip_with_the_reported_stretch() {
    let dir = ScratchDir::new("r16-quantised");
    let map = ramp_sine(WIDTH, HEIGHT);
    let path = dir.join("map.r16");
    let info = write_heightmap(&path, &map).unwrap();
    assert_eq!(info.format, Format::R16);
    assert_eq!(
        fs::metadata(&path).unwrap().len(),
        (WIDTH * HEIGHT * 2) as u64,
        "no header"
    );

    let back = read_r16(&path, WIDTH, HEIGHT, info.stretch).unwrap();
    assert_eq!(back.cell_size_m, [1.0, 1.0]);
    assert_within_quantisation(&map, &back);

    // Without a stretch the codes come back raw: the minimum is 0, the maximum 65535.
    let raw = read_r16(&path, WIDTH, HEIGHT, None).unwrap();
    let stretch = info.stretch.unwrap();
    let argmin = map.data.iter().position(|&h| h == stretch.min_m).unwrap();
    let argmax = map.data.iter().position(|&h| h == stretch.max_m).unwrap();
    assert_eq!(raw.data[argmin], 0.0);
    assert_eq!(raw.data[argmax], 65535.0);
}

#[test]
fn r16_read_heightmap_needs_a_square_file_and_gives_raw_codes() {
    let dir = ScratchDir::new("r16-square");
    let path = dir.join("non_square.r16");
    write_heightmap(&path, &ramp_sine(WIDTH, HEIGHT)).unwrap();
    let error = read_heightmap(&path).unwrap_err();
    assert!(matches!(error, RasterError::Decode { .. }), "{error}");
    assert!(error.to_string().contains("read_r16"), "{error}");

    let square = ramp_sine(16, 16);
    let path = dir.join("square.r16");
    let stretch = write_heightmap(&path, &square).unwrap().stretch.unwrap();
    let raw = read_heightmap(&path).unwrap();
    assert_eq!((raw.width, raw.height), (16, 16));
    for (&height_m, &code) in square.data.iter().zip(&raw.data) {
        assert_eq!(code, f32::from(stretch.code_from_metres(height_m)));
    }
}

#[test]
fn north_up_orientation_is_preserved_by_every_format() {
    let dir = ScratchDir::new("north-up");
    // Zero everywhere but one spike in row 0, column 1 (north edge, near the west corner).
    let mut map = constant(WIDTH, HEIGHT, 0.0);
    map.data[1] = 100.0;
    for name in ["map.exr", "map.tif", "map.png", "map.r16"] {
        let path = dir.join(name);
        let info = write_heightmap(&path, &map).unwrap();
        let back = match info.format {
            Format::R16 => read_r16(&path, WIDTH, HEIGHT, info.stretch).unwrap(),
            _ => read_heightmap(&path).unwrap(),
        };
        let peak = back
            .data
            .iter()
            .enumerate()
            .max_by(|a, b| a.1.total_cmp(b.1))
            .map(|(index, _)| index);
        assert_eq!(
            peak,
            Some(1),
            "{name}: the spike must stay at row 0, column 1"
        );
        assert_eq!(back.data[1], 100.0, "{name}");
        assert_eq!(
            back.data[WIDTH * (HEIGHT - 1) + 1],
            0.0,
            "{name}: south row untouched"
        );
    }
}

#[test]
fn constant_maps_round_trip_exactly_in_every_format() {
    let dir = ScratchDir::new("constant");
    let map = constant(WIDTH, HEIGHT, 812.375);
    for name in ["map.exr", "map.tif", "map.png", "map.r16"] {
        let path = dir.join(name);
        let info = write_heightmap(&path, &map).unwrap();
        if let Some(stretch) = info.stretch {
            assert_eq!(
                stretch,
                Stretch {
                    min_m: 812.375,
                    max_m: 812.375
                },
                "{name}"
            );
        }
        let back = match info.format {
            Format::R16 => {
                let raw = read_r16(&path, WIDTH, HEIGHT, None).unwrap();
                assert!(
                    raw.data.iter().all(|&code| code == 0.0),
                    "{name}: all codes zero"
                );
                read_r16(&path, WIDTH, HEIGHT, info.stretch).unwrap()
            }
            _ => read_heightmap(&path).unwrap(),
        };
        assert_eq!(back.data, map.data, "{name}");
    }
}

#[test]
fn encode_heightmap_gives_the_bytes_write_heightmap_stores() {
    let dir = ScratchDir::new("encode-bytes");
    let map = ramp_sine(WIDTH, HEIGHT);
    for format in [Format::Exr, Format::Tiff, Format::Png16, Format::R16] {
        let path = dir.join(&format!("map.{}", format.extension()));
        assert_eq!(Format::from_path(&path).unwrap(), format);
        let info = write_heightmap(&path, &map).unwrap();
        let (bytes, stretch) = encode_heightmap(format, &map).unwrap();
        assert_eq!(stretch, info.stretch, "{format:?}");
        assert_eq!(bytes, fs::read(&path).unwrap(), "{format:?}");
    }
}

#[test]
fn png_carries_the_stretch_and_cell_size_text_chunks() {
    let map = ramp_sine(WIDTH, HEIGHT);
    let (bytes, stretch) = encode_heightmap(Format::Png16, &map).unwrap();
    let stretch = stretch.unwrap();
    let mut reader = png::Decoder::new(Cursor::new(&bytes)).read_info().unwrap();
    let mut pixels = vec![0; reader.output_buffer_size().unwrap()];
    let frame = reader.next_frame(&mut pixels).unwrap();
    assert_eq!((frame.width, frame.height), (WIDTH as u32, HEIGHT as u32));
    assert_eq!(frame.color_type, png::ColorType::Grayscale);
    assert_eq!(frame.bit_depth, png::BitDepth::Sixteen);

    let texts = &reader.info().uncompressed_latin1_text;
    let text = |keyword: &str| {
        let chunk = texts.iter().find(|chunk| chunk.keyword == keyword);
        chunk
            .unwrap_or_else(|| panic!("missing tEXt {keyword}"))
            .text
            .clone()
    };
    assert_eq!(text("terrasketch:min_m"), stretch.min_m.to_string());
    assert_eq!(text("terrasketch:max_m"), stretch.max_m.to_string());
    assert_eq!(
        text("terrasketch:min_m").parse::<f32>().unwrap(),
        stretch.min_m
    );
    assert_eq!(text("terrasketch:cell_size_m"), "2.5 4");
}

#[test]
fn geotiff_tags_are_present_and_readable() {
    use tiff::tags::Tag;

    let map = ramp_sine(WIDTH, HEIGHT);
    let (bytes, _) = encode_heightmap(Format::Tiff, &map).unwrap();
    let mut decoder = tiff::decoder::Decoder::new(Cursor::new(bytes)).unwrap();
    let scale = decoder.get_tag_f64_vec(Tag::ModelPixelScaleTag).unwrap();
    assert_eq!(scale, [2.5, 4.0, 0.0]);
    let tiepoint = decoder.get_tag_f64_vec(Tag::ModelTiepointTag).unwrap();
    assert_eq!(tiepoint, [0.0, 0.0, 0.0, 0.0, HEIGHT as f64 * 4.0, 0.0]);

    // A corner-sampled tile whose south-west sample is at (100, 200): its pixels reach half a
    // cell past its samples.
    let options = terrasketch_raster::WriteOptions {
        sampling: terrasketch_raster::Sampling::Corners,
        stretch: None,
        origin_m: [100.0, 200.0],
        ..Default::default()
    };
    let (corner_bytes, _) =
        terrasketch_raster::encode_heightmap_with(Format::Tiff, &map, &options).unwrap();
    let mut corner = tiff::decoder::Decoder::new(Cursor::new(corner_bytes)).unwrap();
    let tiepoint = corner.get_tag_f64_vec(Tag::ModelTiepointTag).unwrap();
    let north = 200.0 + (HEIGHT as f64 - 0.5) * 4.0;
    assert_eq!(tiepoint, [0.0, 0.0, 0.0, 100.0 - 1.25, north, 0.0]);
    let keys = decoder.get_tag_u16_vec(Tag::GeoKeyDirectoryTag).unwrap();
    assert_eq!(
        keys[..4],
        [1, 1, 0, 3],
        "KeyDirectoryVersion 1, revision 1.0, 3 keys"
    );
    let key = |id: u16| {
        let entry = keys[4..]
            .chunks_exact(4)
            .find(|entry| entry[0] == id)
            .unwrap();
        assert_eq!(entry[1..3], [0, 1], "key {id} stored inline");
        entry[3]
    };
    assert_eq!(key(1024), 1, "GTModelTypeGeoKey = projected");
    assert_eq!(key(1025), 1, "GTRasterTypeGeoKey = PixelIsArea");
    assert_eq!(key(3076), 9001, "ProjLinearUnitsGeoKey = metre");
    assert_eq!(decoder.get_tag_u32(Tag::SampleFormat).unwrap(), 3, "IEEEFP");
    assert_eq!(decoder.get_tag_u32(Tag::BitsPerSample).unwrap(), 32);
    assert_eq!(decoder.get_tag_u32(Tag::SamplesPerPixel).unwrap(), 1);
}

#[test]
fn png_without_stretch_chunks_reads_raw_codes() {
    let dir = ScratchDir::new("png-raw");
    let path = dir.join("plain.png");
    let codes: Vec<u16> = (0..WIDTH * HEIGHT).map(|i| (i * 61) as u16).collect();
    let mut bytes = Vec::new();
    {
        let mut encoder = png::Encoder::new(&mut bytes, WIDTH as u32, HEIGHT as u32);
        encoder.set_color(png::ColorType::Grayscale);
        encoder.set_depth(png::BitDepth::Sixteen);
        let mut writer = encoder.write_header().unwrap();
        let big_endian: Vec<u8> = codes.iter().flat_map(|code| code.to_be_bytes()).collect();
        writer.write_image_data(&big_endian).unwrap();
    }
    fs::write(&path, bytes).unwrap();
    let map = read_heightmap(&path).unwrap();
    assert_eq!((map.width, map.height), (WIDTH, HEIGHT));
    assert_eq!(map.cell_size_m, [1.0, 1.0]);
    let expected: Vec<f32> = codes.iter().map(|&code| f32::from(code)).collect();
    assert_eq!(map.data, expected);
}

#[test]
fn tiff_integer_samples_are_converted_and_cell_size_defaults() {
    use tiff::encoder::{TiffEncoder, colortype};

    let dir = ScratchDir::new("tiff-int");
    let unsigned: Vec<u16> = (0..WIDTH * HEIGHT).map(|i| (i * 71) as u16).collect();
    let signed: Vec<i16> = (0..WIDTH * HEIGHT).map(|i| i as i16 - 400).collect();

    let (w, h) = (WIDTH as u32, HEIGHT as u32);
    let mut u16_file = Cursor::new(Vec::new());
    let mut encoder = TiffEncoder::new(&mut u16_file).unwrap();
    encoder
        .write_image::<colortype::Gray16>(w, h, &unsigned)
        .unwrap();
    let mut i16_file = Cursor::new(Vec::new());
    let mut encoder = TiffEncoder::new(&mut i16_file).unwrap();
    encoder
        .write_image::<colortype::GrayI16>(w, h, &signed)
        .unwrap();
    let path_u16 = dir.join("u16.tif");
    fs::write(&path_u16, u16_file.into_inner()).unwrap();
    let path_i16 = dir.join("i16.tif");
    fs::write(&path_i16, i16_file.into_inner()).unwrap();

    let map = read_heightmap(&path_u16).unwrap();
    assert_eq!(map.cell_size_m, [1.0, 1.0]);
    assert_eq!(
        map.data,
        unsigned.iter().map(|&v| f32::from(v)).collect::<Vec<_>>()
    );
    let map = read_heightmap(&path_i16).unwrap();
    assert_eq!(
        map.data,
        signed.iter().map(|&v| f32::from(v)).collect::<Vec<_>>()
    );
}

#[test]
fn exr_reader_prefers_a_channel_named_height() {
    use exr::prelude::*;

    let dir = ScratchDir::new("exr-height");
    let path = dir.join("two_channels.exr");
    let channels = SpecificChannels::build()
        .with_channel("height")
        .with_channel("mask")
        .with_pixel_fn(|position: Vec2<usize>| {
            (position.x() as f32 + 10.0 * position.y() as f32, 7.0_f32)
        });
    Image::from_channels((5, 3), channels)
        .write()
        .to_file(&path)
        .unwrap();

    let map = read_heightmap(&path).unwrap();
    assert_eq!((map.width, map.height), (5, 3));
    assert_eq!(map.data[0], 0.0);
    assert_eq!(map.data[5 * 2 + 4], 24.0);
    assert_eq!(map.cell_size_m, [1.0, 1.0], "no cell size attribute");
}

#[test]
fn exr_reader_takes_compressed_tiles_from_other_writers() {
    use exr::prelude::*;

    let dir = ScratchDir::new("exr-tiles");
    let path = dir.join("tiled.exr");
    let expected = ramp_sine(50, 30);
    let channels = SpecificChannels::build()
        .with_channel("Y")
        .with_pixel_fn(|position: Vec2<usize>| (expected.data[position.y() * 50 + position.x()],));
    let encoding = Encoding {
        compression: Compression::ZIP16,
        blocks: Blocks::Tiles(Vec2(16, 16)),
        line_order: LineOrder::Increasing,
    };
    let layer = Layer::new((50, 30), LayerAttributes::default(), encoding, channels);
    Image::from_layer(layer).write().to_file(&path).unwrap();

    let map = read_heightmap(&path).unwrap();
    assert_eq!((map.width, map.height), (50, 30));
    assert_eq!(map.data, expected.data, "partial edge tiles land in place");
}

#[test]
fn format_comes_from_the_extension_case_insensitively() {
    let cases = [
        ("a.exr", Format::Exr),
        ("a.EXR", Format::Exr),
        ("dir.png/a.Tif", Format::Tiff),
        ("a.tiff", Format::Tiff),
        ("a.PNG", Format::Png16),
        ("a.r16", Format::R16),
        ("a.R16", Format::R16),
    ];
    for (path, format) in cases {
        assert_eq!(
            Format::from_path(Path::new(path)).unwrap(),
            format,
            "{path}"
        );
    }
    for path in ["a.jpg", "a", "a.exr.bak", ".png"] {
        let error = Format::from_path(Path::new(path)).unwrap_err();
        assert!(
            matches!(error, RasterError::UnsupportedExtension { .. }),
            "{path}"
        );
        let message = error.to_string();
        for extension in [".exr", ".tif", ".tiff", ".png", ".r16", path] {
            assert!(message.contains(extension), "{message:?} lacks {extension}");
        }
    }
}

#[test]
fn unsupported_extension_is_refused_for_reading_and_writing() {
    let dir = ScratchDir::new("unsupported");
    let path = dir.join("map.jpg");
    let error = write_heightmap(&path, &ramp_sine(4, 4)).unwrap_err();
    assert!(
        matches!(error, RasterError::UnsupportedExtension { .. }),
        "{error}"
    );
    assert!(dir.entries().is_empty(), "nothing written");
    fs::write(&path, b"not an image").unwrap();
    let error = read_heightmap(&path).unwrap_err();
    assert!(
        matches!(error, RasterError::UnknownFormat { .. }),
        "{error}"
    );
    assert!(
        error.to_string().contains("not a heightmap or DEM"),
        "{error}"
    );
}

#[test]
fn read_errors_name_the_missing_file() {
    let dir = ScratchDir::new("missing-file");
    let path = dir.join("absent.exr");
    let error = read_heightmap(&path).unwrap_err();
    assert!(
        matches!(&error, RasterError::Io { path: p, .. } if *p == path),
        "{error}"
    );
    assert!(error.to_string().contains("absent.exr"), "{error}");
}
