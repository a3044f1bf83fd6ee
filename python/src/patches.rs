//! `btfsynth.map_patches` (`synthesize_surface(..., method="soler2002")`) and
//! `btfsynth.PatchMap`: hierarchical pattern mapping (Soler, Cani and Angelidis 2002), the
//! CLI's `synth ANALYSIS MESH --method soler2002` without the files: texture coordinates
//! into the sample at every corner of the user's own mesh, nothing remeshed.

use crate::analysis::{Analysis, AnalysisData};
use crate::arrays::view;
use crate::errors::{value_error, IntoPy};
use crate::long;
use crate::plane::json;
use crate::stack::IN_MEMORY;
use crate::surface::{vec3s, Original};
use btfsynth::fsutil::{check_file_target, write_with_temp};
use btfsynth::mesh::textured::TexturedMesh;
use btfsynth::render::Scene;
use btfsynth::synth::patches::output::{write_uv_map, Provenance, UvMap};
use btfsynth::synth::patches::prepare::{fit_sample, recorded_params, texels_per_unit, Matching};
use btfsynth::synth::patches::{map_mesh, PatchMapping, SolerParams};
use btfsynth::Result;
use glam::Vec2;
use numpy::PyArrayDyn;
use pyo3::prelude::*;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// A pattern-mapped mesh: the mesh as given (vertices and faces in its order) with, at each
/// face corner, the sample texel it shows, and the patch (cluster) that textured each face.
#[pyclass(module = "btfsynth._native", frozen)]
pub struct PatchMap {
    mesh: TexturedMesh,
    mapping: PatchMapping,
    params: serde_json::Value,
    texel: f32,
    original: Original,
    pub analysis: Arc<AnalysisData>,
    /// The result as the renderers read it.
    pub scene: Arc<Scene>,
}

#[pymethods]
impl PatchMap {
    /// Vertex positions, float32 `[V, 3]`, as the mesh gave them (a read-only view).
    #[getter]
    fn vertices<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyArrayDyn<f32>>> {
        let p = &slf.get().mesh.positions;
        view(slf.as_any(), vec3s(p), &[p.len(), 3])
    }

    /// Triangles, uint32 `[F, 3]`, as the mesh gave them (polygons fan-triangulated; a view).
    #[getter]
    fn faces<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyArrayDyn<u32>>> {
        let t = &slf.get().mesh.triangles;
        view(slf.as_any(), t.as_flattened(), &[t.len(), 3])
    }

    /// Per face, per corner, the sample coordinate, float32 `[F, 3, 2]`: column and row in
    /// sample texels, texel centres at integers (a read-only view). `save()` writes them
    /// normalised, v up, as OBJ and PLY readers expect.
    #[getter]
    fn corner_uv<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyArrayDyn<f32>>> {
        let uv = &slf.get().mapping.corner_uv;
        view(slf.as_any(), vec2s(uv.as_flattened()), &[uv.len(), 3, 2])
    }

    /// Per face, the patch (cluster of the hierarchy) that textured it, uint32 `[F]` (a view).
    #[getter]
    fn cluster<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyArrayDyn<u32>>> {
        let c = &slf.get().mapping.cluster;
        view(slf.as_any(), c, &[c.len()])
    }

    /// Per face, the level of its patch in the hierarchy (0 the coarsest), uint8 `[F]` (a view).
    #[getter]
    fn level<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyArrayDyn<u8>>> {
        let l = &slf.get().mapping.level;
        view(slf.as_any(), l, &[l.len()])
    }

    /// One sample texel in model units.
    #[getter]
    fn texel(&self) -> f32 {
        self.texel
    }

    /// What each level of the hierarchy did, as the CLI's `--report` writes it (without
    /// the parameters, see `params`).
    #[getter]
    fn report<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        json(py, &serde_json::to_value(&self.mapping.report).unwrap_or_default())
    }

    /// The parameters the file's header records (method, texels per unit, rotations, …).
    #[getter]
    fn params<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        json(py, &self.params)
    }

    /// Writes the result `btfsynth synth … --method soler2002` writes: a `.ply` or `.obj` of
    /// the mesh with texture coordinates at every face corner, atomically; refuses an
    /// existing file unless `overwrite`. For an analysis loaded from a directory and a mesh
    /// read from a file, the CLI's bytes for the same inputs, output path and seed.
    #[pyo3(signature = (path, overwrite=false))]
    fn save(&self, py: Python<'_>, path: PathBuf, overwrite: bool) -> PyResult<PathBuf> {
        let ext = path.extension().map(|e| e.to_string_lossy().to_ascii_lowercase()).unwrap_or_default();
        if ext != "ply" && ext != "obj" {
            return Err(value_error(py, "path", format!("{}: expected a .ply or .obj file", path.display())));
        }
        let analysis = self.analysis.dir().map_or_else(|| PathBuf::from(IN_MEMORY), Path::to_path_buf);
        let (mesh, (w, h)) =
            (self.original.name(), (self.analysis.images.width, self.analysis.images.height));
        let written = py.allow_threads(|| -> Result<PathBuf> {
            check_file_target(&path, overwrite)?;
            let provenance = Provenance {
                analysis: &analysis,
                mesh: &mesh,
                sample: (w, h),
                tileable: self.analysis.sample.manifest.params.tileable,
                texel: self.texel,
                params: self.params.clone(),
            };
            write_with_temp(&path, |tmp| {
                let m = &self.mesh;
                write_uv_map((&path, tmp), &m.positions, &m.triangles, &self.mapping, &provenance)
            })?;
            Ok(path.clone())
        });
        written.py(py)
    }

    fn __repr__(&self) -> String {
        format!(
            "PatchMap({} faces, {} patches, texel {})",
            self.mesh.triangles.len(),
            self.mapping.report.clusters,
            self.texel
        )
    }
}

/// Corner coordinates as a flat slice of floats (glam's `Vec2` is two `f32`s, `repr(C)`).
fn vec2s(v: &[Vec2]) -> &[f32] {
    // SAFETY: Vec2 is #[repr(C)] { x, y: f32 } with no padding.
    unsafe { std::slice::from_raw_parts(v.as_ptr().cast::<f32>(), v.len() * 2) }
}

/// Maps `analysis`'s sample onto a mesh (a path, or `mesh=` vertices `[V, 3]` with
/// `faces=[F, 3]`) by hierarchical pattern mapping, as `btfsynth synth ANALYSIS MESH
/// --method soler2002` does; `synthesize_surface(..., method="soler2002")` calls it. The
/// texture's size: `scale` texels per model unit, or `texels_across` the mesh's largest side
/// (default 4 × the sample's width). The other keywords are the CLI's flags of that method:
/// `colour_space` is `lab`, `hsv`, `rgb` or `appearance`; `relax=False` is `--no-relax`,
/// `keep_borders=True` `--keep-borders`.
#[pyfunction]
#[pyo3(signature = (analysis, mesh, faces=None, *, scale=None, texels_across=None, seed=0, rotations=19, band=6.0,
    max_distortion=0.1, fit_threshold=0.3, colour_space="lab", relax=true, keep_borders=false, first_face=None,
    orientation=None, progress=None))]
#[allow(clippy::too_many_arguments)]
pub fn map_patches(
    py: Python<'_>,
    analysis: &Bound<'_, Analysis>,
    mesh: &Bound<'_, PyAny>,
    faces: Option<Bound<'_, PyAny>>,
    scale: Option<f32>,
    texels_across: Option<f32>,
    seed: u64,
    rotations: usize,
    band: f32,
    max_distortion: f32,
    fit_threshold: f32,
    colour_space: &str,
    relax: bool,
    keep_borders: bool,
    first_face: Option<usize>,
    orientation: Option<f32>,
    progress: Option<PyObject>,
) -> PyResult<PatchMap> {
    let data = analysis.get().data.clone();
    let original = crate::surface::original(py, mesh, faces.as_ref())?;
    for (name, value) in [("scale", scale), ("texels_across", texels_across)] {
        if value.is_some_and(|v| !v.is_finite() || v <= 0.0) {
            return Err(value_error(py, name, "expected a positive number"));
        }
    }
    if scale.is_some() && texels_across.is_some() {
        return Err(value_error(py, "scale", "give at most one of scale and texels_across"));
    }
    let matching = Matching::parse(colour_space).map_err(|e| value_error(py, "colour_space", e))?;
    let mut params = SolerParams {
        texels_per_unit: 1.0,
        rotations,
        band,
        max_flat_error: max_distortion,
        max_fit_error: fit_threshold,
        colour: matching.colour_space(),
        relax,
        move_borders: !keep_borders,
        matching: true,
        seed,
        first_face,
        orientation,
    };
    params.validate().py(py)?;
    let (shared, given) = (data.clone(), original.clone());
    let (mesh, mapping, params, texel, scene) = long::run(py, progress.as_ref(), move |hook| {
        let name = given.name();
        let mesh = given.textured()?;
        let tileable = shared.sample.manifest.params.tileable;
        let appearance = shared.sample.levels[0].appearance.as_ref();
        let dir = shared.dir().map_or_else(|| PathBuf::from(IN_MEMORY), Path::to_path_buf);
        let (sample, shown) = fit_sample(&shared.images, appearance, matching, tileable, &dir)?;
        params.texels_per_unit =
            texels_per_unit(&mesh.positions, scale, texels_across, shared.images.width, &name)?;
        let mapping = map_mesh(&mesh.positions, &mesh.triangles, &name, sample, &params, hook)?;
        let texel = 1.0 / params.texels_per_unit;
        // The renderers' scene, from the result moved into the library's form and back.
        let PatchMapping { corner_uv, cluster, level, report } = mapping;
        let sample = (shared.images.width, shared.images.height);
        let comments = Vec::new();
        let map = UvMap { mesh, corner_uv, level, cluster, comments, sample, texel, tileable };
        let scene = Scene::from_uv_map(&map, &name)?;
        let UvMap { mesh, corner_uv, level, cluster, .. } = map;
        let mapping = PatchMapping { corner_uv, cluster, level, report };
        Ok((mesh, mapping, recorded_params(&params, matching, shown), texel, Arc::new(scene)))
    })?;
    Ok(PatchMap { mesh, mapping, params, texel, original, analysis: data, scene })
}
