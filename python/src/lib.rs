//! The Python face of btfsynth (`btfsynth._native`, wrapped by the `btfsynth` package):
//! the library's in-memory pipeline with numpy arrays in and out. Every function calls the
//! same library entry points as the CLI, so the same inputs and seed give the CLI's values;
//! long calls release the GIL, report progress and stop on Ctrl-C ([`long`]); library errors
//! become the `btfsynth.Error` hierarchy ([`errors`]).

mod analysis;
mod arrays;
mod errors;
mod long;
mod patches;
mod plane;
mod stack;
mod surface;

use pyo3::prelude::*;

/// The presets `synth --list-presets` lists: dicts of `name`, `paper` and the whole
/// `recipe` (the form `recipe=` takes).
#[pyfunction]
fn presets(py: Python<'_>) -> PyResult<Vec<Bound<'_, PyAny>>> {
    btfsynth::synth::Preset::all()
        .iter()
        .map(|p| {
            let value = serde_json::json!({"name": p.name, "paper": p.paper, "recipe": p.to_json()});
            plane::json(py, &value)
        })
        .collect()
}

#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add_class::<stack::Stack>()?;
    m.add_class::<analysis::Analysis>()?;
    m.add_class::<plane::Plane>()?;
    m.add_class::<surface::Surface>()?;
    m.add_class::<patches::PatchMap>()?;
    m.add_function(wrap_pyfunction!(analysis::analyze, m)?)?;
    m.add_function(wrap_pyfunction!(analysis::analysis_from_files, m)?)?;
    m.add_function(wrap_pyfunction!(plane::synthesize_plane, m)?)?;
    m.add_function(wrap_pyfunction!(surface::synthesize_surface, m)?)?;
    m.add_function(wrap_pyfunction!(patches::map_patches, m)?)?;
    m.add_function(wrap_pyfunction!(surface::render, m)?)?;
    m.add_function(wrap_pyfunction!(surface::export_gltf, m)?)?;
    m.add_function(wrap_pyfunction!(presets, m)?)?;
    m.add_function(wrap_pyfunction!(long::running, m)?)?;
    Ok(())
}
