//! Light from every direction: a uniform sky, the built-in sky preset, or an
//! equirectangular environment map (EXR or Radiance HDR), reduced to a uniform part and a
//! few thousand directional samples that [`super::ambient`] integrates over the light
//! directions' Voronoi cells.
//!
//! **Units.** Radiance is relative to the directional light of a render: a uniform sky of
//! radiance 1 lights a white Lambertian plane as much as the directional light does at
//! normal incidence (it delivers irradiance π, as does a directional light of strength 1
//! under the images' convention, which include the cosine of their light). So the weight
//! an environment gives the image of light cell *i* is (1/π) ∫_cell L(ω) dω, and a sample
//! of power π at a measured light direction reproduces that light's directional render.
//!
//! **Map orientation.** World +Y is up. Row `y` of an H-row map looks at θ = 180°·(y + ½)/H
//! from +Y (the top row is the zenith) and column `x` of a W-column map at azimuth
//! φ = 360°·(x + ½)/W about +Y, from +Z towards +X: the convention of a light's `θ,φ`, so
//! the pixel of an environment that lies in the direction of a light `θ,φ` lights from there.

use super::camera::world_direction;
use crate::{Error, Result};
use glam::Vec3;
use std::path::Path;

/// One directional sample of an environment: the light arriving from a small patch of the
/// sphere.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EnvSample {
    /// Unit world direction towards the light (the patch's power-weighted centre).
    pub direction: Vec3,
    /// Radiance integrated over the patch's solid angle (linear RGB).
    pub power: Vec3,
}

/// Radiance arriving from every direction of the sphere.
#[derive(Clone, Debug, PartialEq)]
pub struct Environment {
    /// Radiance arriving equally from every direction (linear RGB).
    pub uniform: Vec3,
    /// The rest of the light, as directional samples.
    pub samples: Vec<EnvSample>,
}

/// Longitude × latitude cells an environment map is reduced to: 4.5° cells, several per
/// light cell of a Bonn dome (about 15° across), so that sample placement does not show.
const MAP_CELLS: (usize, usize) = (80, 40);

/// The built-in sky's resolution: it varies slowly, so fewer samples suffice.
const SKY_CELLS: (usize, usize) = (48, 24);

impl Environment {
    /// A sky of the same radiance from every direction (an ambient term `F` is `uniform(F)`).
    pub fn uniform(radiance: Vec3) -> Environment {
        Environment { uniform: radiance, samples: Vec::new() }
    }

    /// The built-in clear sky (to go with a sun of strength 1): bluish at the zenith,
    /// paler towards the horizon, and a dim ground below it. A horizontal plane receives
    /// about a fifth of the sun's irradiance at normal incidence from it.
    pub fn sky() -> Environment {
        let zenith = Vec3::new(0.10, 0.16, 0.30);
        let horizon = Vec3::new(0.28, 0.30, 0.33);
        let ground = Vec3::new(0.06, 0.055, 0.05);
        let radiance = |d: Vec3| {
            if d.y < 0.0 {
                ground
            } else {
                horizon.lerp(zenith, d.y.sqrt())
            }
        };
        Environment::from_function(SKY_CELLS, radiance)
    }

    /// An environment of `columns × rows` equirectangular cells whose radiance at the cell
    /// centres is `radiance(direction)`.
    pub fn from_function((columns, rows): (usize, usize), radiance: impl Fn(Vec3) -> Vec3) -> Environment {
        let mut samples = Vec::with_capacity(columns * rows);
        for y in 0..rows {
            for x in 0..columns {
                let (theta, phi) = cell_centre(x, y, columns, rows);
                let direction = world_direction(theta.to_degrees(), phi.to_degrees());
                let power = radiance(direction) * cell_solid_angle(y, columns, rows);
                if power.max_element() > 0.0 {
                    samples.push(EnvSample { direction, power });
                }
            }
        }
        Environment { uniform: Vec3::ZERO, samples }
    }

    /// An equirectangular map (`[rows][columns]` linear RGB radiance, see the module notes),
    /// reduced to at most 80 × 40 cells: each cell keeps the power of the pixels in it,
    /// from their power-weighted mean direction, so a single bright pixel stays where it is.
    pub fn from_equirect(columns: usize, rows: usize, rgb: &[Vec3]) -> Result<Environment> {
        if columns == 0 || rows == 0 || rgb.len() != columns * rows {
            return Err(Error::invalid(format!(
                "environment map: {} pixels for {columns}x{rows}",
                rgb.len()
            )));
        }
        if let Some(bad) = rgb.iter().find(|p| !p.is_finite() || p.min_element() < 0.0) {
            return Err(Error::invalid(format!(
                "environment map: radiance {bad} is negative or not a number"
            )));
        }
        let (cw, ch) = (MAP_CELLS.0.min(columns), MAP_CELLS.1.min(rows));
        let mut power = vec![Vec3::ZERO; cw * ch];
        let mut centre = vec![Vec3::ZERO; cw * ch];
        for y in 0..rows {
            let solid_angle = cell_solid_angle(y, columns, rows);
            for x in 0..columns {
                let p = rgb[y * columns + x] * solid_angle;
                let (theta, phi) = cell_centre(x, y, columns, rows);
                let cell = (y * ch / rows) * cw + x * cw / columns;
                power[cell] += p;
                centre[cell] += world_direction(theta.to_degrees(), phi.to_degrees()) * luminance(p);
            }
        }
        let samples = power
            .iter()
            .zip(&centre)
            .filter(|(p, _)| p.max_element() > 0.0)
            .map(|(&power, &c)| EnvSample { direction: c.normalize_or(Vec3::Y), power })
            .collect();
        Ok(Environment { uniform: Vec3::ZERO, samples })
    }

    /// Reads an equirectangular map from an EXR (linear) or Radiance `.hdr` file.
    pub fn open(path: &Path) -> Result<Environment> {
        let ext = path.extension().map(|e| e.to_string_lossy().to_ascii_lowercase());
        if !matches!(ext.as_deref(), Some("exr" | "hdr")) {
            return Err(Error::format(path, "an environment map is an equirectangular .exr or .hdr file"));
        }
        let image = image::open(path)
            .map_err(|e| Error::format(path, format!("cannot read the environment map: {e}")))?
            .into_rgb32f();
        let (w, h) = (image.width() as usize, image.height() as usize);
        let rgb: Vec<Vec3> = image.pixels().map(|p| Vec3::new(p[0], p[1], p[2])).collect();
        Environment::from_equirect(w, h, &rgb).map_err(|e| Error::format(path, e.to_string()))
    }

    /// This environment plus a uniform sky of `radiance`.
    pub fn with_uniform(mut self, radiance: Vec3) -> Environment {
        self.uniform += radiance;
        self
    }

    /// True if it sends no light at all.
    pub fn is_dark(&self) -> bool {
        self.uniform.max_element() <= 0.0 && self.samples.is_empty()
    }

    /// Irradiance on a plane facing `normal`, divided by π (what the plane's white
    /// Lambertian albedo reflects): a check on the units, and a measure of how bright an
    /// environment is.
    pub fn lambert(&self, normal: Vec3) -> Vec3 {
        let directional: Vec3 = self.samples.iter().map(|s| s.power * s.direction.dot(normal).max(0.0)).sum();
        self.uniform + directional / std::f32::consts::PI
    }
}

fn luminance(c: Vec3) -> f32 {
    // Any positive weights would keep a lone pixel in place; these also centre colour well.
    0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z + 1e-30
}

/// (θ, φ) in radians of the centre of cell (x, y) of a `columns × rows` map.
fn cell_centre(x: usize, y: usize, columns: usize, rows: usize) -> (f32, f32) {
    let theta = std::f32::consts::PI * (y as f32 + 0.5) / rows as f32;
    let phi = std::f32::consts::TAU * (x as f32 + 0.5) / columns as f32;
    (theta, phi)
}

/// Solid angle of one cell of row `y`: 2π/columns × (cos θ₀ − cos θ₁).
pub fn cell_solid_angle(y: usize, columns: usize, rows: usize) -> f32 {
    let pi = std::f64::consts::PI;
    let (t0, t1) = (pi * y as f64 / rows as f64, pi * (y + 1) as f64 / rows as f64);
    (std::f64::consts::TAU / columns as f64 * (t0.cos() - t1.cos())) as f32
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f32::consts::PI;

    #[test]
    fn cells_cover_the_sphere() {
        let total: f32 = (0..40).map(|y| cell_solid_angle(y, 80, 40) * 80.0).sum();
        assert!((total - 4.0 * PI).abs() < 1e-4, "{total}");
    }

    #[test]
    fn a_uniform_map_lights_a_plane_like_a_uniform_sky() {
        // Reduced from 160×80 to 80×40 cells: the power is kept whatever the reduction.
        let env = Environment::from_equirect(160, 80, &vec![Vec3::ONE; 160 * 80]).unwrap();
        assert_eq!(env.samples.len(), 80 * 40);
        for n in [Vec3::Y, Vec3::X, Vec3::new(0.3, -0.5, 0.8).normalize()] {
            let l = env.lambert(n);
            assert!((l - Vec3::ONE).abs().max_element() < 5e-3, "{n}: {l}");
        }
    }

    #[test]
    fn a_lone_bright_pixel_keeps_its_direction_and_power() {
        let (w, h) = (161, 81);
        let mut rgb = vec![Vec3::ZERO; w * h];
        let (x, y) = (37, 12);
        rgb[y * w + x] = Vec3::new(2.0, 1.0, 0.5);
        let env = Environment::from_equirect(w, h, &rgb).unwrap();
        assert_eq!(env.samples.len(), 1);
        let (theta, phi) = cell_centre(x, y, w, h);
        let expected = world_direction(theta.to_degrees(), phi.to_degrees());
        assert!((env.samples[0].direction - expected).length() < 1e-5);
        let power = Vec3::new(2.0, 1.0, 0.5) * cell_solid_angle(y, w, h);
        assert!((env.samples[0].power - power).length() < 1e-7);
    }

    #[test]
    fn the_sky_is_brighter_above_than_below_and_moderate() {
        let sky = Environment::sky();
        let (up, down) = (sky.lambert(Vec3::Y), sky.lambert(Vec3::NEG_Y));
        assert!(up.y > 2.0 * down.y, "{up} vs {down}");
        assert!((0.1..0.4).contains(&up.y), "{up}");
    }

    #[test]
    fn maps_are_read_from_exr_and_hdr_files() {
        let dir = tempfile::tempdir().unwrap();
        let (w, h) = (8, 4);
        let image = image::Rgb32FImage::from_fn(w, h, |x, y| image::Rgb([x as f32, y as f32, 0.5]));
        for name in ["sky.exr", "sky.hdr"] {
            let path = dir.path().join(name);
            image.save(&path).unwrap();
            let env = Environment::open(&path).unwrap();
            let expected: f32 = (0..h as usize).map(|y| cell_solid_angle(y, 8, 4) * 8.0 * 0.5).sum();
            let blue: f32 = env.samples.iter().map(|s| s.power.z).sum();
            assert!((blue - expected).abs() < 1e-2 * expected, "{name}: {blue} vs {expected}");
            assert_eq!(env.samples.len(), 32);
        }
        let text = dir.path().join("sky.png");
        std::fs::write(&text, b"not an image").unwrap();
        assert!(Environment::open(&text).is_err());
        assert!(Environment::open(&dir.path().join("missing.exr")).is_err());
    }

    #[test]
    fn bad_maps_are_refused() {
        assert!(Environment::from_equirect(2, 2, &[Vec3::ONE; 3]).is_err());
        assert!(Environment::from_equirect(1, 1, &[Vec3::new(-1.0, 0.0, 0.0)]).is_err());
        assert!(Environment::from_equirect(1, 1, &[Vec3::splat(f32::NAN)]).is_err());
    }
}
