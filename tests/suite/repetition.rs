//! `eval`'s repetition figure, through the real CLI on a real photograph (the bundled
//! gravel, as a 128² and a 64² sample): pieces of the sample on a lattice are flagged, the
//! same pieces at random offsets are not, a whole-sample tiling is flagged, and a periodic
//! sample's periodic continuation is not penalised.

use crate::common;

use image::RgbImage;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde_json::Value;
use std::path::Path;

const SIDE: u32 = 384;
/// The periodic sample's period.
const PIECE: u32 = 32;

fn gravel() -> RgbImage {
    image::open(concat!(env!("CARGO_MANIFEST_DIR"), "/data/gravel-128.png")).unwrap().to_rgb8()
}

fn repetition(analysis: &Path, picture: &RgbImage, name: &str) -> f64 {
    let path = analysis.parent().unwrap().join(format!("{name}.png"));
    picture.save(&path).unwrap();
    let r = common::btfsynth(&["eval", analysis.to_str().unwrap(), path.to_str().unwrap(), "--json"]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let q: Value = serde_json::from_slice(&r.stdout).unwrap();
    q["probes"][0]["repetition"].as_f64().unwrap()
}

/// Nine pieces cut from random places of the sample.
fn pieces(sample: &RgbImage, side: u32, rng: &mut ChaCha8Rng) -> Vec<RgbImage> {
    (0..9)
        .map(|_| {
            let (x, y) =
                (rng.random_range(0..=sample.width() - side), rng.random_range(0..=sample.height() - side));
            image::imageops::crop_imm(sample, x, y, side, side).to_image()
        })
        .collect()
}

/// On a 128² sample and on a 64² one (the size of most pattern libraries), pieces of a
/// quarter of the sample's side.
#[test]
fn eval_flags_pieces_on_a_lattice_but_not_the_same_pieces_at_random_offsets() {
    for side in [128, 64] {
        lattice_against_random_offsets(side, side / 4);
    }
}

fn lattice_against_random_offsets(side: u32, piece_side: u32) {
    let dir = tempfile::tempdir().unwrap();
    let analysis = common::analyze_gravel(dir.path(), "analysis", &format!("0,0,{side},{side}"));
    let sample = image::imageops::crop_imm(&gravel(), 0, 0, side, side).to_image();
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    // The lattice: a 3×3 arrangement of nine pieces repeated, so each recurs every three
    // pieces.
    let cut = pieces(&sample, piece_side, &mut rng);
    let mut lattice = RgbImage::new(SIDE, SIDE);
    for (i, j) in (0..SIDE / piece_side).flat_map(|j| (0..SIDE / piece_side).map(move |i| (i, j))) {
        let piece = &cut[((j % 3) * 3 + i % 3) as usize];
        image::imageops::replace(&mut lattice, piece, (i * piece_side) as i64, (j * piece_side) as i64);
    }
    // The same kind of pieces (larger, so that they cover) pasted at jittered places in a
    // random order, each a random one of the nine.
    let (big, jitter) = (pieces(&sample, piece_side * 3 / 2, &mut rng), piece_side as i64 / 4);
    let mut scattered = RgbImage::new(SIDE, SIDE);
    let mut places: Vec<(i64, i64)> = (-1..=(SIDE / piece_side) as i64)
        .flat_map(|j| (-1..=(SIDE / piece_side) as i64).map(move |i| (i, j)))
        .map(|(i, j)| {
            let mut at = |k: i64| k * piece_side as i64 + rng.random_range(-jitter..=jitter);
            (at(i), at(j))
        })
        .collect();
    rand::seq::SliceRandom::shuffle(places.as_mut_slice(), &mut rng);
    for (x, y) in places {
        image::imageops::replace(&mut scattered, &big[rng.random_range(0..9)], x, y);
    }
    let (on_lattice, at_random) =
        (repetition(&analysis, &lattice, "lattice"), repetition(&analysis, &scattered, "scattered"));
    assert!(on_lattice > 0.4, "{side}²: pieces on a lattice: repetition {on_lattice}");
    assert!(at_random < 0.1, "{side}²: the same pieces at random offsets: repetition {at_random}");
    assert!(on_lattice > 4.0 * at_random, "{side}²: {on_lattice} vs {at_random}");

    // A tiling of the whole sample is a lattice too.
    let mut tiled = RgbImage::new(SIDE, SIDE);
    for (i, j) in (0..SIDE.div_ceil(side)).flat_map(|j| (0..SIDE.div_ceil(side)).map(move |i| (i, j))) {
        image::imageops::replace(&mut tiled, &sample, (i * side) as i64, (j * side) as i64);
    }
    let whole = repetition(&analysis, &tiled, "tiled");
    assert!(whole > 0.4, "{side}²: a whole-sample tiling: repetition {whole}");
}

/// A periodic sample (a 32² piece of the photograph tiled 4×4) recurs in itself, so its
/// correct output, the same period continued, recurs everywhere without being a defect.
#[test]
fn a_periodic_samples_periodic_output_is_not_penalised() {
    let dir = tempfile::tempdir().unwrap();
    let piece = image::imageops::crop_imm(&gravel(), 40, 40, PIECE, PIECE).to_image();
    let tile = |side: u32| RgbImage::from_fn(side, side, |x, y| *piece.get_pixel(x % PIECE, y % PIECE));
    let sample = dir.path().join("periodic.png");
    tile(128).save(&sample).unwrap();
    let analysis = dir.path().join("analysis");
    let r = common::btfsynth(&["-q", "analyze", sample.to_str().unwrap(), "-o", analysis.to_str().unwrap()]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let periodic = repetition(&analysis, &tile(SIDE), "continued");
    assert!(periodic < 0.05, "the period continued: repetition {periodic}");
}
