//! Synthetic BTFs: `btfsynth gen`. Measured BTFs cannot be downloaded here, so ground truth
//! is made as in Tong et al. 2002 (Fig. 8): a height field with albedo variation is
//! ray-traced from every view and light direction of a measurement dome.
//!
//! Images are rectified on the reference plane (the field's mean height), as in a measured
//! BTF: pixel (col, row) always shows the same point of that plane, so points above it move
//! with the view (parallax) and hide what is behind them (occlusion). Column runs along the
//! tangent s; rows run down the tangent t (t points up in the image, as seen from above).

pub mod materials;
pub mod trace;

use crate::btf::{Btf, Direction, DirectionPair, DirectionSet};
use crate::progress::Progress;
use crate::{Error, Param, Result};
use glam::Vec3;
use half::f16;
use materials::{unit, Bricks, Material, Pebbles, Weave};
use rayon::prelude::*;
use trace::{HeightField, Hit};

/// The procedural materials `gen` can make.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum MaterialKind {
    /// Rounded stones on a sandy ground, one per cell of a jittered grid.
    Pebbles,
    /// A plain weave of red warp and beige weft threads.
    Weave,
    /// Running-bond bricks with bevelled edges and mortar grooves.
    Bricks,
}

impl MaterialKind {
    /// Every kind with a one-line description, for listing them.
    pub const ALL: [(MaterialKind, &'static str); 3] = [
        (MaterialKind::Pebbles, "rounded stones on a sandy ground (Worley-like cells)"),
        (MaterialKind::Weave, "plain weave: interlaced red warp and beige weft threads"),
        (MaterialKind::Bricks, "running-bond bricks with bevelled edges and mortar grooves"),
    ];

    /// The kind's name on the command line and in manifests (`pebbles`, `weave`, `bricks`).
    pub fn name(self) -> &'static str {
        match self {
            MaterialKind::Pebbles => "pebbles",
            MaterialKind::Weave => "weave",
            MaterialKind::Bricks => "bricks",
        }
    }

    fn material(self, size: usize, seed: u64) -> Box<dyn Material> {
        match self {
            MaterialKind::Pebbles => Box::new(Pebbles::new(size, seed)),
            MaterialKind::Weave => Box::new(Weave::new(size, seed)),
            MaterialKind::Bricks => Box::new(Bricks::new(size, seed)),
        }
    }
}

/// Parameters of a generated stack.
#[derive(Clone, Debug)]
pub struct GenParams {
    /// Width and height of the sample in pixels (default 64).
    pub size: usize,
    /// The dome used for both views and lights; every view × light pair is rendered
    /// (default `ubo81`, 6561 images).
    pub directions: DirectionSet,
    /// Seed of the material's random layout (default 0).
    pub seed: u64,
    /// Samples per pixel, a square number: stratified and jittered (default 4).
    pub samples_per_pixel: usize,
}

impl Default for GenParams {
    fn default() -> Self {
        GenParams { size: 64, directions: DirectionSet::Ubo81, seed: 0, samples_per_pixel: 4 }
    }
}

impl GenParams {
    /// Checks the size and the samples per pixel; [`generate`] does it first.
    pub fn validate(&self) -> Result<()> {
        if !(4..=2048).contains(&self.size) {
            return Err(Error::out_of_range(Param::SampleSize, self.size, "outside 4..=2048 pixels"));
        }
        let root = (self.samples_per_pixel as f64).sqrt().round() as usize;
        if root == 0 || root * root != self.samples_per_pixel || root > 8 {
            return Err(Error::out_of_range(
                Param::SamplesPerPixel,
                self.samples_per_pixel,
                "must be a square number from 1 to 64",
            ));
        }
        Ok(())
    }
}

/// Renders `kind` on every view × light pair of `params.directions`. Deterministic: the
/// same parameters give the same pixels whatever the thread count.
pub fn generate(kind: MaterialKind, params: &GenParams, progress: &dyn Progress) -> Result<Btf> {
    let dome = params.directions.directions();
    generate_pairs(kind, params, &dome, &dome, progress)
}

/// Renders `kind` for every pair of `views` × `lights` (view-major: all lights of the first
/// view, then the next); `params.directions` is ignored.
pub fn generate_pairs(
    kind: MaterialKind,
    params: &GenParams,
    views: &[Direction],
    lights: &[Direction],
    progress: &dyn Progress,
) -> Result<Btf> {
    params.validate()?;
    if views.is_empty() || lights.is_empty() {
        return Err(Error::invalid("generation needs at least one view and one light"));
    }
    let material = kind.material(params.size, params.seed);
    let max_theta = views.iter().map(|d| d.theta).fold(0.0, f32::max);
    let field = HeightField::new(material.as_ref(), params.size, max_theta);
    tracing::debug!(triangles = field.triangle_count(), "height field meshed");

    let samples = subsamples(params);
    progress.start("tracing views", views.len() as u64);
    let hits: Vec<Vec<Option<Hit>>> = views
        .par_iter()
        .map(|view| {
            let unit = view.unit();
            let hits = samples.iter().map(|&(x, y)| field.primary(x, y, unit)).collect();
            progress.advance(1);
            hits
        })
        .collect();
    progress.finish();

    let per_pixel = params.samples_per_pixel;
    let per_image = params.size * params.size * 3;
    let mut pixels = vec![f16::ZERO; per_image * views.len() * lights.len()];
    progress.start("shading images", (views.len() * lights.len()) as u64);
    pixels.par_chunks_mut(per_image).enumerate().for_each(|(i, image)| {
        let (v, l) = (i / lights.len(), i % lights.len());
        let (view, light) = (views[v].unit(), lights[l].unit());
        for (pixel, out) in image.chunks_exact_mut(3).enumerate() {
            let sum: Vec3 = hits[v][pixel * per_pixel..(pixel + 1) * per_pixel]
                .iter()
                .flatten()
                .map(|hit| field.shade(hit, view, light))
                .sum();
            let rgb = sum / per_pixel as f32;
            out.copy_from_slice(&[f16::from_f32(rgb.x), f16::from_f32(rgb.y), f16::from_f32(rgb.z)]);
        }
        progress.advance(1);
    });
    progress.finish();
    let pairs = views
        .iter()
        .flat_map(|&view| lights.iter().map(move |&light| DirectionPair { light, view }))
        .collect();
    Btf::new(params.size, params.size, pairs, pixels)
}

/// Sample positions on the reference plane, pixel-major: a jittered √spp × √spp grid per
/// pixel. Row 0 is at the top of the image, i.e. at the largest t.
fn subsamples(params: &GenParams) -> Vec<(f32, f32)> {
    let n = params.size;
    let root = (params.samples_per_pixel as f64).sqrt().round() as usize;
    let mut out = Vec::with_capacity(n * n * params.samples_per_pixel);
    for row in 0..n {
        for col in 0..n {
            for k in 0..params.samples_per_pixel {
                let (a, b) = ((k % root) as f32, (k / root) as f32);
                let jx = unit(params.seed, col as i64, row as i64, 2 * k as i64 + 100);
                let jy = unit(params.seed, col as i64, row as i64, 2 * k as i64 + 101);
                let x = col as f32 + (a + jx) / root as f32;
                let y = (n - row) as f32 - (b + jy) / root as f32;
                out.push((x, y));
            }
        }
    }
    out
}
