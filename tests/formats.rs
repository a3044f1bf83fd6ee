//! Real BTF file formats: Bonn `.btf` files (DFMF, FMF, BDI) built by hand from btflib's
//! documented layout, round trips through `convert`, malformed files, UBO2003 zips, UTIA's
//! XYZ EXRs, and a seeded mutation test of the readers.

mod common;

use btfsynth::btf::colour::{d65_white_xyz, ColourModel};
use btfsynth::btf::convert::{to_btf, ToBtfOptions};
use btfsynth::btf::gen::{generate, GenParams, MaterialKind};
use btfsynth::btf::ubo2014::{BonnBtf, Scalar};
use btfsynth::btf::{load, Btf, Crop, DirectionSet, ImageSource, LoadOptions};
use btfsynth::progress::Silent;
use common::{assert_one_line_error, btfsynth, pattern, write_png};
use half::f16;
use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

// ---------------------------------------------------------------------------------------
// The largest single allocation made by a thread that asked to be watched: a reader that
// allocated from an unchecked count would show up here.

struct Watching;

thread_local! {
    static WATCHED: Cell<bool> = const { Cell::new(false) };
}
static LARGEST: AtomicUsize = AtomicUsize::new(0);

fn note(size: usize) {
    if WATCHED.try_with(|w| w.get()).unwrap_or(false) {
        LARGEST.fetch_max(size, Ordering::Relaxed);
    }
}

unsafe impl GlobalAlloc for Watching {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        note(layout.size());
        System.alloc(layout)
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        System.dealloc(ptr, layout)
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        note(layout.size());
        System.alloc_zeroed(layout)
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        note(new_size);
        System.realloc(ptr, layout, new_size)
    }
}

#[global_allocator]
static ALLOCATOR: Watching = Watching;

/// Runs `f` on this thread with its allocations watched; returns the result and the
/// largest single allocation (other tests run on other threads and are not counted).
fn watched<T>(f: impl FnOnce() -> T) -> (T, usize) {
    WATCHED.with(|w| w.set(true));
    LARGEST.store(0, Ordering::Relaxed);
    let out = f();
    WATCHED.with(|w| w.set(false));
    (out, LARGEST.load(Ordering::Relaxed))
}

// ---------------------------------------------------------------------------------------
// Bonn files by hand, field by field as btflib reads them (not through btfsynth's writer).

/// Little-endian bytes, with named section boundaries.
#[derive(Default)]
struct Bytes {
    b: Vec<u8>,
    sections: Vec<(usize, &'static str)>,
}

impl Bytes {
    fn mark(&mut self, section: &'static str) {
        self.sections.push((self.b.len(), section));
    }
    fn raw(&mut self, v: &[u8]) {
        self.b.extend_from_slice(v);
    }
    fn u8(&mut self, v: u8) {
        self.b.push(v);
    }
    fn u32(&mut self, v: u32) {
        self.raw(&v.to_le_bytes());
    }
    fn i32(&mut self, v: i32) {
        self.raw(&v.to_le_bytes());
    }
    fn f32(&mut self, v: f32) {
        self.raw(&v.to_le_bytes());
    }
    fn scalar(&mut self, v: f32, size: u8) {
        match size {
            2 => self.raw(&f16::from_f32(v).to_le_bytes()),
            4 => self.f32(v),
            _ => self.raw(&(v as f64).to_le_bytes()),
        }
    }
}

/// The shape of a hand-made file.
struct Spec {
    signature: &'static str,
    /// (θ, φ) in degrees.
    views: Vec<(f32, f32)>,
    lights: Vec<(f32, f32)>,
    width: usize,
    height: usize,
    rotations: Vec<[f32; 9]>,
    version: u32,
    cosine: bool,
}

impl Spec {
    fn small(signature: &'static str) -> Self {
        Spec {
            signature,
            views: vec![(0.0, 0.0), (30.0, 90.0)],
            lights: vec![(0.0, 0.0), (15.0, 0.0), (45.0, 270.0)],
            width: 4,
            height: 2,
            rotations: match signature.ends_with('R') || signature.ends_with("2!") {
                true => vec![
                    [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
                    [0.0, -1.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0],
                ],
                false => vec![],
            },
            version: 4,
            cosine: false,
        }
    }
    fn images(&self) -> usize {
        self.views.len() * self.lights.len()
    }
    fn pixels(&self) -> usize {
        self.width * self.height
    }
}

/// Signature, meta header, directions, size and (except for BDI) the rotation block.
fn common_header(spec: &Spec, out: &mut Bytes) {
    out.mark("signature");
    out.raw(spec.signature.as_bytes());
    out.mark("meta header");
    let mut meta = Bytes::default();
    meta.u32(spec.version);
    for text in ["test setup", "test sensor", "test light"] {
        let mut field = [0u8; 80];
        field[..text.len()].copy_from_slice(text.as_bytes());
        meta.raw(&field);
    }
    meta.f32(10.0);
    for v in [1.0, 1.0, 1.0] {
        meta.f32(v);
    }
    if spec.version > 1 {
        meta.u32(spec.cosine as u32);
    }
    if spec.version > 2 {
        meta.u32(5);
        meta.raw(b"<x/>\n");
    }
    if spec.version > 3 {
        meta.u32(3);
        for name in ["R", "G", "B"] {
            meta.u32(1);
            meta.raw(name.as_bytes());
        }
    }
    out.u32(meta.b.len() as u32 + 4);
    out.raw(&meta.b);
    out.mark("direction table");
    out.u32(spec.views.len() as u32);
    for &(t, p) in &spec.views {
        out.f32(t.to_radians());
        out.f32(p.to_radians());
        out.u32(spec.lights.len() as u32);
        for &(t, p) in &spec.lights {
            out.f32(t.to_radians());
            out.f32(p.to_radians());
        }
    }
    out.mark("image size");
    out.u32(spec.width as u32);
    out.u32(spec.height as u32);
    if !spec.signature.starts_with("!BDIF") && spec.signature.ends_with('R') {
        rotation_block(spec, out);
    }
}

fn rotation_block(spec: &Spec, out: &mut Bytes) {
    out.mark("rotation block");
    out.u32(spec.rotations.len() as u32);
    for r in &spec.rotations {
        for &v in r {
            out.f32(v);
        }
    }
}

/// A deterministic factor value.
fn value(seed: usize, i: usize, k: usize) -> f32 {
    let h = (seed * 7919 + i * 104_729 + k * 1_299_709) % 1000;
    (h as f32 / 1000.0 - 0.3) * 0.8
}

/// Per channel: U (images × K) and SxV (pixels × K) as plain arrays.
struct ChannelData {
    u: Vec<Vec<f32>>,
    sxv: Vec<Vec<f32>>,
}

fn channel_data(spec: &Spec, k: usize, seed: usize) -> Vec<ChannelData> {
    (0..3)
        .map(|c| ChannelData {
            u: (0..spec.images()).map(|i| (0..k).map(|j| value(seed + c, i, j)).collect()).collect(),
            sxv: (0..spec.pixels())
                .map(|p| (0..k).map(|j| value(seed + 10 + c, p, j) + 0.5).collect())
                .collect(),
        })
        .collect()
}

/// A DFMF file; `transposed` stores U with one row per pixel (btflib's other layout).
fn dfmf(spec: &Spec, model: i32, size: u8, data: &[ChannelData], transposed: bool) -> Bytes {
    let mut out = Bytes::default();
    common_header(spec, &mut out);
    out.mark("DFMF colour model");
    out.u32(data[0].u[0].len() as u32);
    out.i32(model);
    for v in [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0] {
        out.f32(v);
    }
    for (c, ch) in data.iter().enumerate() {
        out.mark(["channel 0 factors", "channel 1 factors", "channel 2 factors"][c]);
        let k = ch.u[0].len();
        let (first, second) = if transposed { (&ch.sxv, &ch.u) } else { (&ch.u, &ch.sxv) };
        out.u8(size);
        out.u32(k as u32);
        out.u32(first.len() as u32);
        out.u32(second.len() as u32);
        for j in 0..k {
            out.scalar(1.0 + j as f32, size);
        }
        for row in first.iter().chain(second.iter()) {
            for &v in row {
                out.scalar(v, size);
            }
        }
    }
    out
}

/// What a factorized file decodes to in channel `c` of image `i` at pixel `p`.
fn product(data: &[ChannelData], c: usize, i: usize, p: usize, size: u8) -> f32 {
    let round = |v: f32| if size == 2 { f16::from_f32(v).to_f32() } else { v };
    data[c].u[i].iter().zip(&data[c].sxv[p]).map(|(&a, &b)| round(a) * round(b)).sum()
}

fn tmp_file(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, bytes).unwrap();
    path
}

fn decode(path: &Path) -> Btf {
    load(path, &LoadOptions::default(), &Silent).unwrap_or_else(|e| panic!("{e}"))
}

fn close(a: f32, b: f32, tol: f32) -> bool {
    (a - b).abs() <= tol * (1.0 + b.abs())
}

// ---------------------------------------------------------------------------------------

#[test]
fn dfmf_by_hand_decodes_texel_by_texel_with_lights_not_views() {
    let dir = tempfile::tempdir().unwrap();
    for (signature, size, transposed) in
        [("!DFMF08FCR", 2, false), ("!DFMF08FCR", 4, true), ("!DFMF08FC", 8, false), ("!DFMF08FC", 4, true)]
    {
        let spec = Spec::small(signature);
        let data = channel_data(&spec, 2, 3);
        let path = tmp_file(dir.path(), "hand.btf", &dfmf(&spec, 0, size, &data, transposed).b);
        let stack = decode(&path);
        assert_eq!((stack.width(), stack.height(), stack.len()), (4, 2, 6), "{signature}");
        assert_eq!((stack.views().len(), stack.lights().len()), (2, 3));
        for v in 0..2 {
            for l in 0..3 {
                let i = l + 3 * v;
                let p = stack.pairs()[i];
                assert_eq!((p.light.theta, p.light.phi), spec.lights[l], "image {i}");
                assert_eq!((p.view.theta, p.view.phi), spec.views[v], "image {i}");
                for y in 0..2 {
                    for x in 0..4 {
                        let got = stack.rgb(i, x, y);
                        for c in 0..3 {
                            let want = product(&data, c, i, x + 4 * y, size);
                            assert!(
                                close(got[c], want, 2e-3),
                                "{signature} {size}: image {i} ({x},{y}) c{c}: {got:?} vs {want}"
                            );
                        }
                    }
                }
            }
        }
        let file = BonnBtf::open(&path).unwrap();
        assert_eq!(file.rotations().len(), spec.rotations.len());
        assert_eq!(file.meta().measurement_setup, "test setup");
    }
}

#[test]
fn dfmf_colour_model_11_and_the_cosine_flag_are_undone() {
    let dir = tempfile::tempdir().unwrap();
    let mut spec = Spec::small("!DFMF08FCR");
    spec.cosine = true;
    let data = channel_data(&spec, 3, 5);
    let path = tmp_file(dir.path(), "m11.btf", &dfmf(&spec, 11, 4, &data, false).b);
    let stack = decode(&path);
    for i in 0..spec.images() {
        let cos = stack.pairs()[i].light.theta.to_radians().cos();
        for p in 0..spec.pixels() {
            let v: Vec<f64> = (0..3).map(|c| product(&data, c, i, p, 4) as f64).collect();
            // btflib: Y = exp(v0) − ε, U = v1·(Y + ε), V = v2·(Y + ε), then YUV → RGB.
            let y = v[0].exp() - 1e-5;
            let (u, w) = (v[1] * (y + 1e-5), v[2] * (y + 1e-5));
            let rgb = [y + 1.13983 * w, y - 0.39465 * u - 0.5806 * w, y + 2.03211 * u];
            let got = stack.rgb(i, p % 4, p / 4);
            for c in 0..3 {
                let want = (rgb[c] / cos as f64) as f32;
                assert!(close(got[c], want, 2e-3), "image {i} pixel {p}: {got:?} vs {want}");
            }
        }
    }
}

/// An FMF: one factorization whose rows interleave the channels.
fn fmf(
    spec: &Spec,
    size: u8,
    k: usize,
    log_flag: bool,
    texel_rows: bool,
) -> (Bytes, Vec<Vec<f32>>, Vec<Vec<f32>>) {
    let (side_a, side_b) =
        if texel_rows { (3 * spec.pixels(), spec.images()) } else { (3 * spec.images(), spec.pixels()) };
    let u: Vec<Vec<f32>> = (0..side_a).map(|r| (0..k).map(|j| value(1, r, j) * 0.5).collect()).collect();
    let sxv: Vec<Vec<f32>> = (0..side_b).map(|r| (0..k).map(|j| value(2, r, j) + 0.4).collect()).collect();
    let mut out = Bytes::default();
    common_header(spec, &mut out);
    out.mark("FMF header");
    if spec.signature == "!FMF12FCER" {
        out.u8(2);
        out.u32(log_flag as u32);
        out.u32(2);
        out.u32(2);
        for _ in 0..4 {
            out.raw(&f16::from_f32(0.25).to_le_bytes());
        }
    }
    out.u32(k as u32);
    out.u8(size);
    out.u32(k as u32);
    out.u32(u.len() as u32);
    out.u32(sxv.len() as u32);
    out.mark("FMF factors");
    for j in 0..k {
        out.scalar(j as f32 + 1.0, size);
    }
    for row in u.iter().chain(&sxv) {
        for &v in row {
            out.scalar(v, size);
        }
    }
    (out, u, sxv)
}

#[test]
fn fmf_by_hand_in_both_layouts_with_the_dynamic_range_flag() {
    let dir = tempfile::tempdir().unwrap();
    for (signature, texel_rows, log_flag) in
        [("!FMF06FC", false, false), ("!FMF06FCR", true, false), ("!FMF12FCER", false, true)]
    {
        let spec = Spec::small(signature);
        let (bytes, u, sxv) = fmf(&spec, 4, 2, log_flag, texel_rows);
        let path = tmp_file(dir.path(), "fmf.btf", &bytes.b);
        let stack = decode(&path);
        for i in 0..spec.images() {
            for p in 0..spec.pixels() {
                let got = stack.rgb(i, p % 4, p / 4);
                for c in 0..3 {
                    let (a, b) = if texel_rows { (&sxv[i], &u[c + 3 * p]) } else { (&u[c + 3 * i], &sxv[p]) };
                    let mut want: f32 = a.iter().zip(b).map(|(x, y)| x * y).sum();
                    if log_flag {
                        want = want.exp() - 1e-5;
                    }
                    assert!(
                        close(got[c], want, 2e-3),
                        "{signature}: image {i} pixel {p} c{c}: {got:?} vs {want}"
                    );
                }
            }
        }
        let info = BonnBtf::open(&path).unwrap().describe();
        assert_eq!(info["format"], "FMF");
        assert_eq!(info["dynamic_range_reduction"], log_flag);
    }
}

/// A BDI: half-float ABRDFs (channel, light, view) per texel, chunks of `scan_lines` rows;
/// `sparse` stores only the texels whose mask byte (x-major) is set.
fn bdi(spec: &Spec, scan_lines: usize, sparse: bool) -> (Bytes, Vec<bool>) {
    let (w, h) = (spec.width, spec.height);
    let stored: Vec<bool> = (0..w * h).map(|p| !sparse || p % 4 != 1).collect();
    let mut out = Bytes::default();
    common_header(spec, &mut out);
    out.mark("BDI chunk layout");
    out.u32(scan_lines as u32);
    out.u8(if sparse { 2 } else { 0 });
    out.mark("BDI mask");
    for x in 0..w {
        for y in 0..h {
            out.u8(stored[x + w * y] as u8);
        }
    }
    rotation_block(spec, &mut out);
    out.mark("BDI chunks");
    let texels: Vec<usize> = (0..w * h).filter(|&p| stored[p]).collect();
    for chunk in texels.chunks(w * scan_lines) {
        out.u32((chunk.len() * 3 * spec.images() * 2) as u32);
        for &p in chunk {
            for i in 0..spec.images() {
                for c in 0..3 {
                    out.raw(&f16::from_f32(bdi_value(p, i, c)).to_le_bytes());
                }
            }
        }
    }
    (out, stored)
}

fn bdi_value(p: usize, i: usize, c: usize) -> f32 {
    0.01 * (p * 31 + i * 7 + c) as f32
}

#[test]
fn bdi_by_hand_full_and_sparse() {
    let dir = tempfile::tempdir().unwrap();
    for sparse in [false, true] {
        let mut spec = Spec::small("!BDIF06R2!");
        spec.width = 4;
        spec.height = 3;
        let (bytes, stored) = bdi(&spec, 2, sparse);
        let path = tmp_file(dir.path(), "a.bdi", &bytes.b);
        let stack = decode(&path);
        for i in 0..spec.images() {
            for (p, &is_stored) in stored.iter().enumerate() {
                let want: [f32; 3] = std::array::from_fn(|c| {
                    if is_stored {
                        f16::from_f32(bdi_value(p, i, c)).to_f32()
                    } else {
                        0.0
                    }
                });
                assert_eq!(stack.rgb(i, p % 4, p / 4), want, "sparse {sparse}: image {i} pixel {p}");
            }
        }
        // One image alone, and a crop, decode the same values.
        let window = BonnBtf::open(&path)
            .unwrap()
            .into_window(Some(Crop { x: 1, y: 1, width: 2, height: 2 }))
            .unwrap();
        let mut one = vec![f16::ZERO; 12];
        window.decode_image(4, &mut one).unwrap();
        assert_eq!(one[0].to_f32(), stack.rgb(4, 1, 1)[0]);
        assert_eq!(one[9 + 2].to_f32(), stack.rgb(4, 2, 2)[2]);
    }
}

#[test]
fn crop_decodes_only_the_crop() {
    let dir = tempfile::tempdir().unwrap();
    let spec = Spec::small("!DFMF08FCR");
    let data = channel_data(&spec, 2, 9);
    let path = tmp_file(dir.path(), "c.btf", &dfmf(&spec, 0, 4, &data, false).b);
    let full = decode(&path);
    let crop = Crop { x: 1, y: 1, width: 2, height: 1 };
    let cut = load(&path, &LoadOptions { crop: Some(crop) }, &Silent).unwrap();
    assert_eq!((cut.width(), cut.height()), (2, 1));
    for i in 0..full.len() {
        for x in 0..2 {
            assert_eq!(cut.rgb(i, x, 0), full.rgb(i, x + 1, 1));
        }
    }
    let e = load(&path, &LoadOptions { crop: Some(Crop { x: 3, y: 0, width: 2, height: 1 }) }, &Silent)
        .unwrap_err();
    assert!(e.to_string().contains("does not fit"), "{e}");
}

// ---------------------------------------------------------------------------------------
// Round trips through `convert`.

fn small_stack(directions: DirectionSet, size: usize) -> Btf {
    let params = GenParams { size, directions, samples_per_pixel: 1, ..GenParams::default() };
    generate(MaterialKind::Pebbles, &params, &Silent).unwrap()
}

#[test]
fn folder_to_btf_at_full_rank_to_folder_is_exact_within_f16() {
    let dir = tempfile::tempdir().unwrap();
    let stack = small_stack(DirectionSet::Grid(6), 12);
    let folder = dir.path().join("stack");
    btfsynth::btf::write_stack(&stack, &folder, Default::default(), None, false, &Silent).unwrap();
    let btf = dir.path().join("stack.btf");
    let run = |args: &[&str]| {
        let out = btfsynth(args);
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        String::from_utf8_lossy(&out.stderr).into_owned()
    };
    let report = run(&[
        "-q",
        "convert",
        folder.to_str().unwrap(),
        "-o",
        btf.to_str().unwrap(),
        "--components",
        "36",
        "--precision",
        "float",
        "--colour-model",
        "0",
    ]);
    assert!(report.contains("error"), "{report}");
    let back = dir.path().join("back");
    run(&["-q", "convert", btf.to_str().unwrap(), "-o", back.to_str().unwrap()]);
    let reread = decode(&back);
    assert_eq!(reread.len(), stack.len());
    for i in 0..stack.len() {
        let j = reread.find(&stack.pairs()[i]).expect("every pair survives");
        for (a, b) in stack.image(i).iter().zip(reread.image(j)) {
            // One f16 rounding step apart at most (or 1e-6 of the stack's unit scale, for
            // values near zero).
            let ulp = f16::from_bits(a.to_bits() + 1).to_f32() - a.to_f32();
            assert!((a.to_f32() - b.to_f32()).abs() <= ulp.abs() * 1.01 + 1e-6, "image {i}: {a} vs {b}");
        }
    }
}

/// The singular values of channel `c` of the stack's (images × pixels) matrix, by
/// nalgebra's SVD (independent of btfsynth's factorization).
fn singular_values(stack: &Btf, c: usize) -> Vec<f64> {
    let pixels = stack.width() * stack.height();
    let m = nalgebra::DMatrix::from_fn(stack.len(), pixels, |i, p| stack.image(i)[p * 3 + c].to_f64());
    let mut s: Vec<f64> = m.svd(false, false).singular_values.iter().copied().collect();
    s.sort_by(|a, b| b.total_cmp(a));
    s
}

#[test]
fn truncation_error_is_what_the_discarded_singular_values_predict() {
    let dir = tempfile::tempdir().unwrap();
    let stack = small_stack(DirectionSet::Grid(7), 10);
    for k in [3, 10, 25] {
        let path = dir.path().join(format!("k{k}.btf"));
        let options = ToBtfOptions {
            components: k,
            model: ColourModel::Rgb,
            scalar: Scalar::F32,
            rotation_block: true,
            rotations: vec![],
            seed: 0,
        };
        let report = to_btf(&stack, &path, &options, &Silent).unwrap();
        let (mut discarded, mut total) = (0.0, 0.0);
        for c in 0..3 {
            let s = singular_values(&stack, c);
            discarded += s[k..].iter().map(|v| v * v).sum::<f64>();
            total += s.iter().map(|v| v * v).sum::<f64>();
            let channel =
                (s[k..].iter().map(|v| v * v).sum::<f64>() / s.iter().map(|v| v * v).sum::<f64>()).sqrt();
            assert!(
                (report.predicted_error[c] - channel).abs() < 1e-3 * channel + 1e-6,
                "k {k} c {c}: {report:?} vs {channel}"
            );
        }
        let predicted = (discarded / total).sqrt();
        // The file's error includes f16 rounding of the decoded images (≈ 3e-4).
        assert!(
            (report.relative_error - predicted).abs() < 0.01 * predicted + 4e-4,
            "k {k}: {report:?} vs {predicted}"
        );
        assert!(report.relative_error > 1e-3, "k {k} must lose something: {report:?}");
    }
}

#[test]
fn half_precision_and_model_11_files_read_back_close() {
    let dir = tempfile::tempdir().unwrap();
    let stack = small_stack(DirectionSet::Grid(5), 8);
    // Pure black (shadowed) texels are what log-Y encoding handles worst; lift them as a
    // measured material with some ambient light would be.
    let lifted: Vec<f16> = stack.pixels().iter().map(|v| f16::from_f32(v.to_f32() + 0.02)).collect();
    let stack = Btf::new(8, 8, stack.pairs().to_vec(), lifted).unwrap();
    for (model, scalar) in [
        (ColourModel::Rgb, Scalar::F16),
        (ColourModel::LogYUvOverY, Scalar::F16),
        (ColourModel::LogYUvOverY, Scalar::F32),
    ] {
        let path = dir.path().join("m.btf");
        let options =
            ToBtfOptions { components: 25, model, scalar, rotation_block: false, rotations: vec![], seed: 1 };
        let report = to_btf(&stack, &path, &options, &Silent).unwrap();
        assert!(report.relative_error < 3e-3, "{model:?} {scalar:?}: {report:?}");
        let back = decode(&path);
        let e = btfsynth::btf::factorize::relative_difference(&stack, &{
            let mut reordered = Vec::new();
            for p in stack.pairs() {
                reordered.extend_from_slice(back.image(back.find(p).unwrap()));
            }
            Btf::new(8, 8, stack.pairs().to_vec(), reordered).unwrap()
        });
        assert!((e - report.relative_error).abs() < 1e-6, "{e} vs {report:?}");
    }
}

#[test]
fn incomplete_stacks_cannot_become_dfmf() {
    let stack = small_stack(DirectionSet::Grid(3), 4);
    let keep: Vec<usize> = (0..stack.len() - 1).collect();
    let pixels: Vec<f16> = keep.iter().flat_map(|&i| stack.image(i).to_vec()).collect();
    let partial = Btf::new(4, 4, keep.iter().map(|&i| stack.pairs()[i]).collect(), pixels).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let options = ToBtfOptions {
        components: 2,
        model: ColourModel::Rgb,
        scalar: Scalar::F16,
        rotation_block: true,
        rotations: vec![],
        seed: 0,
    };
    let e = to_btf(&partial, &dir.path().join("x.btf"), &options, &Silent).expect_err("refused");
    assert!(e.to_string().contains("every view × light pair"), "{e}");
    assert!(!dir.path().join("x.btf").exists());
}

// ---------------------------------------------------------------------------------------
// Malformed files: one error naming the file and the section, and no allocation from an
// unchecked count.

/// Opens and decodes; the error text if anything fails.
fn try_read(path: &Path, bytes: Vec<u8>) -> Result<Btf, String> {
    let file = BonnBtf::from_bytes(path, bytes).map_err(|e| e.to_string())?;
    let window = file.into_window(None).map_err(|e| e.to_string())?;
    window.decode_all(&Silent).map_err(|e| e.to_string())
}

fn assert_names(e: &str, section: &str) {
    assert!(e.starts_with("bad.btf: "), "the error names the file: {e}");
    assert!(e.contains(section), "the error names the section {section:?}: {e}");
    assert!(!e.contains('\n'), "one line: {e}");
}

#[test]
fn truncation_at_every_byte_is_an_error_naming_the_section() {
    let path = Path::new("bad.btf");
    let spec = Spec::small("!DFMF08FCR");
    let good = dfmf(&spec, 0, 2, &channel_data(&spec, 2, 1), false);
    let (mut fmf_spec, mut bdi_spec) = (Spec::small("!FMF12FCER"), Spec::small("!BDIF06R2!"));
    fmf_spec.version = 3;
    bdi_spec.version = 2;
    let files = [good, fmf(&fmf_spec, 2, 2, true, false).0, bdi(&bdi_spec, 1, true).0];
    for file in files {
        assert!(try_read(path, file.b.clone()).is_ok());
        for len in 0..file.b.len() {
            let (result, largest) = watched(|| try_read(path, file.b[..len].to_vec()));
            let e = result
                .err()
                .unwrap_or_else(|| panic!("a file cut at {len} of {} bytes was accepted", file.b.len()));
            // The section the cut falls in (or, at a boundary, the one that follows).
            let section =
                file.sections.iter().rev().find(|(at, _)| *at <= len).map(|s| s.1).unwrap_or("signature");
            let before =
                file.sections.iter().rev().find(|(at, _)| *at < len).map(|s| s.1).unwrap_or("signature");
            assert!(e.starts_with("bad.btf: ") && !e.contains('\n'), "{e}");
            // Cut inside the signature, the file may read as a shorter signature whose
            // meta header is then cut.
            let in_signature = section == "signature" && e.contains("meta header");
            assert!(
                e.contains(section) || e.contains(before) || in_signature,
                "cut at {len}: expected {section:?}: {e}"
            );
            assert!(largest < 1 << 20, "cut at {len}: allocated {largest} bytes");
        }
    }
}

/// Overwrites 4 bytes at `at`.
fn patch(mut b: Vec<u8>, at: usize, v: &[u8]) -> Vec<u8> {
    b[at..at + v.len()].copy_from_slice(v);
    b
}

#[test]
fn each_malformed_header_field_is_named() {
    let path = Path::new("bad.btf");
    let spec = Spec::small("!DFMF08FCR");
    let good = dfmf(&spec, 0, 2, &channel_data(&spec, 2, 1), false);
    let at = |name: &str| good.sections.iter().find(|s| s.1 == name).unwrap().0;
    let (meta, dirs, size, rot) =
        (at("meta header"), at("direction table"), at("image size"), at("rotation block"));
    let cases: Vec<(&str, Vec<u8>, &str)> = vec![
        ("wrong signature", patch(good.b.clone(), 0, b"!XYZ"), "signature"),
        ("PVF", patch(good.b.clone(), 0, b"!PVF06FC"), "not supported yet: PVF"),
        ("header size disagrees", patch(good.b.clone(), meta, &500u32.to_le_bytes()), "meta header"),
        ("2^32 views", patch(good.b.clone(), dirs, &u32::MAX.to_le_bytes()), "direction table"),
        ("2^32 lights", patch(good.b.clone(), dirs + 12, &u32::MAX.to_le_bytes()), "direction table"),
        ("NaN angle", patch(good.b.clone(), dirs + 4, &f32::NAN.to_le_bytes()), "non-finite"),
        ("θ beyond the horizon", patch(good.b.clone(), dirs + 4, &2.0f32.to_le_bytes()), "direction table"),
        ("zero width", patch(good.b.clone(), size, &0u32.to_le_bytes()), "image size"),
        ("huge size", patch(good.b.clone(), size, &[0xff; 8]), "channel 0 factors"),
        ("rotation count too large", patch(good.b.clone(), rot, &1000u32.to_le_bytes()), "rotation block"),
        ("rotation count too small", patch(good.b.clone(), rot, &1u32.to_le_bytes()), "rotation block"),
        (
            "unknown colour model",
            patch(good.b.clone(), at("DFMF colour model") + 4, &7i32.to_le_bytes()),
            "not supported yet: colour model 7",
        ),
        ("bad scalar size", patch(good.b.clone(), at("channel 1 factors"), &[3]), "channel 1 factors"),
        (
            "NaN in SxV",
            {
                let n = good.b.len();
                patch(good.b.clone(), n - 2, &f16::NAN.to_le_bytes())
            },
            "not a finite number",
        ),
    ];
    for (what, bytes, needle) in cases {
        let (result, largest) = watched(|| try_read(path, bytes));
        let e = result.err().unwrap_or_else(|| panic!("{what}: accepted"));
        assert_names(&e, needle);
        assert!(largest < 1 << 20, "{what}: allocated {largest} bytes");
    }
    // A 20-byte file that claims 2³² views allocates nothing large.
    let mut tiny = b"!DFMF08FC".to_vec();
    tiny.extend_from_slice(&[0xff; 11]);
    let (result, largest) = watched(|| try_read(path, tiny));
    assert_names(&result.unwrap_err(), "meta header");
    assert!(largest < 4096, "{largest}");
}

#[test]
fn the_cli_prints_one_line_for_a_bad_btf() {
    let dir = tempfile::tempdir().unwrap();
    let spec = Spec::small("!DFMF08FCR");
    let good = dfmf(&spec, 0, 2, &channel_data(&spec, 2, 1), false);
    let dirs = good.sections.iter().find(|s| s.1 == "direction table").unwrap().0;
    let bad = tmp_file(dir.path(), "bad.btf", &patch(good.b.clone(), dirs, &u32::MAX.to_le_bytes()));
    let (bad, o) = (bad.to_str().unwrap(), dir.path().join("o"));
    for args in [
        vec!["info", bad],
        vec!["analyze", bad, "-o", o.to_str().unwrap()],
        vec!["convert", bad, "-o", o.to_str().unwrap()],
    ] {
        assert_one_line_error(&btfsynth(&args), "bad.btf: direction table");
    }
    assert!(!o.exists());
}

#[test]
fn info_json_describes_a_btf_from_its_header() {
    let dir = tempfile::tempdir().unwrap();
    let spec = Spec::small("!DFMF08FCR");
    let path = tmp_file(dir.path(), "d.btf", &dfmf(&spec, 11, 2, &channel_data(&spec, 2, 1), false).b);
    let out = btfsynth(&["info", path.to_str().unwrap(), "--json"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["kind"], "btf-file");
    assert_eq!(v["format"], "DFMF");
    assert_eq!(v["signature"], "!DFMF08FCR");
    assert_eq!((v["width"].as_u64(), v["height"].as_u64()), (Some(4), Some(2)));
    assert_eq!(
        (v["lights"].as_u64(), v["views"].as_u64(), v["images"].as_u64()),
        (Some(3), Some(2), Some(6))
    );
    assert_eq!(v["components"], serde_json::json!([2, 2, 2]));
    assert_eq!(v["colour_model"]["id"], 11);
    assert_eq!(v["header"]["measurement_setup"], "test setup");
    assert_eq!(v["header"]["light_source"], "test light");
    assert_eq!(v["rotations"], 2);
}

// ---------------------------------------------------------------------------------------
// UBO2003 / ATRIUM archives.

fn write_zip(path: &Path, members: &[(String, Vec<u8>)]) {
    let mut zip = zip::ZipWriter::new(std::fs::File::create(path).unwrap());
    let options =
        zip::write::SimpleFileOptions::default().compression_method(zip::CompressionMethod::Deflated);
    for (name, bytes) in members {
        zip.start_file(name.as_str(), options).unwrap();
        std::io::Write::write_all(&mut zip, bytes).unwrap();
    }
    zip.finish().unwrap();
}

fn png_bytes(dir: &Path, seed: u32) -> Vec<u8> {
    let p = dir.join("tmp.png");
    write_png(&p, 5, 4, pattern(seed));
    std::fs::read(p).unwrap()
}

#[test]
fn ubo2003_zip_reads_in_place_like_the_same_folder() {
    let dir = tempfile::tempdir().unwrap();
    let names = ["tl000 pl000 tv000 pv000.png", "tl015 pl000 tv000 pv000.png", "tl015 pl060 tv030 pv090.png"];
    let folder = dir.path().join("folder");
    std::fs::create_dir(&folder).unwrap();
    let mut members = vec![("UBO_TEST/readme.txt".to_string(), b"ignored".to_vec())];
    for (k, name) in names.iter().enumerate() {
        write_png(&folder.join(name), 5, 4, pattern(k as u32));
        members.push((format!("UBO_TEST/{name}"), png_bytes(dir.path(), k as u32)));
    }
    let zip = dir.path().join("ubo.zip");
    write_zip(&zip, &members);
    let from_zip = decode(&zip);
    let from_folder = decode(&folder);
    assert_eq!(from_zip, from_folder);
    let before = common::entries(dir.path());
    let crop =
        load(&zip, &LoadOptions { crop: Some(Crop { x: 1, y: 1, width: 2, height: 2 }) }, &Silent).unwrap();
    assert_eq!(crop.rgb(2, 0, 0), from_folder.rgb(2, 1, 1));
    assert_eq!(common::entries(dir.path()), before, "nothing unpacked to disk");
}

#[test]
fn zip_with_a_bad_member_names_it() {
    let dir = tempfile::tempdir().unwrap();
    let good = png_bytes(dir.path(), 1);
    type Members = Vec<(String, Vec<u8>)>;
    let cases: Vec<(Members, &str)> = vec![
        (
            vec![
                ("tl000 pl000 tv000 pv000.png".into(), good.clone()),
                ("tl015 pl000 tv000 pv000.png".into(), good[..good.len() / 2].to_vec()),
            ],
            "member 'tl015 pl000 tv000 pv000.png'",
        ),
        (
            vec![("tl000 pl000 tv000 pv000.png".into(), good.clone()), ("photo.png".into(), good.clone())],
            "member 'photo.png'",
        ),
        (
            vec![
                ("tl000 pl000 tv000 pv000.png".into(), good.clone()),
                ("tl000_pl000_tv000_pv000.png".into(), good.clone()),
            ],
            "same light and view",
        ),
        (vec![("readme.txt".into(), b"x".to_vec())], "no images"),
    ];
    for (k, (members, needle)) in cases.into_iter().enumerate() {
        let zip = dir.path().join(format!("bad{k}.zip"));
        write_zip(&zip, &members);
        let out = btfsynth(&["info", zip.to_str().unwrap()]);
        assert_one_line_error(&out, needle);
        assert!(String::from_utf8_lossy(&out.stderr).contains(&format!("bad{k}.zip")));
    }
    // Not a zip at all, behind a .zip name.
    let fake = tmp_file(dir.path(), "fake.zip", b"PK\x03\x04 garbage");
    assert_one_line_error(&btfsynth(&["info", fake.to_str().unwrap()]), "zip directory");
}

#[test]
fn atrium_hdr_members_follow_btf_extractor_orientation() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (3u32, 2u32);
    let pixels: Vec<image::Rgb<f32>> = (0..w * h).map(|i| image::Rgb([i as f32 * 0.5, 1.0, 2.0])).collect();
    let mut standard = Vec::new();
    image::codecs::hdr::HdrEncoder::new(&mut standard).encode(&pixels, w as usize, h as usize).unwrap();
    let text = String::from_utf8_lossy(&standard).into_owned();
    let line = format!("-Y {h} +X {w}");
    assert!(text.contains(&line));
    let atrium = text.replacen(&line, &format!("+X {w} -Y {h}"), 1);
    let mut atrium_bytes = standard.clone();
    let at = text.find(&line).unwrap();
    atrium_bytes[at..at + line.len()].copy_from_slice(&atrium.as_bytes()[at..at + line.len()]);
    let zip = dir.path().join("atrium.zip");
    write_zip(
        &zip,
        &[
            ("CEILING/tl000 pl000 tv000 pv000.hdr".into(), standard),
            ("CEILING/tl015 pl000 tv000 pv000.hdr".into(), atrium_bytes),
        ],
    );
    let stack = decode(&zip);
    for y in 0..h as usize {
        for x in 0..w as usize {
            let v = (y * w as usize + x) as f32 * 0.5;
            assert_eq!(stack.rgb(0, x, y), [v, 1.0, 2.0], "standard orientation");
            // Read as standard scan lines, then flipped upside down.
            let flipped = ((h as usize - 1 - y) * w as usize + x) as f32 * 0.5;
            assert_eq!(stack.rgb(1, x, y)[0], flipped, "ATRIUM orientation");
        }
    }
}

// ---------------------------------------------------------------------------------------
// UTIA: XYZ EXRs in per-view folders.

#[test]
fn utia_xyz_exr_d65_white_is_srgb_white() {
    let dir = tempfile::tempdir().unwrap();
    let view = dir.path().join("tv000_pv000");
    std::fs::create_dir(&view).unwrap();
    let white = d65_white_xyz();
    let data: Vec<f16> = (0..4 * 3).flat_map(|_| white.map(f16::from_f32)).collect();
    btfsynth::btf::image_io::write_exr(&view.join("tl000_pl000.exr"), 4, 3, &data).unwrap();
    // A colour: XYZ of linear sRGB (0.2, 0.5, 0.1) (IEC 61966-2-1 forward matrix).
    let rgb = [0.2f32, 0.5, 0.1];
    let m = [[0.4124, 0.3576, 0.1805], [0.2126, 0.7152, 0.0722], [0.0193, 0.1192, 0.9505]];
    let xyz = m.map(|r| r[0] * rgb[0] + r[1] * rgb[1] + r[2] * rgb[2]);
    let data: Vec<f16> = (0..4 * 3).flat_map(|_| xyz.map(f16::from_f32)).collect();
    btfsynth::btf::image_io::write_exr(&view.join("tl030_pl090.exr"), 4, 3, &data).unwrap();
    let stack = decode(dir.path());
    let i = stack.pairs().iter().position(|p| p.light.theta == 0.0).unwrap();
    for c in stack.rgb(i, 2, 1) {
        assert!((c - 1.0).abs() < 2e-3, "D65 white → {:?}", stack.rgb(i, 2, 1));
    }
    let got = stack.rgb(1 - i, 0, 0);
    for c in 0..3 {
        assert!((got[c] - rgb[c]).abs() < 2e-3, "{got:?} vs {rgb:?}");
    }
    // The same image outside a UTIA folder is RGB, read as is.
    let flat = dir.path().join("flat");
    std::fs::create_dir(&flat).unwrap();
    btfsynth::btf::image_io::write_exr(&flat.join("tl000_pl000_tv000_pv000.exr"), 4, 3, &data).unwrap();
    assert!((decode(&flat).rgb(0, 0, 0)[0] - f16::from_f32(xyz[0]).to_f32()).abs() < 1e-6);
}

// ---------------------------------------------------------------------------------------
// Seeded mutations of valid files: every variant is read without a panic.

#[test]
fn mutated_files_never_panic() {
    use rand::{Rng, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(13);
    let seeds: Vec<Vec<u8>> = {
        let d = Spec::small("!DFMF08FCR");
        let nr = Spec::small("!DFMF08FC");
        let mut f = Spec::small("!FMF12FCER");
        f.version = 2;
        let b = Spec::small("!BDIF06R2!");
        vec![
            dfmf(&d, 11, 2, &channel_data(&d, 2, 1), false).b,
            dfmf(&nr, 0, 4, &channel_data(&nr, 3, 2), true).b,
            fmf(&f, 2, 2, true, true).0.b,
            fmf(&Spec::small("!FMF06FC"), 8, 1, false, false).0.b,
            bdi(&b, 1, true).0.b,
            bdi(&b, 2, false).0.b,
        ]
    };
    let path = Path::new("mutant.btf");
    let started = std::time::Instant::now();
    let (mut accepted, mut rejected) = (0, 0);
    let ((), largest) = watched(|| {
        for n in 0..60_000 {
            let seed = &seeds[n % seeds.len()];
            let bytes = mutate(seed, &mut rng);
            let result = std::panic::catch_unwind(|| try_read(path, bytes.clone()));
            match result {
                Ok(Ok(stack)) => {
                    accepted += 1;
                    assert!(stack.pixels().iter().all(|v| v.is_finite()), "variant {n}: non-finite pixels");
                }
                Ok(Err(e)) => {
                    rejected += 1;
                    assert!(e.starts_with("mutant.btf: ") && !e.contains('\n'), "variant {n}: {e}");
                }
                Err(_) => panic!("variant {n} panicked: {:?}", bytes),
            }
        }
    });
    assert!(largest < 64 << 20, "a mutant allocated {largest} bytes");
    assert!(accepted > 1000 && rejected > 10_000, "accepted {accepted}, rejected {rejected}");
    eprintln!(
        "mutation test: {accepted} accepted, {rejected} rejected in {:.1} s",
        started.elapsed().as_secs_f64()
    );

    // Zip archives: mutated bytes on disk, read through the archive reader.
    let dir = tempfile::tempdir().unwrap();
    let seed_zip = dir.path().join("seed.zip");
    let members: Vec<(String, Vec<u8>)> =
        (0..3).map(|k| (format!("M/tl0{k}0 pl000 tv000 pv000.png"), png_bytes(dir.path(), k))).collect();
    write_zip(&seed_zip, &members);
    let seed = std::fs::read(&seed_zip).unwrap();
    let mutant = dir.path().join("mutant.zip");
    let (mut accepted, mut rejected) = (0, 0);
    let ((), largest) = watched(|| {
        for n in 0..3_000 {
            let bytes = mutate(&seed, &mut rng);
            std::fs::write(&mutant, &bytes).unwrap();
            let result = std::panic::catch_unwind(|| load(&mutant, &LoadOptions::default(), &Silent));
            match result {
                Ok(Ok(_)) => accepted += 1,
                Ok(Err(e)) => {
                    rejected += 1;
                    assert!(
                        e.to_string().contains("mutant.zip") && !e.to_string().contains('\n'),
                        "zip variant {n}: {e}"
                    );
                }
                Err(_) => panic!("zip variant {n} panicked"),
            }
        }
    });
    assert!(largest < 80 << 20, "a zip mutant allocated {largest} bytes");
    assert!(accepted > 10 && rejected > 100, "zips: accepted {accepted}, rejected {rejected}");
    eprintln!(
        "zip mutations: {accepted} accepted, {rejected} rejected; total {:.1} s",
        started.elapsed().as_secs_f64()
    );

    fn mutate(seed: &[u8], rng: &mut impl Rng) -> Vec<u8> {
        let mut b = seed.to_vec();
        for _ in 0..rng.random_range(1..4) {
            if b.is_empty() {
                b.push(rng.random());
            }
            let at = rng.random_range(0..b.len());
            match rng.random_range(0..6) {
                0 => b[at] ^= 1 << rng.random_range(0..8),
                1 => b[at] = rng.random(),
                2 if at + 4 <= b.len() => {
                    let v: u32 =
                        [0, 1, 2, 255, 0x7fff_ffff, u32::MAX, b.len() as u32][rng.random_range(0..7)];
                    b[at..at + 4].copy_from_slice(&v.to_le_bytes());
                }
                3 => b.truncate(at),
                4 => b.insert(at, rng.random()),
                _ => {
                    b.remove(at);
                }
            }
        }
        b
    }
}

#[test]
fn analyze_accepts_a_btf_crop() {
    let dir = tempfile::tempdir().unwrap();
    let stack = small_stack(DirectionSet::Grid(4), 24);
    let path = dir.path().join("s.btf");
    let options = ToBtfOptions {
        components: 8,
        model: ColourModel::Rgb,
        scalar: Scalar::F16,
        rotation_block: true,
        rotations: vec![],
        seed: 0,
    };
    to_btf(&stack, &path, &options, &Silent).unwrap();
    let out = dir.path().join("analysis");
    let r = btfsynth(&[
        "-q",
        "analyze",
        path.to_str().unwrap(),
        "--crop",
        "2,2,20,20",
        "--textons",
        "8",
        "--levels",
        "1",
        "--selected",
        "8",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let info: serde_json::Value =
        serde_json::from_slice(&btfsynth(&["info", out.to_str().unwrap(), "--json"]).stdout).unwrap();
    assert_eq!((info["width"].as_u64(), info["images"].as_u64()), (Some(20), Some(16)));
}
