//! `btfsynth.synthesize_surface`, `btfsynth.Surface`, `btfsynth.render` and
//! `btfsynth.export_gltf`: the CLI's `synth ANALYSIS MESH`, `render` and `export` in memory.

use crate::analysis::{Analysis, AnalysisData};
use crate::arrays::{floats, indices, owned, view};
use crate::errors::{value_error, IntoPy};
use crate::long;
use crate::patches::PatchMap;
use crate::plane::{json, with_sample, Choices};
use crate::stack::IN_MEMORY;
use btfsynth::export::{bake_export, ExportOptions, ExportSource, SourceNames};
use btfsynth::fsutil::{check_file_target, write_file_atomic};
use btfsynth::mesh::field::Orientation;
use btfsynth::mesh::textured::{load_textured, TexturedMesh};
use btfsynth::mesh::Mesh;
use btfsynth::render::ambient::AmbientCache;
use btfsynth::render::cpu::{render as render_shot, valid_spp, RenderOptions};
use btfsynth::render::tracer::Tracer;
use btfsynth::render::{Environment, Material, Mode, Scene, ShotPlan};
use btfsynth::synth::surface_map::{
    build_pyramid, synthesize_surface as synthesize, write_surface_ply, Density, MeshLevel, SurfaceMap,
    MAX_VERTICES,
};
use btfsynth::synth::{LevelReport, State};
use btfsynth::{Error, Result};
use glam::Vec3;
use numpy::ndarray::Array3;
use numpy::PyArrayDyn;
use pyo3::prelude::*;
use pyo3::types::PyBytes;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// The user's mesh: a file, or arrays.
#[derive(Clone)]
pub enum Original {
    File(PathBuf),
    Arrays(Arc<Mesh>),
}

impl Original {
    /// What provenance and errors call it.
    pub fn name(&self) -> PathBuf {
        match self {
            Original::File(path) => path.clone(),
            Original::Arrays(_) => PathBuf::from(IN_MEMORY),
        }
    }

    /// The mesh exactly as given, for an export's geometry and layout.
    pub fn textured(&self) -> Result<TexturedMesh> {
        match self {
            Original::File(path) => load_textured(path),
            Original::Arrays(mesh) => Ok(TexturedMesh {
                positions: mesh.positions().to_vec(),
                triangles: mesh.triangles().to_vec(),
                uvs: None,
            }),
        }
    }
}

/// A synthesized surface: the remeshed finest level with, per vertex, the sample texel it
/// copies, its texton and its tangent frame.
#[pyclass(module = "btfsynth._native", frozen)]
pub struct Surface {
    level: MeshLevel,
    state: State,
    reports: Vec<LevelReport>,
    provenance: serde_json::Value,
    original: Original,
    analysis: Arc<AnalysisData>,
    /// The surface as the renderers and the exporter read it.
    scene: Arc<Scene>,
}

#[pymethods]
impl Surface {
    /// Vertex positions, float32 `[V, 3]` (a read-only view).
    #[getter]
    fn vertices<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyArrayDyn<f32>>> {
        let p = slf.get().level.mesh.positions();
        view(slf.as_any(), vec3s(p), &[p.len(), 3])
    }

    /// Triangles, uint32 `[F, 3]` of vertex indices (a read-only view).
    #[getter]
    fn faces<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyArrayDyn<u32>>> {
        let t = slf.get().level.mesh.triangles();
        view(slf.as_any(), t.as_flattened(), &[t.len(), 3])
    }

    /// Sample coordinates per vertex, int32 `[V, 2]` (column, row in sample texels; a view).
    #[getter]
    fn uv<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyArrayDyn<i32>>> {
        let uv = &slf.get().state.uv;
        view(slf.as_any(), uv.as_flattened(), &[uv.len(), 2])
    }

    /// Where each vertex lies within its texel, float32 `[V, 2]`: within half a texel of
    /// the texel's centre, zero where the synthesis gives whole texels. `uv + subtexel` is
    /// the coordinate `save_ply`, `render` and `export_gltf` use.
    #[getter]
    fn subtexel<'py>(slf: &Bound<'py, Self>) -> Bound<'py, PyArrayDyn<f32>> {
        let state = &slf.get().state;
        let places: Vec<f32> =
            (0..state.uv.len()).flat_map(|v| state.subtexel.get(v).copied().unwrap_or([0.0; 2])).collect();
        let array = numpy::ndarray::Array2::from_shape_vec((state.uv.len(), 2), places)
            .expect("two values per vertex");
        owned(slf.py(), array)
    }

    /// Texton label per vertex, uint16 `[V]` (a read-only view).
    #[getter]
    fn textons<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyArrayDyn<u16>>> {
        let labels = &slf.get().state.labels;
        view(slf.as_any(), labels, &[labels.len()])
    }

    /// The texture's direction s (its columns) per vertex, float32 `[V, 3]` unit tangents;
    /// with the normal n it makes the frame (s, n × s, n) (a read-only view).
    #[getter]
    fn frames<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyArrayDyn<f32>>> {
        let s = &slf.get().level.frames.s;
        view(slf.as_any(), vec3s(s), &[s.len(), 3])
    }

    /// One sample texel in model units.
    #[getter]
    fn texel(&self) -> f32 {
        self.level.texel
    }

    /// Per level (coarsest first), as the CLI's `--report` writes them.
    #[getter]
    fn reports<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        json(py, &serde_json::to_value(&self.reports).unwrap_or_default())
    }

    /// The parameters the PLY header records (preset, recipe, seed, orient, density, …).
    #[getter]
    fn params<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        json(py, &self.provenance)
    }

    /// Writes the surface map `btfsynth synth` writes (binary PLY: position, normal, frame
    /// direction, texton, u, v per vertex), atomically; refuses an existing file unless
    /// `overwrite`. For an analysis loaded from a directory and a mesh read from a file, the
    /// same bytes as the CLI's for the same inputs, output folder and seed.
    #[pyo3(signature = (path, overwrite=false))]
    fn save_ply(&self, py: Python<'_>, path: PathBuf, overwrite: bool) -> PyResult<PathBuf> {
        let analysis = self.analysis.dir().map_or_else(|| PathBuf::from(IN_MEMORY), Path::to_path_buf);
        let mesh = self.original.name();
        let written = py.allow_threads(|| -> Result<PathBuf> {
            check_file_target(&path, overwrite)?;
            btfsynth::fsutil::write_with_temp(&path, |tmp| {
                write_surface_ply(tmp, &self.level, &self.state, (&analysis, &mesh), &self.provenance)
            })?;
            Ok(path.clone())
        });
        written.py(py)
    }

    fn __repr__(&self) -> String {
        format!(
            "Surface({} vertices, {} faces, preset {})",
            self.level.mesh.vertex_count(),
            self.level.mesh.face_count(),
            self.provenance["preset"]
        )
    }
}

/// Positions as a flat slice of floats (glam's `Vec3` is three `f32`s, `repr(C)`).
pub fn vec3s(v: &[Vec3]) -> &[f32] {
    // SAFETY: Vec3 is #[repr(C)] { x, y, z: f32 } with no padding.
    unsafe { std::slice::from_raw_parts(v.as_ptr().cast::<f32>(), v.len() * 3) }
}

/// The mesh argument: a path, or `vertices` `[V, 3]` with `faces` `[F, 3]`.
pub fn original(
    py: Python<'_>,
    mesh: &Bound<'_, PyAny>,
    faces: Option<&Bound<'_, PyAny>>,
) -> PyResult<Original> {
    if let Some(faces) = faces {
        let positions = floats(mesh, "mesh", &[None, Some(3)], &["V", "3"])?;
        let n = positions.len() / 3;
        let triangles = indices(faces, "faces", &[None, Some(3)], &["F", "3"], n)?;
        let positions = positions.chunks_exact(3).map(|c| Vec3::new(c[0], c[1], c[2])).collect();
        let triangles = triangles.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
        let mesh = Mesh::new(positions, triangles).map_err(|e| value_error(py, "mesh", e))?;
        return Ok(Original::Arrays(Arc::new(mesh)));
    }
    match mesh.extract::<PathBuf>() {
        Ok(path) => Ok(Original::File(path)),
        Err(_) => Err(crate::errors::type_error(
            "mesh",
            format!(
                "expected a path, or vertex positions [V, 3] with faces=[F, 3]; got {}",
                crate::arrays::type_name(mesh)
            ),
        )),
    }
}

/// Refuses a finest mesh too small for `levels` levels of `side`² templates, or too large.
fn check_vertices(vertices: usize, what: &str, levels: usize, side: usize) -> Result<()> {
    let least = (4usize << (2 * (levels.max(1) - 1)).min(60)).max(side * side);
    if vertices < least || vertices > MAX_VERTICES {
        let message = format!(
            "gives a finest mesh of about {vertices} vertices; {levels} level(s) of {side}x{side} templates need {least} to {MAX_VERTICES}"
        );
        let param = match what {
            "scale" => btfsynth::Param::Scale,
            "texels_across" => btfsynth::Param::TexelsAcross,
            _ => btfsynth::Param::Vertices,
        };
        return Err(Error::out_of_range(param, vertices, message));
    }
    Ok(())
}

/// Synthesizes `analysis` on a mesh (a path, or `mesh=` vertices `[V, 3]` with
/// `faces=[F, 3]`) as `btfsynth synth ANALYSIS MESH` does: remeshed to one vertex per sample
/// texel at the density given (one of `vertices`, `texels_across`, `scale`; default 4 × the
/// sample's width across), then the preset's passes. `orient` is `smooth`, `axis:x,y,z` or a
/// constraints file, as `--orient`.
#[pyfunction]
#[pyo3(signature = (analysis, mesh, faces=None, *, vertices=None, texels_across=None, scale=None, preset="appearance",
    recipe=None, seed=0, levels=None, k=None, neighborhood=7, search="kcoherence", orient="smooth", progress=None))]
#[allow(clippy::too_many_arguments)]
pub fn synthesize_surface<'py>(
    py: Python<'py>,
    analysis: &Bound<'py, Analysis>,
    mesh: &Bound<'py, PyAny>,
    faces: Option<Bound<'py, PyAny>>,
    vertices: Option<usize>,
    texels_across: Option<f32>,
    scale: Option<f32>,
    preset: &'py str,
    recipe: Option<Bound<'py, PyAny>>,
    seed: u64,
    levels: Option<usize>,
    k: Option<usize>,
    neighborhood: usize,
    search: &'py str,
    orient: &'py str,
    progress: Option<PyObject>,
) -> PyResult<Surface> {
    let data = analysis.get().data.clone();
    let original = original(py, mesh, faces.as_ref())?;
    let density = match (vertices, texels_across, scale) {
        (Some(n), None, None) => Density::Vertices(n),
        (None, Some(n), None) if n.is_finite() && n > 0.0 => Density::TexelsAcross(n),
        (None, None, Some(s)) if s.is_finite() && s > 0.0 => Density::Scale(s),
        (None, None, None) => Density::TexelsAcross(4.0 * data.sample.manifest.width as f32),
        (None, Some(_), None) => return Err(value_error(py, "texels_across", "expected a positive number")),
        (None, None, Some(_)) => return Err(value_error(py, "scale", "expected a positive number")),
        _ => {
            return Err(value_error(py, "vertices", "give at most one of vertices, texels_across and scale"))
        }
    };
    let orientation = Orientation::parse(orient).map_err(|e| value_error(py, "orient", e))?;
    let choices = Choices { preset, recipe, seed, levels, k, neighborhood, search };
    let session = choices.session(py, &data, true)?;
    let mut provenance = session.provenance();
    provenance["orient"] = orient.into();
    provenance["density"] = density.to_string().into();
    let (shared, given) = (data.clone(), original.clone());
    let (level, state, reports, scene) = long::run(py, progress.as_ref(), move |hook| {
        let loaded;
        let mesh = match &given {
            Original::File(path) => {
                loaded = btfsynth::mesh::load(path)?;
                &loaded
            }
            Original::Arrays(mesh) => mesh.as_ref(),
        };
        let levels = session.levels();
        let what = match density {
            Density::Vertices(n) => (n, "vertices"),
            Density::Scale(_) | Density::TexelsAcross(_) => {
                let texel = density.texel(mesh)?;
                let estimate = mesh.surface_area() / (3f64.sqrt() / 2.0 * f64::from(texel).powi(2));
                let name = if matches!(density, Density::Scale(_)) { "scale" } else { "texels_across" };
                (estimate.round() as usize, name)
            }
        };
        check_vertices(what.0, what.1, levels, session.params().neighborhood)?;
        let pyramid = build_pyramid(mesh, density, levels, &orientation, session.params(), hook)?;
        let (state, mut reports) =
            with_sample(&shared, &session, |sample| synthesize(&pyramid, sample, session.params(), hook))?;
        reports.iter_mut().for_each(|r| r.device = None);
        let level =
            pyramid.levels.into_iter().next().ok_or_else(|| Error::internal("a pyramid without levels"))?;
        let scene = Scene::from_surface_map(SurfaceMap::from_synthesis(&level, &state));
        Ok((level, state, reports, Arc::new(scene)))
    })?;
    Ok(Surface { level, state, reports, provenance, original, analysis: data, scene })
}

/// The lighting of `env` as the CLI's `--env` and `--ambient` make it: the directional
/// light's strength and the environment.
fn lighting(env: Option<&str>, ambient: f32) -> Result<(f32, Option<Environment>)> {
    let (sun, environment) = match env {
        None => (1.0, None),
        Some("uniform") => (0.0, Some(Environment::uniform(Vec3::ONE))),
        Some("sky" | "sky+sun") => (1.0, Some(Environment::sky())),
        Some(file) => (0.0, Some(Environment::open(Path::new(file))?)),
    };
    Ok(match (environment, ambient) {
        (environment, a) if a <= 0.0 => (sun, environment),
        (Some(e), a) => (sun, Some(e.with_uniform(Vec3::splat(a)))),
        (None, a) => (sun, Some(Environment::uniform(Vec3::splat(a)))),
    })
}

/// Renders `surface` (a `Surface`, or a `PatchMap` from `method="soler2002"`) on the CPU as
/// `btfsynth render` renders its first frame: float32 `[height, width, 4]` linear RGB
/// premultiplied by coverage, and coverage. `material` shades it: by default the analysis
/// it was made from; an `Analysis` or a `Stack` of the same sample size (the whole measured
/// BTF, say, where the analysis kept fewer images). `view` and `light` are (θ, φ) in degrees
/// around the model; `env` is `sky`, `uniform` or an equirectangular `.hdr`/`.exr` file;
/// `mode` is `pixel` or `vertex`.
#[pyfunction]
#[pyo3(signature = (surface, material=None, *, size=(512, 512), view=(70.0, 0.0), light=(45.0, 45.0), env=None,
    ambient=0.0, spp=4, shadows=true, mode="pixel", orthographic=false),
    // Spelled out so that help() shows the tuples' values (pyo3 writes `...` for them).
    text_signature = "(surface, material=None, *, size=(512, 512), view=(70.0, 0.0), light=(45.0, 45.0), env=None, \
    ambient=0.0, spp=4, shadows=True, mode='pixel', orthographic=False)")]
#[allow(clippy::too_many_arguments)]
pub fn render<'py>(
    py: Python<'py>,
    surface: &Bound<'py, PyAny>,
    material: Option<&Bound<'py, PyAny>>,
    size: (u32, u32),
    view: (f32, f32),
    light: (f32, f32),
    env: Option<String>,
    ambient: f32,
    spp: u32,
    shadows: bool,
    mode: &str,
    orthographic: bool,
) -> PyResult<Bound<'py, PyArrayDyn<f32>>> {
    let (height, width) = size;
    if !(1..=16384).contains(&width) || !(1..=16384).contains(&height) {
        return Err(value_error(py, "size", format!("({height}, {width}): sides must be from 1 to 16384")));
    }
    if !valid_spp(spp) {
        return Err(value_error(py, "spp", format!("{spp}: expected a square number from 1 to 1024")));
    }
    if !ambient.is_finite() || ambient < 0.0 {
        return Err(value_error(py, "ambient", format!("{ambient}: expected a radiance of 0 or more")));
    }
    let mode = match mode {
        "pixel" => Mode::Pixel,
        "vertex" => Mode::Vertex,
        other => return Err(value_error(py, "mode", format!("'{other}': expected 'pixel' or 'vertex'"))),
    };
    for (name, (theta, phi)) in [("view", view), ("light", light)] {
        if !theta.is_finite() || !phi.is_finite() {
            return Err(value_error(py, name, "angles must be finite"));
        }
    }
    let (scene, analysis) = scene_of(surface)?;
    let shading = shading(py, material, &analysis)?;
    let plan = ShotPlan { size: (width, height), view, light, orthographic, ..ShotPlan::default() };
    let frame = long::run(py, None, move |_| {
        let material = match shading {
            Shading::Analysis(analysis) => analysis.material()?,
            Shading::Stack(btf) => Arc::new(Material::from_btf(&btf)?),
        };
        let (sun, environment) = lighting(env.as_deref(), ambient)?;
        let options = RenderOptions { mode, shadows, spp, sun };
        let tracer = Tracer::new(&scene.mesh);
        let shot = plan.shots(scene.mesh.bounds())[0];
        let mut cache = environment.map(|e| AmbientCache::new(&scene, &material, e, shadows));
        let ambient =
            cache.as_mut().map(|a| a.for_camera((&scene, &material), &shot.camera, Some(&tracer)).0);
        Ok(render_shot(&scene, &material, &tracer, &shot, options, ambient))
    })?;
    let array = Array3::from_shape_vec((frame.height, frame.width, 4), frame.rgba)
        .map_err(|e| Error::internal(e.to_string()))
        .py(py)?;
    Ok(owned(py, array))
}

/// What a render shades with: an analysis' sample, or a stack's images.
enum Shading {
    Analysis(Arc<AnalysisData>),
    Stack(Arc<btfsynth::btf::Btf>),
}

/// The scene and analysis of a `Surface` or a `PatchMap`.
fn scene_of(surface: &Bound<'_, PyAny>) -> PyResult<(Arc<Scene>, Arc<AnalysisData>)> {
    if let Ok(s) = surface.downcast::<Surface>() {
        return Ok((s.get().scene.clone(), s.get().analysis.clone()));
    }
    if let Ok(p) = surface.downcast::<PatchMap>() {
        return Ok((p.get().scene.clone(), p.get().analysis.clone()));
    }
    let got = crate::arrays::type_name(surface);
    Err(crate::errors::type_error("surface", format!("expected a Surface or a PatchMap, got {got}")))
}

/// `material` (None, an `Analysis` or a `Stack`) as what a render of `analysis`'s result
/// shades with; its sample must be the analysis' size (the coordinates index it).
fn shading(
    py: Python<'_>,
    material: Option<&Bound<'_, PyAny>>,
    analysis: &Arc<AnalysisData>,
) -> PyResult<Shading> {
    let (shading, size) = match material {
        None => return Ok(Shading::Analysis(analysis.clone())),
        Some(m) => match (m.downcast::<Analysis>(), m.downcast::<crate::stack::Stack>()) {
            (Ok(a), _) => {
                let data = a.get().data.clone();
                let size = (data.images.width, data.images.height);
                (Shading::Analysis(data), size)
            }
            (_, Ok(s)) => {
                let btf = s.get().btf.clone();
                let size = (btf.width(), btf.height());
                (Shading::Stack(btf), size)
            }
            _ => {
                let got = crate::arrays::type_name(m);
                return Err(crate::errors::type_error(
                    "material",
                    format!("expected an Analysis or a Stack, got {got}"),
                ));
            }
        },
    };
    let wanted = (analysis.images.width, analysis.images.height);
    if size != wanted {
        return Err(value_error(
            py,
            "material",
            format!(
                "a {}x{} sample; the surface's coordinates index a {}x{} one",
                size.0, size.1, wanted.0, wanted.1
            ),
        ));
    }
    Ok(shading)
}

/// `surface` as a `Surface`; a `PatchMap` is refused with the way to export it.
fn exported<'a, 'py>(surface: &'a Bound<'py, PyAny>) -> PyResult<&'a Bound<'py, Surface>> {
    surface.downcast::<Surface>().map_err(|_| {
        let got = crate::arrays::type_name(surface);
        let message = if surface.is_instance_of::<PatchMap>() {
            "expected a Surface: a PatchMap (method=\"soler2002\") is exported from its file, \
             PatchMap.save(\"x.ply\") then `btfsynth export x.ply -o x.glb`"
                .to_string()
        } else {
            format!("expected a Surface, got {got}")
        };
        crate::errors::type_error("surface", message)
    })
}

/// Bakes `surface` into a glTF binary (`.glb`) as `btfsynth export` does and returns its
/// bytes; with `path`, also writes them there atomically (refusing an existing file unless
/// `overwrite`). `size` is the atlas side in texels; `light` (θ, φ) the light a BTF is
/// baked under; `vertex_colors` writes the dense synthesized mesh with per-vertex colours.
#[pyfunction]
#[pyo3(signature = (surface, path=None, *, size=None, light=None, vertex_colors=false, name=None, overwrite=false, progress=None))]
#[allow(clippy::too_many_arguments)]
pub fn export_gltf<'py>(
    py: Python<'py>,
    surface: &Bound<'py, PyAny>,
    path: Option<PathBuf>,
    size: Option<u32>,
    light: Option<(f32, f32)>,
    vertex_colors: bool,
    name: Option<String>,
    overwrite: bool,
    progress: Option<PyObject>,
) -> PyResult<Bound<'py, PyBytes>> {
    if let Some(p) = &path {
        if p.extension().is_none_or(|e| !e.eq_ignore_ascii_case("glb")) {
            return Err(value_error(
                py,
                "path",
                format!("{}: the package writes binary glTF, a .glb file", p.display()),
            ));
        }
    }
    if let Some(size) = size.filter(|s| !btfsynth::export::SIZE_RANGE.contains(s)) {
        let range = &btfsynth::export::SIZE_RANGE;
        return Err(value_error(
            py,
            "size",
            format!("{size}: the atlas side must be from {} to {} texels", range.start(), range.end()),
        ));
    }
    let light = match light {
        Some((theta, phi)) => {
            Some(btfsynth::btf::Direction::new(theta, phi).map_err(|e| value_error(py, "light", e))?)
        }
        None => None,
    };
    let s = exported(surface)?.get();
    let (scene, analysis, original) = (s.scene.clone(), s.analysis.clone(), s.original.clone());
    let name = name.unwrap_or_else(|| match &original {
        Original::File(p) => p.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default(),
        Original::Arrays(_) => "btfsynth".into(),
    });
    let glb = long::run(py, progress.as_ref(), move |hook| {
        if let Some(p) = &path {
            check_file_target(p, overwrite)?;
        }
        let material = analysis.material()?;
        let mesh = if vertex_colors { None } else { Some(original.textured()?) };
        let (surface_name, mesh_name) = (PathBuf::from(IN_MEMORY), original.name());
        let analysis_name = analysis.dir().map_or_else(|| PathBuf::from(IN_MEMORY), Path::to_path_buf);
        let names = SourceNames { surface: &surface_name, analysis: &analysis_name, mesh: &mesh_name };
        let source =
            ExportSource { scene: &scene, material: &material, maps: &[], mesh: mesh.as_ref(), names };
        let options = ExportOptions {
            size,
            light,
            vertex_colours: vertex_colors,
            overwrite,
            ..ExportOptions::default()
        };
        let glb = bake_export(&name, &source, &options, hook)?.document.to_glb();
        if let Some(p) = &path {
            write_file_atomic(p, &glb)?;
        }
        Ok(glb)
    })?;
    Ok(PyBytes::new(py, &glb))
}
