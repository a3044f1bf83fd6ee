//! Loading a BTF stack from whatever the path holds:
//!
//! 1. a `btf.json` manifest (the file itself, or a directory that contains one);
//! 2. a directory of Bonn/UTIA-named images, `tl{θl} pl{φl} tv{θv} pv{φv}.{jpg,png,exr}`
//!    with space or underscore separators, flat or inside `tv###_pv###/` subfolders;
//! 3. a single PNG, JPEG or EXR image: a one-image BTF seen and lit along the normal;
//! 4. a file that holds a whole stack, decoded through [`crate::btf::stack_file`]: a Bonn
//!    `.btf` file (UBO2014) or a zip of UBO2003/ATRIUM images.
//!
//! EXRs in UTIA's `tv###_pv###/` folders hold CIE XYZ and are converted ([`crate::btf::utia`]).

use crate::btf::image_io::is_image_path;
use crate::btf::names::pair_from_name;
use crate::btf::utia::read_stack_image;
use crate::btf::{Btf, Crop, Direction, DirectionPair};
use crate::progress::Progress;
use crate::{Error, Result};
use half::f16;
use rayon::prelude::*;
use std::path::{Path, PathBuf};

/// The manifest's file name.
pub const MANIFEST: &str = "btf.json";

/// How a stack is read.
#[derive(Clone, Copy, Debug, Default)]
pub struct LoadOptions {
    /// Keep only this rectangle of every image (default: the whole image).
    pub crop: Option<Crop>,
}

/// One image of a stack before it is read: where it is and how it was taken.
#[derive(Clone, Debug)]
struct Entry {
    file: PathBuf,
    pair: DirectionPair,
}

/// The manifest as written in `btf.json`. Unknown top-level keys are kept for the writer's
/// own notes (generator, seed, …) and ignored here.
#[derive(serde::Serialize, serde::Deserialize)]
pub struct Manifest {
    /// Every image of the stack with its directions.
    pub images: Vec<ManifestImage>,
    /// Where the stack came from (the generator and its parameters); informational.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub source: Option<serde_json::Value>,
}

/// One image of the manifest; angles `[θ, φ]` in degrees, `file` relative to the manifest.
#[derive(serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ManifestImage {
    /// The image file, relative to the manifest.
    pub file: String,
    /// θ, φ of the light in degrees.
    pub light: [f32; 2],
    /// θ, φ of the view in degrees.
    pub view: [f32; 2],
}

/// Reads the stack at `path` (see the module documentation for the layouts recognised).
pub fn load(path: &Path, options: &LoadOptions, progress: &dyn Progress) -> Result<Btf> {
    if let Some(source) = crate::btf::stack_file::open(path, options.crop)? {
        return source.decode_all(progress);
    }
    let entries = discover(path)?;
    read_entries(&entries, options, progress)
}

/// Every path that reading the stack at `path` reads, for a command to refuse an output
/// that would replace one: `path` itself and, for a `btf.json` manifest (or a folder holding
/// one), the manifest's folder and every image it names, which may lie outside that folder
/// (`"file": "../a.png"`). A manifest that cannot be read adds no images (reading the stack
/// fails then anyway), and one that is not a regular file is not read here (a pipe would be
/// read empty by the time the stack is).
pub fn input_paths(path: &Path) -> Vec<PathBuf> {
    let mut paths = vec![path.to_path_buf()];
    let manifest = if path.is_dir() { path.join(MANIFEST) } else { path.to_path_buf() };
    let is_json = manifest.extension().is_some_and(|e| e.eq_ignore_ascii_case("json"));
    if !is_json || !std::fs::metadata(&manifest).is_ok_and(|m| m.is_file()) {
        return paths;
    }
    if !path.is_dir() {
        paths.push(match manifest.parent() {
            Some(dir) if !dir.as_os_str().is_empty() => dir.to_path_buf(),
            _ => PathBuf::from("."),
        });
    }
    paths.extend(manifest_entries(&manifest).into_iter().flatten().map(|e| e.file));
    paths
}

/// A stack of image files (a folder, a `btf.json` or one image) whose images are read
/// when asked for: [`crate::btf::ImageSource`] for stacks too large to hold, which the
/// analysis streams (see `analysis::basis::streamed_basis`).
pub struct FolderStack {
    path: PathBuf,
    entries: Vec<Entry>,
    pairs: Vec<DirectionPair>,
    width: usize,
    height: usize,
    crop: Option<Crop>,
}

impl FolderStack {
    /// Lists the images at `path` and reads the first one for the size.
    pub fn open(path: &Path, crop: Option<Crop>) -> Result<FolderStack> {
        let entries = discover(path)?;
        let first = read_stack_image(&entries[0].file, crop)?;
        let pairs: Vec<DirectionPair> = entries.iter().map(|e| e.pair).collect();
        if let Some((a, b)) = crate::btf::directions::first_duplicate(&pairs) {
            return Err(Error::format(
                &entries[b].file,
                format!(
                    "has the same light and view directions as {} ({})",
                    entries[a].file.display(),
                    pairs[a]
                ),
            ));
        }
        Ok(FolderStack {
            path: path.to_path_buf(),
            entries,
            pairs,
            width: first.width,
            height: first.height,
            crop,
        })
    }
}

impl crate::btf::ImageSource for FolderStack {
    fn path(&self) -> &Path {
        &self.path
    }

    fn width(&self) -> usize {
        self.width
    }

    fn height(&self) -> usize {
        self.height
    }

    fn pairs(&self) -> &[DirectionPair] {
        &self.pairs
    }

    fn decode_image(&self, i: usize, out: &mut [f16]) -> Result<()> {
        let entry = &self.entries[i];
        let image = read_stack_image(&entry.file, self.crop)?;
        if (image.width, image.height) != (self.width, self.height) {
            return Err(Error::format(
                &entry.file,
                format!(
                    "this image is {}x{} pixels but {} is {}x{}; all images of a stack must have one size",
                    image.width,
                    image.height,
                    self.entries[0].file.display(),
                    self.width,
                    self.height
                ),
            ));
        }
        out.copy_from_slice(&image.data);
        Ok(())
    }

    fn decode_all(&self, progress: &dyn Progress) -> Result<Btf> {
        crate::btf::source::ensure_fits_in_memory(
            &self.path,
            self.pairs.len(),
            self.width * self.height * 3,
        )?;
        read_entries(&self.entries, &LoadOptions { crop: self.crop }, progress)
    }
}

/// What `path` holds, as a list of images with their directions.
fn discover(path: &Path) -> Result<Vec<Entry>> {
    let meta = std::fs::metadata(path).map_err(|e| Error::io(path, e))?;
    if meta.is_dir() {
        let manifest = path.join(MANIFEST);
        if manifest.is_file() {
            return manifest_entries(&manifest);
        }
        return named_entries(path);
    }
    if path.file_name().is_some_and(|n| n == MANIFEST)
        || path.extension().is_some_and(|e| e.eq_ignore_ascii_case("json"))
    {
        return manifest_entries(path);
    }
    if is_image_path(path) {
        let normal = DirectionPair { light: Direction::NORMAL, view: Direction::NORMAL };
        return Ok(vec![Entry { file: path.to_path_buf(), pair: normal }]);
    }
    Err(Error::format(
        path,
        "not a BTF stack: expected a directory, a btf.json manifest or a PNG/JPEG/EXR image",
    ))
}

fn manifest_entries(path: &Path) -> Result<Vec<Entry>> {
    let text = crate::fsutil::read_input_text(path)?;
    let manifest: Manifest =
        serde_json::from_str(&text).map_err(|e| Error::format(path, format!("invalid manifest: {e}")))?;
    if manifest.images.is_empty() {
        return Err(Error::format(path, "the manifest lists no images"));
    }
    let dir = path.parent().unwrap_or(Path::new("."));
    manifest
        .images
        .iter()
        .enumerate()
        .map(|(i, im)| {
            let at =
                |what: &str, e: Error| Error::format(path, format!("image {i} ({}): {what} {e}", im.file));
            let light = Direction::new(im.light[0], im.light[1]).map_err(|e| at("light", e))?;
            let view = Direction::new(im.view[0], im.view[1]).map_err(|e| at("view", e))?;
            Ok(Entry { file: dir.join(&im.file), pair: DirectionPair { light, view } })
        })
        .collect()
}

/// Images directly in `dir` and one level down (the UTIA `tv###_pv###/` layout), sorted by
/// path; other files and hidden files are ignored.
fn named_entries(dir: &Path) -> Result<Vec<Entry>> {
    let mut files = Vec::new();
    for entry in read_dir_sorted(dir)? {
        if entry.is_dir() {
            files.extend(read_dir_sorted(&entry)?.into_iter().filter(|p| p.is_file() && is_image_path(p)));
        } else if is_image_path(&entry) {
            files.push(entry);
        }
    }
    if files.is_empty() {
        return Err(Error::format(
            dir,
            format!("no images found: expected a {MANIFEST} manifest or images named like tl015_pl000_tv000_pv000.png"),
        ));
    }
    files
        .into_iter()
        .map(|file| {
            let pair = pair_from_name(&file)?;
            Ok(Entry { file, pair })
        })
        .collect()
}

fn read_dir_sorted(dir: &Path) -> Result<Vec<PathBuf>> {
    let mut paths: Vec<PathBuf> = std::fs::read_dir(dir)
        .map_err(|e| Error::io(dir, e))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| !p.file_name().is_some_and(|n| n.to_string_lossy().starts_with('.')))
        .collect();
    paths.sort();
    Ok(paths)
}

/// Reads every entry's image in parallel into one compact stack.
fn read_entries(entries: &[Entry], options: &LoadOptions, progress: &dyn Progress) -> Result<Btf> {
    let first = read_stack_image(&entries[0].file, options.crop)?;
    let (width, height) = (first.width, first.height);
    let per_image = width * height * 3;
    let mut pixels = vec![f16::ZERO; per_image * entries.len()];
    pixels[..per_image].copy_from_slice(&first.data);
    progress.start("loading images", entries.len() as u64);
    progress.advance(1);
    pixels
        .par_chunks_mut(per_image)
        .zip(entries.par_iter())
        .skip(1)
        .try_for_each(|(out, entry)| {
            let image = read_stack_image(&entry.file, options.crop)?;
            if (image.width, image.height) != (width, height) {
                return Err(Error::format(
                    &entry.file,
                    format!(
                        "this image is {}x{} pixels but {} is {width}x{height}; all images of a stack must have one size",
                        image.width,
                        image.height,
                        entries[0].file.display()
                    ),
                ));
            }
            out.copy_from_slice(&image.data);
            progress.advance(1);
            Ok(())
        })?;
    progress.finish();
    let pairs: Vec<DirectionPair> = entries.iter().map(|e| e.pair).collect();
    if let Some((a, b)) = crate::btf::directions::first_duplicate(&pairs) {
        return Err(Error::format(
            &entries[b].file,
            format!("has the same light and view directions as {} ({})", entries[a].file.display(), pairs[a]),
        ));
    }
    Btf::new(width, height, pairs, pixels)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bonn_names_parse_with_either_separator() {
        let a = pair_from_name(Path::new("x/tl015 pl000 tv030 pv120.jpg")).unwrap();
        assert_eq!((a.light.theta, a.light.phi, a.view.theta, a.view.phi), (15.0, 0.0, 30.0, 120.0));
        let b = pair_from_name(Path::new("x/tl075_pl345_tv000_pv000.png")).unwrap();
        assert_eq!((b.light.theta, b.light.phi), (75.0, 345.0));
    }

    #[test]
    fn utia_folders_supply_the_view() {
        let a = pair_from_name(Path::new("stack/tv045_pv090/tl015_pl030.png")).unwrap();
        assert_eq!((a.view.theta, a.view.phi), (45.0, 90.0));
        assert!(pair_from_name(Path::new("stack/tv045_pv090/tl015_pl030_tv030_pv090.png")).is_err());
    }

    #[test]
    fn unparseable_and_out_of_range_names_are_errors() {
        for name in [
            "photo.png",
            "tl015_pl000_tv000.png",
            "tl1x_pl0_tv0_pv0.png",
            "tl095_pl0_tv0_pv0.png",
            "tl0_tl0_tv0_pv0.png",
        ] {
            let err = pair_from_name(Path::new(name)).unwrap_err().to_string();
            assert!(err.starts_with(name), "{err}");
        }
    }
}
