//! Hostile files: every loader meets at least 10,000 seeded variants of a valid fixture
//! (truncation at every offset of the header, bit flips, overwritten bytes and fields, huge
//! and odd numbers in place of counts, deleted, repeated and inserted runs, random bytes;
//! for PNG also with the chunk checksums repaired, so the damage reaches the decoder). Each
//! variant must end in `Ok` or in one error of one line, never a panic, and no single
//! allocation may exceed a small multiple of what the file could hold: counts are checked
//! against the bytes present before anything is allocated for them.
//!
//! Allocations are measured by a global allocator that records, per thread, the largest
//! request; loaders that use rayon run on a one-thread pool so that their work stays on the
//! measuring thread.

use btfsynth::analysis::npy;
use btfsynth::btf::image_io;
use btfsynth::mesh::{obj, off, ply, prepare, LoadOptions, Mesh, Soup};
use glam::Vec3;
use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::{Cell, RefCell};
use std::os::unix::ffi::{OsStrExt, OsStringExt};
use std::path::Path;
use std::time::Instant;

struct Tracking;

thread_local! {
    static LARGEST: Cell<usize> = const { Cell::new(0) };
    static IN_VARIANT: Cell<bool> = const { Cell::new(false) };
    static LAST_PANIC: RefCell<String> = const { RefCell::new(String::new()) };
}

fn note(size: usize) {
    let _ = LARGEST.try_with(|l| l.set(l.get().max(size)));
}

// SAFETY: every call is forwarded unchanged to the system allocator.
unsafe impl GlobalAlloc for Tracking {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        note(layout.size());
        unsafe { System.alloc(layout) }
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        note(layout.size());
        unsafe { System.alloc_zeroed(layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        note(new_size);
        unsafe { System.realloc(ptr, layout, new_size) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static ALLOCATOR: Tracking = Tracking;

/// Variants per format (at least 10,000 each).
const VARIANTS: usize = 10_000;
/// Bytes any loader may allocate at once whatever the file (decoder tables, buffers).
const SLACK: usize = 1 << 20;
/// Allocation allowed per byte of a mesh, array or manifest file.
const PER_BYTE: usize = 64;
/// Allocation allowed per byte of an image file: the decoded pixels (at most 1100 bytes per
/// file byte, see `image_io`) in the few forms decoding passes through.
const PER_IMAGE_BYTE: usize = 8 * 1100;

/// What a loader did with one variant.
enum Outcome {
    Ok,
    Error,
}

/// Runs the loader on every variant of `valid` and fails the test on any panic, any error
/// message that is empty or spans lines, or any allocation beyond `per_byte` × the
/// variant's length + [`SLACK`].
fn torture(
    format: &str,
    valid: &[u8],
    variants: impl Iterator<Item = (String, Vec<u8>)>,
    per_byte: usize,
    load: impl Fn(&[u8]) -> Result<(), String>,
) {
    quiet_panics();
    let started = Instant::now();
    assert!(load(valid).is_ok(), "{format}: the fixture itself loads: {:?}", load(valid).err());
    let (mut ok, mut errors, mut failures) = (0usize, 0usize, Vec::new());
    let (mut largest_seen, mut worst_ratio) = (0usize, 0.0f64);
    let mut count = 0;
    for (what, bytes) in variants {
        count += 1;
        IN_VARIANT.with(|f| f.set(true));
        LARGEST.with(|l| l.set(0));
        let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| load(&bytes)));
        let largest = LARGEST.with(|l| l.get());
        IN_VARIANT.with(|f| f.set(false));
        let outcome = match result {
            Ok(Ok(())) => Ok(Outcome::Ok),
            Ok(Err(message)) if !message.trim().is_empty() && message.lines().count() == 1 => {
                Ok(Outcome::Error)
            }
            Ok(Err(message)) => Err(format!("an error of {} lines: {message:?}", message.lines().count())),
            Err(_) => Err(format!("panic: {}", LAST_PANIC.with(|p| p.borrow().clone()))),
        };
        let limit = per_byte * bytes.len() + SLACK;
        largest_seen = largest_seen.max(largest);
        worst_ratio = worst_ratio.max(largest as f64 / bytes.len().max(1) as f64);
        match outcome {
            Ok(_) if largest > limit => failures
                .push(format!("{what}: allocated {largest} bytes at once for a {}-byte file", bytes.len())),
            Ok(Outcome::Ok) => ok += 1,
            Ok(Outcome::Error) => errors += 1,
            Err(why) => failures.push(format!("{what}: {why}")),
        }
    }
    eprintln!(
        "{format}: {count} variants of a {}-byte file ({ok} loaded, {errors} refused) in {:.2} s; largest \
         single allocation {largest_seen} bytes, at most {worst_ratio:.0} bytes per file byte",
        valid.len(),
        started.elapsed().as_secs_f64()
    );
    assert!(count >= VARIANTS, "{format}: only {count} variants");
    assert!(
        failures.is_empty(),
        "{format}: {} of {count} variants failed, e.g.:\n{}",
        failures.len(),
        failures[..failures.len().min(8)].join("\n")
    );
}

/// Stores a panic's message instead of printing it while a variant runs (the test reports
/// it); panics elsewhere (the tests' own assertions) print as usual.
fn quiet_panics() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        let default = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            if IN_VARIANT.with(|f| f.get()) {
                LAST_PANIC.with(|p| *p.borrow_mut() = info.to_string());
            } else {
                default(info);
            }
        }));
    });
}

/// A small seeded generator (SplitMix64).
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
}

/// Numbers that break counts and sizes when they replace one.
const ODD_NUMBERS: [&str; 12] = [
    "0",
    "-1",
    "255",
    "65536",
    "2147483648",
    "4294967295",
    "4294967296",
    "18446744073709551615",
    "99999999999999999999999",
    "1e308",
    "nan",
    "-inf",
];

/// Values that break binary counts and sizes.
const EXTREMES: [u64; 7] = [0, u64::MAX, i64::MAX as u64, 1 << 63, i32::MAX as u64, 1 << 31, u32::MAX as u64];

/// Bytes that are special to some parser.
const ODD_BYTES: [u8; 10] = [0, 0xFF, 0x7F, 0x80, b'\n', b' ', b'-', b'9', b'.', b'#'];

/// `count` seeded variants of `valid`: first a truncation at every offset of its first
/// `header` bytes, then random damage of the kinds listed in the module documentation.
fn variants(
    valid: &[u8],
    header: usize,
    count: usize,
    seed: u64,
) -> impl Iterator<Item = (String, Vec<u8>)> + '_ {
    let header = header.min(valid.len());
    let truncations = (0..header).map(move |at| (format!("truncated at {at}"), valid[..at].to_vec()));
    let mut rng = Rng(seed);
    let damaged = (0..count.saturating_sub(header)).map(move |i| {
        let mut b = valid.to_vec();
        let what = damage(&mut rng, &mut b, header);
        (format!("seed {seed} variant {i}: {what}"), b)
    });
    truncations.chain(damaged)
}

/// Applies one random kind of damage to `b` (mostly inside its first `header` bytes, where
/// the counts are) and says what it did.
fn damage(rng: &mut Rng, b: &mut Vec<u8>, header: usize) -> String {
    let len = b.len().max(1);
    let at = if rng.below(3) > 0 { rng.below(header.max(1)) } else { rng.below(len) }
        .min(b.len().saturating_sub(1));
    match rng.below(9) {
        0 => {
            let flips = 1 + rng.below(8);
            for _ in 0..flips {
                let k = rng.below(len).min(b.len().saturating_sub(1));
                if let Some(byte) = b.get_mut(k) {
                    *byte ^= 1 << rng.below(8);
                }
            }
            format!("{flips} bit flips")
        }
        1 => {
            let v = ODD_BYTES[rng.below(ODD_BYTES.len())];
            if let Some(byte) = b.get_mut(at) {
                *byte = v;
            }
            format!("byte {at} set to {v:#04x}")
        }
        2 => {
            // A number in the text replaced: the header's counts and sizes.
            let starts: Vec<usize> = (0..b.len().min(header.max(64)))
                .filter(|&k| b[k].is_ascii_digit() && (k == 0 || !b[k - 1].is_ascii_digit()))
                .collect();
            if starts.is_empty() {
                return damage(rng, b, header);
            }
            let start = starts[rng.below(starts.len())];
            let end = (start..b.len()).find(|&k| !b[k].is_ascii_digit()).unwrap_or(b.len());
            let odd = ODD_NUMBERS[rng.below(ODD_NUMBERS.len())];
            b.splice(start..end, odd.bytes());
            format!("number at {start} replaced by {odd}")
        }
        3 => {
            // A binary field overwritten with an extreme value, in either byte order.
            let width = [1, 2, 4, 8][rng.below(4)];
            let value = EXTREMES[rng.below(EXTREMES.len())];
            let big = rng.below(2) == 1;
            let bytes = if big {
                value.to_be_bytes()[8 - width..].to_vec()
            } else {
                value.to_le_bytes()[..width].to_vec()
            };
            let end = (at + width).min(b.len());
            b[at..end].copy_from_slice(&bytes[..end - at]);
            format!(
                "{width} bytes at {at} set to {value:#x} ({})",
                if big { "big-endian" } else { "little-endian" }
            )
        }
        4 => {
            let end = (at + 1 + rng.below(32)).min(b.len());
            b.drain(at..end);
            format!("bytes {at}..{end} deleted")
        }
        5 => {
            let end = (at + 1 + rng.below(64)).min(b.len());
            let run = b[at..end].to_vec();
            let times = 1 + rng.below(4);
            for _ in 0..times {
                b.splice(at..at, run.iter().copied());
            }
            format!("bytes {at}..{end} repeated {times} times")
        }
        6 => {
            let n = 1 + rng.below(16);
            let noise: Vec<u8> = (0..n).map(|_| rng.next() as u8).collect();
            b.splice(at..at, noise);
            format!("{n} random bytes inserted at {at}")
        }
        7 => {
            let cut = rng.below(len);
            b.truncate(cut);
            format!("truncated at {cut}")
        }
        _ => {
            let n = rng.below(2 * len);
            *b = (0..n).map(|_| rng.next() as u8).collect();
            format!("{n} random bytes")
        }
    }
}

/// Parses and validates a mesh as `mesh::load` does.
fn load_mesh(
    parse: fn(&[u8], &Path) -> btfsynth::Result<Soup>,
    name: &str,
) -> impl Fn(&[u8]) -> Result<(), String> + '_ {
    move |bytes| {
        let path = Path::new(name);
        let soup = parse(bytes, path).map_err(|e| e.to_string())?;
        prepare::prepare(soup, path, &LoadOptions::default()).map(|_| ()).map_err(|e| e.to_string())
    }
}

/// A square pyramid: 5 vertices, a quad base and four triangles.
fn pyramid() -> Mesh {
    let p = vec![
        Vec3::new(0.0, 0.0, 0.0),
        Vec3::new(1.0, 0.0, 0.0),
        Vec3::new(1.0, 1.0, 0.0),
        Vec3::new(0.0, 1.0, 0.0),
        Vec3::new(0.5, 0.5, 1.0),
    ];
    let t = vec![[0, 2, 1], [0, 3, 2], [0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]];
    Mesh::new(p, t).expect("the pyramid is valid")
}

#[test]
fn obj_files() {
    let valid = b"# a square pyramid\nmtllib none.mtl\no pyramid\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n\
        v 0.5 0.5 1\nvt 0 0\nvt 1 0\nvn 0 0 -1\ng base\nusemtl stone\nf 1/1/1 4/2/1 3/1/1 2/1/1\n\
        g sides\nf 1 2 5\nf 2/2 3/1 5/2\nf -3 -2 -1\nf 4//1 1//1 5//1\n";
    torture(
        "OBJ",
        valid,
        variants(valid, valid.len(), VARIANTS, 1),
        PER_BYTE,
        load_mesh(obj::parse, "f.obj"),
    );
}

#[test]
fn off_files() {
    let valid = b"OFF\n# a square pyramid\n5 5 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n0.5 0.5 1\n\
        4 0 3 2 1\n3 0 1 4\n3 1 2 4\n3 2 3 4\n3 3 0 4 255 0 0\n";
    torture(
        "OFF",
        valid,
        variants(valid, valid.len(), VARIANTS, 2),
        PER_BYTE,
        load_mesh(off::parse, "f.off"),
    );
}

#[test]
fn ascii_ply_files() {
    let valid = b"ply\nformat ascii 1.0\ncomment a square pyramid\nelement vertex 5\nproperty float x\n\
        property float y\nproperty double z\nproperty uchar red\nelement face 5\n\
        property list uchar int vertex_indices\nproperty uchar flags\nelement edge 1\nproperty int a\n\
        property int b\nend_header\n0 0 0 1\n1 0 0 2\n1 1 0 3\n0 1 0 4\n0.5 0.5 1 5\n4 0 3 2 1 0\n\
        3 0 1 4 0\n3 1 2 4 0\n3 2 3 4 0\n3 3 0 4 7\n0 1\n";
    let header = valid.windows(10).position(|w| w == b"end_header").unwrap() + 11;
    torture(
        "PLY (ASCII)",
        valid,
        variants(valid, header, VARIANTS, 3),
        PER_BYTE,
        load_mesh(ply::read::parse, "f.ply"),
    );
}

#[test]
fn binary_ply_files() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("pyramid.ply");
    let flags = [1u8, 2, 3, 4, 5];
    let property = ply::VertexProperty { name: "flags", data: ply::PropertyData::UChar(&flags) };
    ply::write(&path, &pyramid().with_normals(), &[property], &["a square pyramid"]).unwrap();
    let little = std::fs::read(&path).unwrap();
    let header = little.windows(10).position(|w| w == b"end_header").unwrap() + 11;
    let load = load_mesh(ply::read::parse, "f.ply");
    torture("PLY (binary little-endian)", &little, variants(&little, header, VARIANTS, 4), PER_BYTE, &load);
    let big = big_endian(&little, header);
    torture("PLY (binary big-endian)", &big, variants(&big, header, VARIANTS, 5), PER_BYTE, &load);
}

/// The binary little-endian pyramid written by `ply::write` (floats x y z nx ny nz, uchar
/// flags; faces as uchar count, int indices) converted to big-endian.
fn big_endian(little: &[u8], header: usize) -> Vec<u8> {
    let text = String::from_utf8(little[..header].to_vec())
        .unwrap()
        .replace("binary_little_endian", "binary_big_endian");
    let mut out = text.into_bytes();
    let mut body = &little[header..];
    for _ in 0..5 {
        for _ in 0..6 {
            out.extend(body[..4].iter().rev());
            body = &body[4..];
        }
        out.push(body[0]);
        body = &body[1..];
    }
    while !body.is_empty() {
        out.push(body[0]);
        body = &body[1..];
        for _ in 0..3 {
            out.extend(body[..4].iter().rev());
            body = &body[4..];
        }
    }
    out
}

#[test]
fn npy_arrays() {
    let floats: Vec<f32> = (0..12).map(|v| v as f32 * 0.25).collect();
    let valid = npy::encode(&[3, 4], &floats).unwrap();
    let header = 10 + u16::from_le_bytes([valid[8], valid[9]]) as usize;
    // As `npy::read` reports a file's problems.
    let load = |b: &[u8]| {
        npy::decode::<f32>(b).map(|_| ()).map_err(|m| btfsynth::Error::format("f.npy", m).to_string())
    };
    torture(".npy (f32)", &valid, variants(&valid, header, VARIANTS, 6), PER_BYTE, load);
    let labels: Vec<u16> = (0..8).collect();
    let valid = npy::encode(&[2, 2, 2], &labels).unwrap();
    let load = |b: &[u8]| {
        npy::decode::<u16>(b).map(|_| ()).map_err(|m| btfsynth::Error::format("f.npy", m).to_string())
    };
    torture(".npy (u16)", &valid, variants(&valid, header, VARIANTS, 7), PER_BYTE, load);
}

#[test]
fn npy_arrays_with_nan_or_infinity_are_refused() {
    for bad in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
        let mut floats: Vec<f32> = (0..12).map(|v| v as f32 * 0.25).collect();
        floats[7] = bad;
        let e = npy::decode::<f32>(&npy::encode(&[3, 4], &floats).unwrap()).unwrap_err();
        assert!(e.contains("value 7 is NaN or infinite"), "{e}");
        let halves: Vec<half::f16> = floats.iter().map(|&v| half::f16::from_f32(v)).collect();
        let e = npy::decode::<half::f16>(&npy::encode(&[12], &halves).unwrap()).unwrap_err();
        assert!(e.contains("value 7 is NaN or infinite"), "{e}");
    }
}

/// Runs `f` on a one-thread rayon pool, so that the loaders' parallel work is measured.
fn on_one_thread<T: Send>(f: impl FnOnce() -> T + Send) -> T {
    thread_local! {
        static POOL: rayon::ThreadPool = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
    }
    POOL.with(|pool| pool.install(f))
}

/// Loads the stack at `path` on a one-thread pool, and carries its largest allocation and
/// any panic back to the calling (measuring) thread.
fn load_stack(path: &Path) -> Result<(), String> {
    let (result, largest) = on_one_thread(|| {
        LARGEST.with(|l| l.set(0));
        IN_VARIANT.with(|f| f.set(true));
        let load = || {
            let loaded = btfsynth::btf::load(path, &Default::default(), &btfsynth::progress::Silent);
            loaded.map(|_| ()).map_err(|e| e.to_string())
        };
        let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(load));
        IN_VARIANT.with(|f| f.set(false));
        let result = result.map_err(|_| LAST_PANIC.with(|p| p.borrow().clone()));
        (result, LARGEST.with(|l| l.get()))
    });
    note(largest);
    match result {
        Ok(loaded) => loaded,
        Err(panic) => panic!("{panic}"),
    }
}

#[test]
fn btf_json_manifests() {
    let dir = tempfile::tempdir().unwrap();
    for (name, seed) in [("a.png", 1), ("b.png", 2)] {
        image::RgbImage::from_fn(4, 4, |x, y| image::Rgb([(x * 60) as u8, (y * 60) as u8, seed * 90]))
            .save(dir.path().join(name))
            .unwrap();
    }
    let valid = br#"{"images": [
  {"file": "a.png", "light": [15, 0], "view": [0, 0]},
  {"file": "b.png", "light": [45.5, 270], "view": [30, 90]}
], "source": {"generator": "hand"}}"#;
    // Each variant is a new file: overwriting one (truncating it) makes ext4 flush it to
    // disk, a hundred times slower. A manifest is read by the same code whatever its name.
    let written = Cell::new(0);
    let load = |bytes: &[u8]| {
        written.set(written.get() + 1);
        let manifest = dir.path().join(format!("btf-{}.json", written.get()));
        std::fs::write(&manifest, bytes).map_err(|e| e.to_string())?;
        let loaded = load_stack(&manifest);
        let _ = std::fs::remove_file(&manifest);
        loaded
    };
    torture("btf.json", valid, variants(valid, valid.len(), VARIANTS, 8), PER_BYTE, load);
}

#[test]
fn bonn_and_utia_file_names() {
    let dir = tempfile::tempdir().unwrap();
    let stack = dir.path().join("stack");
    std::fs::create_dir_all(stack.join("tv030_pv090")).unwrap();
    let png = |path: &Path| image::RgbImage::from_pixel(2, 2, image::Rgb([9, 99, 199])).save(path).unwrap();
    png(&stack.join("tv030_pv090/tl045_pl180.png"));
    let flat = "tl015_pl000_tv000_pv000.png";
    png(&stack.join(flat));
    let current = RefCell::new(std::ffi::OsString::from(flat));
    // The variants are file names. Damage that a file system cannot store ('/', NUL, the
    // names "." and "..", the empty name, the UTIA folder's name) becomes a name it can.
    let load = |bytes: &[u8]| {
        let mut name: Vec<u8> = bytes.iter().map(|&c| if c == b'/' || c == 0 { b'_' } else { c }).collect();
        let stored = |n: &[u8]| n == current.borrow().as_encoded_bytes();
        while name.is_empty()
            || name == b"."
            || name == b".."
            || (stack.join(std::ffi::OsStr::from_bytes(&name)).exists() && !stored(&name))
        {
            name.insert(0, b'x');
        }
        let name = std::ffi::OsString::from_vec(name);
        std::fs::rename(stack.join(&*current.borrow()), stack.join(&name)).map_err(|e| e.to_string())?;
        *current.borrow_mut() = name;
        load_stack(&stack)
    };
    torture(
        "Bonn/UTIA names",
        flat.as_bytes(),
        variants(flat.as_bytes(), flat.len(), VARIANTS, 9),
        PER_BYTE,
        load,
    );
}

/// An image file's bytes loaded as `decode_rgb` does for `name`.
fn load_image(name: &str) -> impl Fn(&[u8]) -> Result<(), String> + '_ {
    move |bytes| image_io::decode_rgb(bytes, Path::new(name)).map(|_| ()).map_err(|e| e.to_string())
}

/// Recomputes every PNG chunk's CRC, so that damage gets past the checksums.
fn repair_png_checksums(b: &mut [u8]) {
    let mut at = 8;
    while at + 12 <= b.len() {
        let len = u32::from_be_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]]) as usize;
        let Some(end) = (at + 8).checked_add(len).filter(|&e| e + 4 <= b.len()) else { return };
        let crc = crc32(&b[at + 4..end]);
        b[end..end + 4].copy_from_slice(&crc.to_be_bytes());
        at = end + 4;
    }
}

fn crc32(bytes: &[u8]) -> u32 {
    let mut crc = !0u32;
    for &byte in bytes {
        crc ^= u32::from(byte);
        for _ in 0..8 {
            crc = if crc & 1 == 1 { (crc >> 1) ^ 0xEDB8_8320 } else { crc >> 1 };
        }
    }
    !crc
}

fn encoded(image: image::DynamicImage, format: image::ImageFormat) -> Vec<u8> {
    let mut bytes = std::io::Cursor::new(Vec::new());
    image.write_to(&mut bytes, format).unwrap();
    bytes.into_inner()
}

fn test_image(w: u32, h: u32) -> image::RgbImage {
    image::RgbImage::from_fn(w, h, |x, y| {
        image::Rgb([(x * 37 % 256) as u8, (y * 53 % 256) as u8, ((x + y) * 17 % 256) as u8])
    })
}

#[test]
fn png_images() {
    let valid = encoded(test_image(8, 6).into(), image::ImageFormat::Png);
    torture("PNG", &valid, variants(&valid, 64, VARIANTS, 10), PER_IMAGE_BYTE, load_image("f.png"));
    let repaired = variants(&valid, 64, VARIANTS, 11).map(|(what, mut b)| {
        repair_png_checksums(&mut b);
        (format!("{what}, checksums repaired"), b)
    });
    torture("PNG (checksums repaired)", &valid, repaired, PER_IMAGE_BYTE, load_image("f.png"));
    let deep = image::DynamicImage::ImageRgb16(image::ImageBuffer::from_fn(5, 3, |x, y| {
        image::Rgb([x as u16 * 9000, y as u16 * 20000, 7])
    }));
    let valid = encoded(deep, image::ImageFormat::Png);
    let repaired = variants(&valid, 64, VARIANTS, 12).map(|(what, mut b)| {
        repair_png_checksums(&mut b);
        (what, b)
    });
    torture("PNG (16-bit, checksums repaired)", &valid, repaired, PER_IMAGE_BYTE, load_image("f.png"));
}

#[test]
fn jpeg_images() {
    let valid = encoded(test_image(16, 16).into(), image::ImageFormat::Jpeg);
    torture("JPEG", &valid, variants(&valid, 700, VARIANTS, 13), PER_IMAGE_BYTE, load_image("f.jpg"));
}

#[test]
fn every_truncation_of_a_jpeg_is_refused() {
    let valid = encoded(test_image(24, 16).into(), image::ImageFormat::Jpeg);
    let load = load_image("f.jpg");
    assert!(load(&valid).is_ok());
    // Decoders paint missing rows grey without an error; the loader must not.
    for keep in 0..valid.len() {
        let e = load(&valid[..keep]).expect_err(&format!("{keep} of {} bytes", valid.len()));
        assert_eq!(e.lines().count(), 1, "{e}");
    }
    // Bytes after the end-of-image marker are no harm (some cameras add them).
    let mut trailing = valid.clone();
    trailing.extend_from_slice(b"\0\0trailer");
    assert!(load(&trailing).is_ok());
}

#[test]
fn exr_images() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("f.exr");
    let data: Vec<half::f16> = (0..8 * 8 * 3).map(|v| half::f16::from_f32(v as f32 / 64.0)).collect();
    image_io::write_exr(&path, 8, 8, &data).unwrap();
    let zip = std::fs::read(&path).unwrap();
    torture("EXR (ZIP)", &zip, variants(&zip, 400, VARIANTS, 14), PER_IMAGE_BYTE, load_image("f.exr"));
    use exr::prelude::{Encoding, Image, SpecificChannels, Vec2, WritableImage};
    let channels = SpecificChannels::rgb(|Vec2(x, y): Vec2<usize>| (x as f32 / 4.0, y as f32 / 4.0, 0.5f32));
    Image::from_encoded_channels((4, 4), Encoding::UNCOMPRESSED, channels).write().to_file(&path).unwrap();
    let raw = std::fs::read(&path).unwrap();
    torture(
        "EXR (uncompressed, f32)",
        &raw,
        variants(&raw, 400, VARIANTS, 15),
        PER_IMAGE_BYTE,
        load_image("f.exr"),
    );
}

#[test]
fn surface_maps() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("surface.ply");
    let mesh = pyramid().with_normals();
    let n = mesh.vertex_count();
    let s: Vec<f32> = vec![1.0; n];
    let zeros: Vec<f32> = vec![0.0; n];
    let labels: Vec<u32> = (0..n as u32).collect();
    let uv: Vec<f32> = (0..n).map(|v| v as f32 * 3.0).collect();
    use ply::{PropertyData::*, VertexProperty as P};
    let properties = [
        P { name: "sx", data: Float(&s) },
        P { name: "sy", data: Float(&zeros) },
        P { name: "sz", data: Float(&zeros) },
        P { name: "texton", data: UInt(&labels) },
        P { name: "u", data: Float(&uv) },
        P { name: "v", data: Float(&uv) },
    ];
    let comments = [
        "btfsynth surface",
        "analysis analysis",
        "analysis-fingerprint fnv1a64:0123456789abcdef",
        "texel 0.25",
        "params {}",
    ];
    ply::write(&path, &mesh, &properties, &comments).unwrap();
    let valid = std::fs::read(&path).unwrap();
    let header = valid.windows(10).position(|w| w == b"end_header").unwrap() + 11;
    let load = |b: &[u8]| {
        btfsynth::synth::surface_map::parse_surface_ply(b, Path::new("s.ply"))
            .map(|_| ())
            .map_err(|e| e.to_string())
    };
    torture("surface map PLY", &valid, variants(&valid, header, VARIANTS, 16), PER_BYTE, load);
}

#[test]
fn the_allocation_measure_sees_a_large_request() {
    LARGEST.with(|l| l.set(0));
    let big = std::hint::black_box(vec![1u8; 3 << 20]);
    assert!(LARGEST.with(|l| l.get()) >= big.len());
}

#[test]
fn a_png_declaring_a_huge_image_is_refused_before_decoding() {
    let mut png = encoded(test_image(8, 6).into(), image::ImageFormat::Png);
    // IHDR's width and height (bytes 16..24), its checksum repaired: 100000 × 100000 pixels.
    png[16..20].copy_from_slice(&100_000u32.to_be_bytes());
    png[20..24].copy_from_slice(&100_000u32.to_be_bytes());
    repair_png_checksums(&mut png);
    LARGEST.with(|l| l.set(0));
    let e = image_io::decode_rgb(&png, Path::new("huge.png")).unwrap_err().to_string();
    assert!(e.contains("100000x100000 pixels, more than a file of"), "{e}");
    assert!(LARGEST.with(|l| l.get()) < SLACK, "nothing was allocated for the pixels");
}
