//! Bonn UBO2003 and ATRIUM archives: a zip of images named `tl… pl… tv… pv….jpg` (or
//! `.hdr` for ATRIUM HDR, `.png`, `.exr`), read in place, one member per image, without
//! unpacking anything to disk.

use crate::btf::image_io::{crop_image, decoded_to_linear, RgbImage};
use crate::btf::names::pair_from_name;
use crate::btf::source::{resolve_crop, ImageSource};
use crate::btf::{Crop, DirectionPair};
use crate::{Error, Result};
use half::f16;
use std::fs::File;
use std::io::Read;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use zip::ZipArchive;

/// Largest member read (uncompressed): far above any BTF image, far below a zip bomb.
const MAX_MEMBER_BYTES: u64 = 1 << 30;

/// True for a file named `*.zip` or one that starts like a zip archive.
pub fn is_zip(path: &Path) -> bool {
    if !path.is_file() {
        return false;
    }
    if path.extension().is_some_and(|e| e.eq_ignore_ascii_case("zip")) {
        return true;
    }
    let mut magic = [0u8; 4];
    let read = File::open(path).and_then(|mut f| f.read_exact(&mut magic));
    read.is_ok() && magic == *b"PK\x03\x04"
}

/// An archive of Bonn-named images, decoded member by member.
pub struct ZipStack {
    path: PathBuf,
    /// Member indices in the archive, in image order (sorted by name).
    members: Vec<(usize, String)>,
    pairs: Vec<DirectionPair>,
    crop: Crop,
    /// Every image's full size (before the crop).
    size: (usize, usize),
    /// Open archives, reused across images (each parses the central directory once).
    archives: Mutex<Vec<ZipArchive<File>>>,
}

impl ZipStack {
    /// Lists the archive's images and their directions, and reads the first image to learn
    /// the size (and check `crop` against it).
    pub fn open(path: &Path, crop: Option<Crop>) -> Result<Self> {
        let mut archive = open_archive(path)?;
        check_unique_names(path, &archive)?;
        let mut members: Vec<(usize, String)> = (0..archive.len())
            .filter_map(|i| archive.name_for_index(i).map(|n| (i, n.to_string())))
            .filter(|(_, name)| is_image_member(name))
            .collect();
        members.sort_by(|a, b| a.1.cmp(&b.1));
        if members.is_empty() {
            return Err(Error::format(
                path,
                "the archive holds no images named like tl015 pl000 tv000 pv000.jpg",
            ));
        }
        let pairs = members
            .iter()
            .map(|(_, name)| {
                pair_from_name(Path::new(name)).map_err(|e| member_error(path, name, message_of(e)))
            })
            .collect::<Result<Vec<_>>>()?;
        if let Some((a, b)) = crate::btf::directions::first_duplicate(&pairs) {
            return Err(Error::format(
                path,
                format!(
                    "members '{}' and '{}' have the same light and view directions",
                    members[a].1, members[b].1
                ),
            ));
        }
        let first = read_member(path, &mut archive, &members[0])?;
        let crop = resolve_crop(path, crop, first.width, first.height)?;
        let size = (first.width, first.height);
        Ok(ZipStack {
            path: path.to_path_buf(),
            members,
            pairs,
            crop,
            size,
            archives: Mutex::new(vec![archive]),
        })
    }

    fn with_archive<T>(&self, f: impl FnOnce(&mut ZipArchive<File>) -> Result<T>) -> Result<T> {
        let pooled = self.archives.lock().unwrap_or_else(|p| p.into_inner()).pop();
        let mut archive = match pooled {
            Some(a) => a,
            None => open_archive(&self.path)?,
        };
        let result = f(&mut archive);
        self.archives.lock().unwrap_or_else(|p| p.into_inner()).push(archive);
        result
    }
}

impl ImageSource for ZipStack {
    fn path(&self) -> &Path {
        &self.path
    }

    fn width(&self) -> usize {
        self.crop.width as usize
    }

    fn height(&self) -> usize {
        self.crop.height as usize
    }

    fn pairs(&self) -> &[DirectionPair] {
        &self.pairs
    }

    fn decode_image(&self, i: usize, out: &mut [f16]) -> Result<()> {
        let member = &self.members[i];
        let image = self.with_archive(|a| read_member(&self.path, a, member))?;
        if (image.width, image.height) != self.size {
            let (w, h) = self.size;
            return Err(member_error(
                &self.path,
                &member.1,
                format!(
                    "{}x{} pixels, but the first image is {w}x{h}; all images of a stack must have one size",
                    image.width, image.height
                ),
            ));
        }
        let cropped = crop_image(&image, self.crop).map_err(|m| member_error(&self.path, &member.1, m))?;
        out.copy_from_slice(&cropped.data);
        Ok(())
    }
}

fn open_archive(path: &Path) -> Result<ZipArchive<File>> {
    let file = File::open(path).map_err(|e| Error::io(path, e))?;
    ZipArchive::new(file).map_err(|e| Error::format(path, format!("zip directory: {e}")))
}

/// Refuses an archive whose central directory lists one name twice: the zip reader keeps
/// one member per name, so the other image would vanish without a word.
fn check_unique_names(path: &Path, archive: &ZipArchive<File>) -> Result<()> {
    use std::io::{BufReader, Seek, SeekFrom};
    let file = File::open(path).map_err(|e| Error::io(path, e))?;
    let mut reader = BufReader::new(file);
    reader.seek(SeekFrom::Start(archive.central_directory_start())).map_err(|e| Error::io(path, e))?;
    let mut seen = std::collections::HashSet::with_capacity(archive.len());
    let mut header = [0u8; 46];
    // Every header is at least 46 bytes, so the walk ends within the file.
    while reader.read_exact(&mut header).is_ok() && header[..4] == *b"PK\x01\x02" {
        let field = |at: usize| usize::from(u16::from_le_bytes([header[at], header[at + 1]]));
        let (name_len, extra_len, comment_len) = (field(28), field(30), field(32));
        let mut name = vec![0u8; name_len];
        if reader.read_exact(&mut name).is_err() {
            break;
        }
        let name = String::from_utf8_lossy(&name).into_owned();
        if seen.contains(&name) {
            return Err(Error::format(
                path,
                format!("the archive holds two members named '{name}'; which image is meant is unclear"),
            ));
        }
        seen.insert(name);
        if reader.seek_relative((extra_len + comment_len) as i64).is_err() {
            break;
        }
    }
    Ok(())
}

/// An error's message without the path it names (a member name is named by the caller).
fn message_of(e: Error) -> String {
    match e {
        Error::Format { message, .. } => message,
        other => other.to_string(),
    }
}

fn member_error(path: &Path, member: &str, message: impl std::fmt::Display) -> Error {
    Error::format(path, format!("member '{member}': {message}"))
}

/// Image members: a known extension and not hidden (macOS archives add `__MACOSX/._*`).
fn is_image_member(name: &str) -> bool {
    let file = name.rsplit('/').next().unwrap_or(name);
    let ext = file.rsplit_once('.').map(|(_, e)| e.to_ascii_lowercase());
    !name.ends_with('/')
        && !file.starts_with('.')
        && !name.starts_with("__MACOSX/")
        && matches!(ext.as_deref(), Some("jpg" | "jpeg" | "png" | "exr" | "hdr"))
}

/// Reads and decodes one member as linear RGB.
fn read_member(
    path: &Path,
    archive: &mut ZipArchive<File>,
    (index, name): &(usize, String),
) -> Result<RgbImage> {
    let mut file =
        archive.by_index(*index).map_err(|e| member_error(path, name, format!("cannot open: {e}")))?;
    if file.size() > MAX_MEMBER_BYTES {
        return Err(member_error(
            path,
            name,
            format!("{} bytes uncompressed is too large for an image", file.size()),
        ));
    }
    // The declared size is not trusted for the allocation: the vector grows as data arrive.
    let mut bytes = Vec::with_capacity(file.size().min(1 << 20) as usize);
    file.read_to_end(&mut bytes).map_err(|e| member_error(path, name, format!("cannot read: {e}")))?;
    decode_image_bytes(&bytes, name).map_err(|m| member_error(path, name, m))
}

/// Decodes an image file's bytes (format by `name`'s extension) as linear RGB: 8- and
/// 16-bit images are sRGB, EXR and Radiance HDR linear.
pub fn decode_image_bytes(bytes: &[u8], name: &str) -> Result<RgbImage, String> {
    let lower = name.to_ascii_lowercase();
    if lower.ends_with(".hdr") {
        return decode_hdr(bytes);
    }
    let format = match lower.rsplit_once('.').map(|(_, e)| e) {
        Some("jpg" | "jpeg") => image::ImageFormat::Jpeg,
        Some("png") => image::ImageFormat::Png,
        Some("exr") => image::ImageFormat::OpenExr,
        _ => return Err("not a JPEG, PNG, EXR or HDR image".into()),
    };
    if format == image::ImageFormat::Jpeg {
        crate::btf::image_io::check_jpeg_complete(bytes)?;
    }
    let decoded = decode_with_limits(bytes, format)?;
    Ok(decoded_to_linear(decoded, format == image::ImageFormat::OpenExr))
}

/// Decodes with a memory limit tied to the member's size, so a small member cannot make
/// the decoder allocate for a huge size its header claims (at most 64 MiB or 1024 × the
/// member).
fn decode_with_limits(bytes: &[u8], format: image::ImageFormat) -> Result<image::DynamicImage, String> {
    let mut reader = image::ImageReader::with_format(std::io::Cursor::new(bytes), format);
    let mut limits = image::Limits::default();
    limits.max_alloc = Some((bytes.len() as u64).saturating_mul(1024).max(64 << 20));
    reader.limits(limits);
    reader.decode().map_err(|e| format!("cannot decode image: {e}"))
}

/// Radiance HDR. ATRIUM's files declare their resolution as `+X w -Y h`; like
/// btf-extractor, they are read as the usual `-Y h +X w` scan lines and flipped upside
/// down.
fn decode_hdr(bytes: &[u8]) -> Result<RgbImage, String> {
    let (fixed, flip) = standard_hdr_orientation(bytes);
    let decoded = decode_with_limits(&fixed, image::ImageFormat::Hdr)?;
    let mut image = decoded_to_linear(decoded, true);
    if flip {
        let row = image.width * 3;
        let rows: Vec<&[f16]> = image.data.chunks_exact(row).rev().collect();
        image.data = rows.concat();
    }
    Ok(image)
}

/// The bytes with a `+X w -Y h` resolution line rewritten as `-Y h +X w`, and whether the
/// rows must then be flipped.
fn standard_hdr_orientation(bytes: &[u8]) -> (std::borrow::Cow<'_, [u8]>, bool) {
    let Some(blank) = bytes.windows(2).position(|w| w == b"\n\n") else {
        return (bytes.into(), false);
    };
    let start = blank + 2;
    let Some(len) = bytes[start..].iter().take(64).position(|&b| b == b'\n') else {
        return (bytes.into(), false);
    };
    let line = String::from_utf8_lossy(&bytes[start..start + len]).into_owned();
    let parts: Vec<&str> = line.split_whitespace().collect();
    if let ["+X", w, "-Y", h] = parts.as_slice() {
        let mut fixed = bytes[..start].to_vec();
        fixed.extend_from_slice(format!("-Y {h} +X {w}").as_bytes());
        fixed.extend_from_slice(&bytes[start + len..]);
        return (fixed.into(), true);
    }
    (bytes.into(), false)
}
