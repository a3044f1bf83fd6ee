//! `btfsynth.synthesize_plane` and `btfsynth.Plane`: texture synthesis on a grid, the CLI's
//! `synth ANALYSIS --plane WxH` without the files.

use crate::analysis::{Analysis, AnalysisData};
use crate::arrays::view;
use crate::errors::{value_error, IntoPy};
use crate::long;
use btfsynth::synth::plane::{synthesize_plane as plane, PlaneResult};
use btfsynth::synth::session::{SearchChoice, SynthSession, SynthSessionBuilder};
use btfsynth::synth::{Device, MetricKind, Preset, Sample};
use btfsynth::Result;
use numpy::{PyArrayDyn, PyArrayMethods};
use pyo3::prelude::*;
use std::sync::Arc;

/// The engine's choices as the CLI's `synth` flags make them, checked against `data`.
pub struct Choices<'py> {
    pub preset: &'py str,
    pub recipe: Option<Bound<'py, PyAny>>,
    pub seed: u64,
    pub levels: Option<usize>,
    pub k: Option<usize>,
    pub neighborhood: usize,
    pub search: &'py str,
}

impl Choices<'_> {
    /// The session, built as `btfsynth synth` builds it for a plane or, with `surface`, a
    /// mesh (on the CPU: the package has no GPU passes, whose results are the same bytes).
    pub fn session(&self, py: Python<'_>, data: &AnalysisData, surface: bool) -> PyResult<SynthSession> {
        let widest = btfsynth::synth::session::MAX_NEIGHBOURHOOD;
        if !(3..=widest).contains(&self.neighborhood) || self.neighborhood % 2 == 0 {
            return Err(value_error(
                py,
                "neighborhood",
                format!("{}: expected an odd whole number from 3 to {widest}", self.neighborhood),
            ));
        }
        let preset = match &self.recipe {
            Some(recipe) => {
                let text: String = py.import("json")?.call_method1("dumps", (recipe,))?.extract()?;
                Preset::from_json(&text).map_err(|e| value_error(py, "recipe", e))?
            }
            None => Preset::by_name(self.preset).py(py)?,
        };
        let search = match self.search {
            "kcoherence" => SearchChoice::KCoherence,
            "full" => SearchChoice::Full,
            other => {
                return Err(value_error(py, "search", format!("'{other}': expected 'kcoherence' or 'full'")))
            }
        };
        let mut builder = SynthSessionBuilder::new()
            .preset(preset)
            .neighbourhood(self.neighborhood)
            .seed(self.seed)
            .device(Device::Cpu)
            .search(search)
            .surface(surface);
        if let Some(levels) = self.levels {
            builder = builder.levels(levels);
        }
        if let Some(k) = self.k {
            builder = builder.k(k);
        }
        let session = builder.build(&data.sample.manifest).py(py)?;
        session.check_sample(&data.sample).py(py)?;
        Ok(session)
    }
}

/// The sample `session` runs on: the analysis' own (no copy) unless it uses fewer levels or
/// matches colours.
pub fn with_sample<T>(
    data: &AnalysisData,
    session: &SynthSession,
    run: impl FnOnce(&Sample) -> Result<T>,
) -> Result<T> {
    let colours = session.params().preset.uses(MetricKind::Colour);
    if session.levels() == data.sample.levels.len() && !colours {
        return run(&data.sample);
    }
    let mut sample = Sample {
        levels: data.sample.levels[..session.levels()].to_vec(),
        manifest: data.sample.manifest.clone(),
    };
    if colours {
        sample.set_colours(&data.images)?;
    }
    run(&sample)
}

/// A synthesized plane: per texel, the sample texel it copies and that texel's texton.
#[pyclass(module = "btfsynth._native", frozen)]
pub struct Plane {
    result: PlaneResult,
    analysis: Arc<AnalysisData>,
    provenance: serde_json::Value,
}

#[pymethods]
impl Plane {
    /// Sample coordinates, int32 `[h, w, 2]`: the column and row of the sample texel each
    /// texel copies (a read-only view).
    #[getter]
    fn uv<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyArrayDyn<i32>>> {
        let p = &slf.get().result;
        view(slf.as_any(), p.state.uv.as_flattened(), &[p.height, p.width, 2])
    }

    /// Texton labels, uint16 `[h, w]` (a read-only view).
    #[getter]
    fn textons<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyArrayDyn<u16>>> {
        let p = &slf.get().result;
        view(slf.as_any(), &p.state.labels, &[p.height, p.width])
    }

    /// `(height, width)`.
    #[getter]
    fn shape(&self) -> (usize, usize) {
        (self.result.height, self.result.width)
    }

    /// Whether the plane tiles without a seam.
    #[getter]
    fn tileable(&self) -> bool {
        self.result.tiles
    }

    /// The plane as a picture, float32 `[h, w, 3]` linear RGB: the sample's image nearest
    /// `view` and `light` ((θ, φ) in degrees) copied through `uv`. Without either, the image
    /// the CLI's `result.png` shows (view and light nearest the normal); with one, the other
    /// is the normal, as the CLI's `--view`/`--light`.
    #[pyo3(signature = (view=None, light=None))]
    fn image<'py>(
        &self,
        py: Python<'py>,
        view: Option<(f32, f32)>,
        light: Option<(f32, f32)>,
    ) -> PyResult<Bound<'py, PyArrayDyn<f32>>> {
        let images = &self.analysis.images;
        let probe = match (view, light) {
            (None, None) => images.default_probes().remove(0),
            (v, l) => {
                let (v, l) = (v.unwrap_or((0.0, 0.0)), l.unwrap_or((0.0, 0.0)));
                images.probes_for(&[([v.0, v.1], [l.0, l.1])]).remove(0)
            }
        };
        let (w, h) = (images.width as i32, images.height as i32);
        let rgb: Vec<f32> = self
            .result
            .state
            .uv
            .iter()
            .flat_map(|&[x, y]| {
                images.rgb(probe.image, x.clamp(0, w - 1) as usize, y.clamp(0, h - 1) as usize)
            })
            .collect();
        numpy::PyArray1::from_vec(py, rgb).reshape(vec![self.result.height, self.result.width, 3])
    }

    /// Per level (coarsest first): vertices, passes, seconds, mean candidates and mean best
    /// distance, as the CLI's `--report` writes them.
    #[getter]
    fn reports<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        json(py, &serde_json::to_value(&self.result.reports).unwrap_or_default())
    }

    /// The parameters, as `plane.json` records them (`params`): preset, recipe, seed, …
    #[getter]
    fn params<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        json(py, &self.provenance)
    }

    fn __repr__(&self) -> String {
        format!("Plane({}x{}, preset {})", self.result.width, self.result.height, self.provenance["preset"])
    }
}

/// A JSON value as Python objects.
pub fn json<'py>(py: Python<'py>, value: &serde_json::Value) -> PyResult<Bound<'py, PyAny>> {
    py.import("json")?.call_method1("loads", (value.to_string(),))
}

/// Synthesizes a `(height, width)` plane from `analysis`: the same result as
/// `btfsynth synth ANALYSIS --plane WxH` with the same preset (or recipe, a dict in the form
/// `params["recipe"]` records), seed, levels, k, neighbourhood and search. `tileable` makes
/// the plane repeat without a seam (`--tileable-output`).
#[pyfunction]
#[pyo3(signature = (analysis, size, *, preset="appearance", recipe=None, seed=0, tileable=false, levels=None, k=None,
    neighborhood=7, search="kcoherence", progress=None))]
#[allow(clippy::too_many_arguments)]
pub fn synthesize_plane<'py>(
    py: Python<'py>,
    analysis: &Bound<'py, Analysis>,
    size: (usize, usize),
    preset: &'py str,
    recipe: Option<Bound<'py, PyAny>>,
    seed: u64,
    tileable: bool,
    levels: Option<usize>,
    k: Option<usize>,
    neighborhood: usize,
    search: &'py str,
    progress: Option<PyObject>,
) -> PyResult<Plane> {
    let data = analysis.get().data.clone();
    let (height, width) = size;
    let choices = Choices { preset, recipe, seed, levels, k, neighborhood, search };
    let session = choices.session(py, &data, false)?;
    let provenance = session.provenance();
    let shared = data.clone();
    let mut result = long::run(py, progress.as_ref(), move |hook| {
        with_sample(&shared, &session, |sample| {
            plane(sample, (width, height), tileable, session.params(), hook)
        })
    })?;
    // As a result file records them: equal inputs, equal values.
    for r in &mut result.reports {
        r.device = None;
    }
    Ok(Plane { result, analysis: data, provenance })
}
