//! `btfsynth.analyze` and `btfsynth.Analysis`: the texton pyramid of a stack, held in
//! memory once and shared (never copied) by every synthesis, render and export made from it.

use crate::arrays::view;
use crate::errors::{value_error, IntoPy};
use crate::long;
use crate::stack::{crop_of, Stack};
use btfsynth::analysis::filters::FilterBank;
use btfsynth::analysis::images::SampleImages;
use btfsynth::analysis::input::{self, Analysed, Input, Mode};
use btfsynth::analysis::pipeline::AnalysisParams;
use btfsynth::analysis::store;
use btfsynth::btf::{Btf, Crop};
use btfsynth::fsutil::StagedDir;
use btfsynth::render::Material;
use btfsynth::synth::Sample;
use btfsynth::{Error, Result};
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict};
use std::path::{Path, PathBuf};
use std::sync::{Arc, OnceLock};

/// An analysis and what synthesis, rendering and export read from it.
pub struct AnalysisData {
    /// Every level, as the engine reads them.
    pub sample: Sample,
    /// The sample's images and directions (what a plane is shown under).
    pub images: SampleImages,
    /// Where the analysis lives.
    pub origin: Origin,
    material: OnceLock<std::result::Result<Arc<Material>, String>>,
}

/// Where an analysis lives: in memory beside its decoded stack, or in a directory.
pub enum Origin {
    /// Analysed in this process from decoded images.
    Memory { analysed: Box<Analysed>, btf: Arc<Btf>, source: PathBuf, crop: Option<Crop> },
    /// Read from an analysis directory (`_temporary`: one this package unpacked, removed
    /// with the analysis).
    Directory { dir: PathBuf, _temporary: Option<tempfile::TempDir> },
}

impl AnalysisData {
    fn from_memory(analysed: Analysed, btf: Arc<Btf>, source: PathBuf, crop: Option<Crop>) -> Result<Self> {
        let levels = analysed.analysis.levels.len();
        let sample = Sample::from_analysis(&analysed.analysis, &btf, levels)?;
        let images = SampleImages::from_btf(&btf);
        let origin = Origin::Memory { analysed: Box::new(analysed), btf, source, crop };
        Ok(AnalysisData { sample, images, origin, material: OnceLock::new() })
    }

    /// Reads the analysis directory `dir` (kept as `temporary` if one was made for it).
    pub fn open(dir: &Path, temporary: Option<tempfile::TempDir>) -> Result<Self> {
        let manifest = store::read_manifest(dir)?;
        store::verify_levels(dir, &manifest, manifest.levels.len())?;
        let sample = Sample::open(dir, manifest.levels.len())?;
        let images = SampleImages::open(dir)?;
        let origin = Origin::Directory { dir: dir.to_path_buf(), _temporary: temporary };
        Ok(AnalysisData { sample, images, origin, material: OnceLock::new() })
    }

    /// The analysis directory, where it has one.
    pub fn dir(&self) -> Option<&Path> {
        match &self.origin {
            Origin::Directory { dir, .. } => Some(dir),
            Origin::Memory { .. } => None,
        }
    }

    /// The sample as the renderers read it, made on first use.
    pub fn material(&self) -> Result<Arc<Material>> {
        let made = self.material.get_or_init(|| {
            let material = match &self.origin {
                Origin::Memory { btf, .. } => Material::from_btf(btf),
                Origin::Directory { dir, .. } => Material::open(dir),
            };
            material.map(Arc::new).map_err(|e| e.to_string())
        });
        made.clone().map_err(Error::invalid)
    }

    /// Writes the analysis directory the CLI's `analyze` writes for the same inputs.
    fn save(&self, out: &Path, overwrite: bool) -> Result<PathBuf> {
        match &self.origin {
            Origin::Memory { analysed, btf, source, crop } => {
                let crop = crop.map(|c| [c.x, c.y, c.width, c.height]);
                store::write(&analysed.analysis, btf, source, crop, out, overwrite)
            }
            Origin::Directory { dir, .. } => copy_dir(dir, out, overwrite),
        }
    }
}

/// Copies the files of the analysis directory `dir` into `out`, atomically.
fn copy_dir(dir: &Path, out: &Path, overwrite: bool) -> Result<PathBuf> {
    let staged = StagedDir::new(out, overwrite)?;
    for (name, bytes) in read_files(dir)? {
        std::fs::write(staged.path().join(&name), bytes).map_err(|e| Error::io(out.join(&name), e))?;
    }
    staged.commit()
}

/// Every file of the analysis directory `dir` (it holds no folders) with its bytes.
fn read_files(dir: &Path) -> Result<Vec<(String, Vec<u8>)>> {
    let entries = std::fs::read_dir(dir).map_err(|e| Error::io(dir, e))?;
    let mut files = Vec::new();
    for entry in entries {
        let path = entry.map_err(|e| Error::io(dir, e))?.path();
        if path.is_file() {
            let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
            files.push((name, std::fs::read(&path).map_err(|e| Error::io(&path, e))?));
        }
    }
    files.sort();
    Ok(files)
}

/// The texton analysis of a stack: a pyramid of texton maps with Γ and kNN lists.
///
/// Made by `analyze()` or `Analysis.load(dir)`; shared, never copied, by every synthesis made
/// from it; picklable (as the files of its directory), so that a Dask cluster sends it to its
/// workers once.
#[pyclass(module = "btfsynth._native", frozen)]
pub struct Analysis {
    pub data: Arc<AnalysisData>,
}

#[pymethods]
impl Analysis {
    /// Reads an analysis directory written by `btfsynth analyze` or `Analysis.save`.
    #[staticmethod]
    fn load(py: Python<'_>, dir: PathBuf) -> PyResult<Analysis> {
        let data = long::run(py, None, move |_| AnalysisData::open(&dir, None))?;
        Ok(Analysis { data: Arc::new(data) })
    }

    /// Writes the directory `btfsynth analyze` writes for the same inputs (atomically);
    /// refuses an existing one unless `overwrite`. Returns its path.
    #[pyo3(signature = (dir, overwrite=false))]
    fn save(&self, py: Python<'_>, dir: PathBuf, overwrite: bool) -> PyResult<PathBuf> {
        let data = self.data.clone();
        long::run(py, None, move |_| data.save(&dir, overwrite))
    }

    /// Pyramid levels, finest first, as `(height, width)`.
    #[getter]
    fn levels(&self) -> Vec<(usize, usize)> {
        self.data.sample.levels.iter().map(|l| (l.height, l.width)).collect()
    }

    /// Textons per level (the default texton, the last row of Γ, not counted).
    #[getter]
    fn textons(&self) -> Vec<usize> {
        self.data.sample.levels.iter().map(|l| l.textons - 1).collect()
    }

    /// The sample's size `(height, width)` and its image count.
    #[getter]
    fn sample_shape(&self) -> (usize, usize, usize) {
        let m = &self.data.sample.manifest;
        (m.images, m.height, m.width)
    }

    /// The length of the kNN lists.
    #[getter]
    fn k(&self) -> usize {
        self.data.sample.manifest.k
    }

    /// Level `level`'s texton map, uint16 `[h, w]` (a read-only view, no copy).
    #[pyo3(signature = (level=0))]
    fn texton_map<'py>(slf: &Bound<'py, Self>, level: usize) -> PyResult<Bound<'py, PyAny>> {
        let l = level_of(slf, level)?;
        Ok(view(slf.as_any(), &l.labels, &[l.height, l.width])?.into_any())
    }

    /// Level `level`'s Γ, float32 `[t+1, t+1]` (the default texton last; a read-only view).
    #[pyo3(signature = (level=0))]
    fn gamma<'py>(slf: &Bound<'py, Self>, level: usize) -> PyResult<Bound<'py, PyAny>> {
        let l = level_of(slf, level)?;
        Ok(view(slf.as_any(), &l.gamma, &[l.textons, l.textons])?.into_any())
    }

    /// Level `level`'s kNN lists, uint32 `[h, w, k]` of pixel indices `y·w + x`, each pixel
    /// itself first (a read-only view).
    #[pyo3(signature = (level=0))]
    fn knn<'py>(slf: &Bound<'py, Self>, level: usize) -> PyResult<Bound<'py, PyAny>> {
        let l = level_of(slf, level)?;
        Ok(view(slf.as_any(), &l.knn, &[l.height, l.width, l.k])?.into_any())
    }

    /// The manifest `analysis.json` holds, as a dict.
    #[getter]
    fn manifest<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let text = serde_json::to_string(&self.data.sample.manifest)
            .map_err(|e| Error::internal(e.to_string()))
            .py(py)?;
        py.import("json")?.call_method1("loads", (text,))
    }

    fn __reduce__<'py>(&self, py: Python<'py>) -> PyResult<(Bound<'py, PyAny>, (Bound<'py, PyDict>,))> {
        let data = self.data.clone();
        let files = long::run(py, None, move |_| match data.dir() {
            Some(dir) => read_files(dir),
            None => {
                let temporary = tempfile::tempdir().map_err(|e| Error::io(std::env::temp_dir(), e))?;
                let dir = data.save(&temporary.path().join("analysis"), false)?;
                read_files(&dir)
            }
        })?;
        let dict = PyDict::new(py);
        for (name, bytes) in files {
            dict.set_item(name, PyBytes::new(py, &bytes))?;
        }
        let rebuild = py.import("btfsynth._native")?.getattr("_analysis_from_files")?;
        Ok((rebuild, (dict,)))
    }

    fn __repr__(&self) -> String {
        let sizes: Vec<String> =
            self.data.sample.levels.iter().map(|l| format!("{}x{}", l.width, l.height)).collect();
        let from = match &self.data.origin {
            Origin::Memory { source, .. } => source.display().to_string(),
            Origin::Directory { dir, .. } => dir.display().to_string(),
        };
        format!("Analysis(levels {}, k {}, from {from})", sizes.join(", "), self.data.sample.manifest.k)
    }
}

fn level_of<'a>(slf: &'a Bound<'_, Analysis>, level: usize) -> PyResult<&'a btfsynth::synth::SampleLevel> {
    let levels = &slf.get().data.sample.levels;
    levels.get(level).ok_or_else(|| {
        value_error(
            slf.py(),
            "level",
            format!("{level} is not a level of this analysis (0 to {})", levels.len() - 1),
        )
    })
}

/// An analysis from the files of its directory (what `Analysis.__reduce__` gives).
#[pyfunction]
#[pyo3(name = "_analysis_from_files")]
pub fn analysis_from_files(py: Python<'_>, files: &Bound<'_, PyDict>) -> PyResult<Analysis> {
    let mut owned = Vec::new();
    for (name, bytes) in files.iter() {
        owned.push((name.extract::<String>()?, bytes.downcast::<PyBytes>()?.as_bytes().to_vec()));
    }
    let data = long::run(py, None, move |_| {
        let temporary = tempfile::tempdir().map_err(|e| Error::io(std::env::temp_dir(), e))?;
        for (name, bytes) in owned {
            // Names come from our own pickles; anything else is refused rather than followed.
            if name.contains(['/', '\\']) || name.starts_with('.') {
                return Err(Error::invalid(format!("'{name}' is not a file of an analysis directory")));
            }
            let path = temporary.path().join(&name);
            std::fs::write(&path, bytes).map_err(|e| Error::io(&path, e))?;
        }
        let dir = temporary.path().to_path_buf();
        AnalysisData::open(&dir, Some(temporary))
    })?;
    Ok(Analysis { data: Arc::new(data) })
}

/// The analysis parameters as the CLI's `analyze` flags set them, checked: a parameter
/// out of range is a `ValueError` naming it.
fn check(py: Python<'_>, params: &AnalysisParams) -> PyResult<()> {
    let p = params;
    for (name, value, low, high) in [
        ("textons", p.textons, 1, usize::MAX),
        ("selected", p.selected, 1, usize::MAX),
        ("levels", p.levels, 1, usize::MAX),
        ("k", p.k, 1, 256),
        ("basis", p.basis_rank, 1, 1024),
        ("appearance_dims", p.appearance_dims, 1, 64),
    ] {
        if !(low..=high).contains(&value) {
            let range =
                if high == usize::MAX { format!("at least {low}") } else { format!("from {low} to {high}") };
            return Err(value_error(py, name, format!("{value}: expected a whole number {range}")));
        }
    }
    if !(3..=63).contains(&p.neighborhood) || p.neighborhood % 2 == 0 {
        return Err(value_error(
            py,
            "neighborhood",
            format!("{}: expected an odd whole number from 3 to 63", p.neighborhood),
        ));
    }
    Ok(())
}

/// A kNN list longer than the coarsest level has pixels is refused (as the CLI refuses it).
fn check_size(params: &AnalysisParams, (w, h): (usize, usize)) -> Result<()> {
    params.validate(w, h)?;
    let sizes = btfsynth::analysis::pyramid::level_sizes(w, h, params.levels);
    let (cw, ch) = sizes[sizes.len() - 1];
    if params.k > cw * ch {
        let message =
            format!("a kNN list holds at most the {cw}x{ch} = {} pixels of the coarsest level", cw * ch);
        return Err(Error::out_of_range(btfsynth::Param::K, params.k, message));
    }
    Ok(())
}

// `appearance_dims`' default below is the library's, written as a number so that help()
// shows it.
const _: () = assert!(btfsynth::analysis::appearance::DEFAULT_DIMS == 16);

/// Analyses a stack (a `Stack`, or a path as the CLI's `analyze` reads it) into an
/// `Analysis`: the same computation, and the same bytes once saved, as
/// `btfsynth analyze STACK -o DIR` with the same values. Keyword arguments are the CLI's flags
/// with their defaults; `progress` is a callable `progress(done, total, stage)`.
#[pyfunction]
#[pyo3(signature = (stack, *, textons=400, selected=400, levels=3, k=11, neighborhood=5, tileable=false,
    basis=32, appearance_dims=16, seed=0, filters=None, crop=None, progress=None))]
#[allow(clippy::too_many_arguments)]
pub fn analyze(
    py: Python<'_>,
    stack: &Bound<'_, PyAny>,
    textons: usize,
    selected: usize,
    levels: usize,
    k: usize,
    neighborhood: usize,
    tileable: bool,
    basis: usize,
    appearance_dims: usize,
    seed: u64,
    filters: Option<PathBuf>,
    crop: Option<(u32, u32, u32, u32)>,
    progress: Option<PyObject>,
) -> PyResult<Analysis> {
    let filters = match filters {
        Some(path) => FilterBank::from_file(&path).py(py)?,
        None => FilterBank::lm48(),
    };
    let basis_rank = basis;
    let params = AnalysisParams {
        textons,
        selected,
        levels,
        k,
        neighborhood,
        tileable,
        basis_rank,
        appearance_dims,
        seed,
        filters,
    };
    check(py, &params)?;
    let crop = crop_of(py, crop)?;
    let data = if let Ok(stack) = stack.downcast::<Stack>() {
        if crop.is_some() {
            return Err(value_error(py, "crop", "crop a Stack when opening it (Stack.open(path, crop=…))"));
        }
        let s = stack.get();
        let (btf, source, crop) = (s.btf.clone(), s.source.clone(), s.crop);
        long::run(py, progress.as_ref(), move |hook| {
            check_size(&params, (btf.width(), btf.height()))?;
            let analysed = Analysed {
                analysis: btfsynth::analysis::pipeline::analyze(&btf, &params, hook)?,
                factors: None,
                basis: None,
            };
            AnalysisData::from_memory(analysed, btf, source, crop)
        })?
    } else {
        let path: PathBuf = stack.extract().map_err(|_| {
            crate::errors::type_error(
                "stack",
                format!("expected a Stack or a path, got {}", crate::arrays::type_name(stack)),
            )
        })?;
        long::run(py, progress.as_ref(), move |hook| analyze_path(&path, crop, &params, hook))?
    };
    Ok(Analysis { data: Arc::new(data) })
}

/// The CLI's path: factors for factorized files, decoded images where they fit, a streamed
/// basis otherwise. An analysis that keeps its sample as factors is held in a temporary
/// directory (the library's in-memory sample is decoded images).
fn analyze_path(
    path: &Path,
    crop: Option<Crop>,
    params: &AnalysisParams,
    hook: &dyn btfsynth::progress::Progress,
) -> Result<AnalysisData> {
    let opened = input::open(path, crop, Mode::Auto, params, hook)?;
    check_size(params, opened.size())?;
    let analysed = input::run(&opened, params, hook)?;
    match opened {
        Input::Images(btf) if analysed.factors.is_none() => {
            AnalysisData::from_memory(analysed, Arc::new(btf), path.to_path_buf(), crop)
        }
        opened => {
            let temporary = tempfile::tempdir().map_err(|e| Error::io(std::env::temp_dir(), e))?;
            let dir = temporary.path().join("analysis");
            let crop = crop.map(|c| [c.x, c.y, c.width, c.height]);
            store::write_analysed(&analysed, &opened, (path, crop), &[], &dir, false)?;
            AnalysisData::open(&dir, Some(temporary))
        }
    }
}
