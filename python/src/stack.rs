//! `btfsynth.Stack`: a BTF sample in memory, from numpy arrays or from any path the CLI
//! reads, decoded to linear RGB (f16, the library's storage).

use crate::arrays::{checked, floats, values};
use crate::errors::{value_error, IntoPy};
use crate::long;
use btfsynth::analysis::input::{self, Mode};
use btfsynth::analysis::pipeline::AnalysisParams;
use btfsynth::btf::image_io::srgb_to_linear;
use btfsynth::btf::{Btf, Crop, Direction, DirectionPair};
use half::f16;
use numpy::{PyArrayDyn, PyArrayMethods, PyUntypedArrayMethods};
use pyo3::prelude::*;
use std::path::PathBuf;
use std::sync::Arc;

/// A BTF stack: `len` images of `height × width` linear RGB, image `i` seen from `view[i]`
/// and lit from `light[i]` (θ, φ in degrees).
///
/// Make one with `Stack.from_arrays`, `Stack.from_image` or `Stack.open`.
#[pyclass(module = "btfsynth._native", frozen)]
pub struct Stack {
    pub btf: Arc<Btf>,
    /// The file it was read from, or `(in memory)`: what an analysis records as its source.
    pub source: PathBuf,
    pub crop: Option<Crop>,
}

/// The path an analysis records for arrays.
pub const IN_MEMORY: &str = "(in memory)";

/// `[θ, φ]` rows of `obj` as directions, named `name` in errors.
fn directions(py: Python<'_>, obj: &Bound<'_, PyAny>, name: &str, n: usize) -> PyResult<Vec<Direction>> {
    let v = floats(obj, name, &[Some(n), Some(2)], &["N", "2"])?;
    v.chunks_exact(2)
        .enumerate()
        .map(|(i, c)| Direction::new(c[0], c[1]).map_err(|e| value_error(py, name, format!("row {i}: {e}"))))
        .collect()
}

#[pymethods]
impl Stack {
    /// A stack from arrays: `images` float32 `[N, H, W, 3]` linear RGB, `view` and `light`
    /// `[N, 2]` (θ from the normal 0–90, φ −360–360, in degrees; float32 or float64).
    #[staticmethod]
    fn from_arrays(
        py: Python<'_>,
        images: &Bound<'_, PyAny>,
        view: &Bound<'_, PyAny>,
        light: &Bound<'_, PyAny>,
    ) -> PyResult<Stack> {
        let (array, _) =
            checked(images, "images", &["float32"], &[None, None, None, Some(3)], &["N", "H", "W", "3"])?;
        let shape = array.shape().to_vec();
        let pixels = values::<f32>(&array)?;
        if let Some(i) = pixels.iter().position(|v| !v.is_finite() || *v < 0.0) {
            return Err(value_error(
                py,
                "images",
                format!("expected finite values ≥ 0 (linear RGB), got {} at flat index {i}", pixels[i]),
            ));
        }
        let n = shape[0];
        let views = directions(py, view, "view", n)?;
        let lights = directions(py, light, "light", n)?;
        let pairs =
            views.into_iter().zip(lights).map(|(view, light)| DirectionPair { light, view }).collect();
        let pixels = pixels.into_iter().map(f16::from_f32).collect();
        let btf = Btf::new(shape[2], shape[1], pairs, pixels).py(py)?;
        Ok(Stack { btf: Arc::new(btf), source: IN_MEMORY.into(), crop: None })
    }

    /// A one-image BTF (seen and lit along the normal) from an `[H, W, 3]` array: uint8 is
    /// sRGB and decoded to linear as the CLI decodes an 8-bit photo; float32/float64 is taken
    /// as linear RGB.
    #[staticmethod]
    fn from_image(py: Python<'_>, image: &Bound<'_, PyAny>) -> PyResult<Stack> {
        let dtypes = ["uint8", "float32", "float64"];
        let (array, dtype) = checked(image, "image", &dtypes, &[None, None, Some(3)], &["H", "W", "3"])?;
        let shape = array.shape().to_vec();
        let pixels: Vec<f16> = if dtype == "uint8" {
            let lut: Vec<f16> =
                (0..=255u8).map(|v| f16::from_f32(srgb_to_linear(v as f32 / 255.0))).collect();
            values::<u8>(&array)?.into_iter().map(|v| lut[v as usize]).collect()
        } else {
            let linear = floats(image, "image", &[None, None, Some(3)], &["H", "W", "3"])?;
            if let Some(i) = linear.iter().position(|v| *v < 0.0) {
                return Err(value_error(
                    py,
                    "image",
                    format!("expected linear RGB ≥ 0, got {} at flat index {i}", linear[i]),
                ));
            }
            linear.into_iter().map(f16::from_f32).collect()
        };
        let normal = DirectionPair { light: Direction::NORMAL, view: Direction::NORMAL };
        let btf = Btf::new(shape[1], shape[0], vec![normal], pixels).py(py)?;
        Ok(Stack { btf: Arc::new(btf), source: IN_MEMORY.into(), crop: None })
    }

    /// Reads a stack from any path the CLI reads (a folder, a `btf.json`, a Bonn `.btf`, a
    /// UBO2003/ATRIUM zip, one photo), decoded; `crop` is `(x, y, w, h)` in pixels. A stack too
    /// large to decode is refused: `analyze(path)` analyses those from their factors.
    #[staticmethod]
    #[pyo3(signature = (path, crop=None, progress=None))]
    fn open(
        py: Python<'_>,
        path: PathBuf,
        crop: Option<(u32, u32, u32, u32)>,
        progress: Option<PyObject>,
    ) -> PyResult<Stack> {
        let crop = crop_of(py, crop)?;
        let source = path.clone();
        let btf = long::run(py, progress.as_ref(), move |hook| {
            match input::open(&path, crop, Mode::Decoded, &AnalysisParams::default(), hook)? {
                input::Input::Images(btf) => Ok(btf),
                _ => Err(btfsynth::Error::internal("a decoded stack was not decoded")),
            }
        })?;
        Ok(Stack { btf: Arc::new(btf), source, crop })
    }

    /// Image width in pixels.
    #[getter]
    fn width(&self) -> usize {
        self.btf.width()
    }

    /// Image height in pixels.
    #[getter]
    fn height(&self) -> usize {
        self.btf.height()
    }

    fn __len__(&self) -> usize {
        self.btf.len()
    }

    /// The images as float32 `[N, H, W, 3]` linear RGB (a copy: the stack stores f16).
    #[getter]
    fn images<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArrayDyn<f32>>> {
        let b = &self.btf;
        let data: Vec<f32> = b.pixels().iter().map(|v| v.to_f32()).collect();
        numpy::PyArray1::from_vec(py, data).reshape(vec![b.len(), b.height(), b.width(), 3])
    }

    /// View directions `[N, 2]` (θ, φ in degrees).
    #[getter]
    fn view<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArrayDyn<f32>>> {
        self.angles(py, |p| p.view)
    }

    /// Light directions `[N, 2]` (θ, φ in degrees).
    #[getter]
    fn light<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArrayDyn<f32>>> {
        self.angles(py, |p| p.light)
    }

    fn __repr__(&self) -> String {
        format!(
            "Stack({} images of {}x{}, from {})",
            self.btf.len(),
            self.btf.width(),
            self.btf.height(),
            self.source.display()
        )
    }
}

impl Stack {
    fn angles<'py>(
        &self,
        py: Python<'py>,
        pick: impl Fn(&DirectionPair) -> Direction,
    ) -> PyResult<Bound<'py, PyArrayDyn<f32>>> {
        let data: Vec<f32> = self.btf.pairs().iter().flat_map(|p| [pick(p).theta, pick(p).phi]).collect();
        numpy::PyArray1::from_vec(py, data).reshape(vec![self.btf.len(), 2])
    }
}

/// `(x, y, w, h)` as a crop with a non-empty size.
pub fn crop_of(py: Python<'_>, crop: Option<(u32, u32, u32, u32)>) -> PyResult<Option<Crop>> {
    match crop {
        Some((_, _, 0, _) | (_, _, _, 0)) => {
            Err(value_error(py, "crop", "width and height must be at least 1"))
        }
        Some((x, y, width, height)) => Ok(Some(Crop { x, y, width, height })),
        None => Ok(None),
    }
}
