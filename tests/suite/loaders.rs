//! Every input layout on small fixtures: manifest, Bonn flat names, UTIA subfolders, single
//! PNG / JPEG / EXR, and cropping.

use crate::common;

use btfsynth::btf::image_io::{srgb_to_linear, write_exr};
use btfsynth::btf::{load, Crop, LoadOptions};
use btfsynth::progress::Silent;
use common::{pattern, write_png};
use half::f16;
use std::path::Path;

fn load_path(path: &Path) -> btfsynth::btf::Btf {
    load(path, &LoadOptions::default(), &Silent).unwrap_or_else(|e| panic!("{e}"))
}

/// The linear value the loader must produce for 8-bit sRGB `v`.
fn linear(v: u8) -> f16 {
    f16::from_f32(srgb_to_linear(v as f32 / 255.0))
}

fn assert_png_pixels(stack: &btfsynth::btf::Btf, image: usize, seed: u32) {
    let f = pattern(seed);
    for y in 0..stack.height() as u32 {
        for x in 0..stack.width() as u32 {
            let rgb = stack.rgb(image, x as usize, y as usize);
            let want = f(x, y).map(|v| linear(v).to_f32());
            assert_eq!(rgb, want, "image {image} pixel ({x},{y})");
        }
    }
}

#[test]
fn manifest_with_mixed_formats() {
    let dir = tempfile::tempdir().unwrap();
    write_png(&dir.path().join("a.png"), 6, 4, pattern(1));
    let exr: Vec<f16> = (0..6 * 4 * 3).map(|i| f16::from_f32(i as f32 * 0.125)).collect();
    write_exr(&dir.path().join("b.exr"), 6, 4, &exr).unwrap();
    std::fs::write(
        dir.path().join("btf.json"),
        r#"{"images": [
            {"file": "a.png", "light": [15, 30], "view": [0, 0]},
            {"file": "b.exr", "light": [60.5, 300], "view": [45, 90]}
        ], "notes": "extra keys are ignored"}"#,
    )
    .unwrap();
    for path in [dir.path().to_path_buf(), dir.path().join("btf.json")] {
        let stack = load_path(&path);
        assert_eq!((stack.width(), stack.height(), stack.len()), (6, 4, 2));
        assert_eq!((stack.pairs()[1].light.theta, stack.pairs()[1].light.phi), (60.5, 300.0));
        assert_eq!((stack.pairs()[1].view.theta, stack.pairs()[1].view.phi), (45.0, 90.0));
        assert_png_pixels(&stack, 0, 1);
        assert!(stack.image(1) == &exr[..], "EXR pixels are linear and exact");
    }
}

#[test]
fn bonn_flat_names_with_spaces_or_underscores() {
    let dir = tempfile::tempdir().unwrap();
    write_png(&dir.path().join("tl015 pl000 tv000 pv000.png"), 5, 5, pattern(1));
    write_png(&dir.path().join("tl075_pl120_tv030_pv060.png"), 5, 5, pattern(2));
    std::fs::write(dir.path().join("README.txt"), "not an image: ignored").unwrap();
    let stack = load_path(dir.path());
    assert_eq!(stack.len(), 2);
    // Sorted by file name: the space-separated one first.
    let p = stack.pairs()[0];
    assert_eq!((p.light.theta, p.light.phi, p.view.theta, p.view.phi), (15.0, 0.0, 0.0, 0.0));
    let p = stack.pairs()[1];
    assert_eq!((p.light.theta, p.light.phi, p.view.theta, p.view.phi), (75.0, 120.0, 30.0, 60.0));
    assert_png_pixels(&stack, 0, 1);
    assert_png_pixels(&stack, 1, 2);
}

#[test]
fn utia_subfolders_per_view() {
    let dir = tempfile::tempdir().unwrap();
    for (k, view) in ["tv000_pv000", "tv030_pv090"].iter().enumerate() {
        std::fs::create_dir(dir.path().join(view)).unwrap();
        write_png(&dir.path().join(view).join("tl000_pl000.png"), 4, 3, pattern(k as u32 * 2));
        write_png(
            &dir.path().join(view).join(format!("tl045_pl180_{view}.png")),
            4,
            3,
            pattern(k as u32 * 2 + 1),
        );
    }
    let stack = load_path(dir.path());
    assert_eq!((stack.len(), stack.views().len(), stack.lights().len()), (4, 2, 2));
    let p = stack.pairs()[2];
    assert_eq!((p.light.theta, p.view.theta, p.view.phi), (0.0, 30.0, 90.0));
    for i in 0..4 {
        assert_png_pixels(&stack, i, i as u32);
    }
}

#[test]
fn single_png_jpeg_and_exr_are_one_image_btfs() {
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("t.png");
    write_png(&png, 7, 5, pattern(3));
    let stack = load_path(&png);
    assert_eq!((stack.len(), stack.width(), stack.height()), (1, 7, 5));
    assert_eq!(stack.pairs()[0].light.theta, 0.0);
    assert_png_pixels(&stack, 0, 3);

    let jpg = dir.path().join("t.JPG");
    let flat = image::RgbImage::from_pixel(8, 8, image::Rgb([200, 100, 50]));
    flat.save_with_format(&jpg, image::ImageFormat::Jpeg).unwrap();
    let stack = load_path(&jpg);
    let rgb = stack.rgb(0, 4, 4);
    for (got, want) in rgb.iter().zip([200u8, 100, 50]) {
        assert!((got - linear(want).to_f32()).abs() < 0.02, "JPEG decodes near {want}: {rgb:?}");
    }

    let exr = dir.path().join("t.exr");
    let data: Vec<f16> = (0..3 * 2 * 3).map(|i| f16::from_f32(1.5 + i as f32)).collect();
    write_exr(&exr, 3, 2, &data).unwrap();
    assert!(load_path(&exr).image(0) == &data[..]);
}

#[test]
fn crop_keeps_the_same_pixels() {
    let dir = tempfile::tempdir().unwrap();
    write_png(&dir.path().join("tl000_pl000_tv000_pv000.png"), 10, 8, pattern(4));
    write_png(&dir.path().join("tl030_pl000_tv000_pv000.png"), 10, 8, pattern(5));
    let full = load_path(dir.path());
    let crop: Crop = "3,2,4,5".parse().unwrap();
    let cut = load(dir.path(), &LoadOptions { crop: Some(crop) }, &Silent).unwrap();
    assert_eq!((cut.width(), cut.height(), cut.len()), (4, 5, 2));
    for i in 0..2 {
        for y in 0..5 {
            for x in 0..4 {
                assert_eq!(cut.rgb(i, x, y), full.rgb(i, x + 3, y + 2));
            }
        }
    }
    let too_big: Crop = "8,0,4,4".parse().unwrap();
    let err = load(dir.path(), &LoadOptions { crop: Some(too_big) }, &Silent).unwrap_err().to_string();
    assert!(err.contains("does not fit"), "{err}");
    assert!("1,2,3".parse::<Crop>().is_err() && "0,0,0,4".parse::<Crop>().is_err());
}

#[test]
fn info_crop_flag_reports_the_cropped_size() {
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("t.png");
    write_png(&png, 12, 9, pattern(6));
    let out = common::btfsynth(&["info", png.to_str().unwrap(), "--json", "--crop", "2,1,8,6"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(
        (json["width"].as_u64(), json["height"].as_u64(), json["images"].as_u64()),
        (Some(8), Some(6), Some(1))
    );
}
