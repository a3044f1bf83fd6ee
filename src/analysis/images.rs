//! The sample images an analysis directory stores (`images.npy`, `directions.npy`), and the
//! few view/light pairs a result is shown and judged under.

use super::npy;
use crate::btf::factored::FactoredStack;
use crate::eval::Picture;
use crate::{Error, Result};
use half::f16;
use serde::Serialize;
use std::path::Path;

/// Every image of the analysed stack with its directions.
pub struct SampleImages {
    /// Width of every image in texels.
    pub width: usize,
    /// Height of every image in texels.
    pub height: usize,
    values: Values,
    /// Per image: θ_light, φ_light, θ_view, φ_view in degrees.
    directions: Vec<[f32; 4]>,
}

/// Where the values come from.
enum Values {
    /// `[n][h][w][3]` linear RGB (`images.npy`).
    Pixels(Vec<f16>),
    /// The sample's factors: each value a K-term product per channel, decoded when asked.
    Factors(Box<FactoredStack>),
}

/// One view/light pair to show a result under: its image and a name for files and tables.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Probe {
    /// `head-on`, `light-45` or `grazing` (the default set), or the asked-for angles.
    pub name: String,
    /// Index of the probe's image in the stack.
    pub image: usize,
    /// θ, φ of the view and the light in degrees, as measured.
    pub view: [f32; 2],
    /// θ, φ of the light in degrees, as measured.
    pub light: [f32; 2],
}

impl Probe {
    /// Bonn-style angles for file names, e.g. `tv000_pv000_tl045_pl000`.
    pub fn angles_tag(&self) -> String {
        let a = |v: f32| v.round() as i64;
        format!(
            "tv{:03}_pv{:03}_tl{:03}_pl{:03}",
            a(self.view[0]),
            a(self.view[1]).rem_euclid(360),
            a(self.light[0]),
            a(self.light[1]).rem_euclid(360)
        )
    }
}

impl SampleImages {
    /// Reads the images and directions of the analysis in `dir`.
    pub fn open(dir: &Path) -> Result<Self> {
        if !dir.join("images.npy").exists() {
            let manifest = super::store::read_manifest(dir)?;
            if manifest.sample.is_some() {
                let f = super::store::read_factors(dir, &manifest)?;
                let directions = f
                    .pairs()
                    .iter()
                    .map(|p| [p.light.theta, p.light.phi, p.view.theta, p.view.phi])
                    .collect();
                return Ok(SampleImages {
                    width: f.width(),
                    height: f.height(),
                    values: Values::Factors(Box::new(f)),
                    directions,
                });
            }
        }
        let images: npy::NpyArray<f16> = npy::read(&dir.join("images.npy"))?;
        let directions: npy::NpyArray<f32> = npy::read(&dir.join("directions.npy"))?;
        let [n, h, w, 3] = images.shape[..] else {
            return Err(Error::format(dir.join("images.npy"), "expected shape [n, h, w, 3]"));
        };
        if n == 0 || directions.shape != [n, 4] {
            return Err(Error::format(dir.join("directions.npy"), format!("expected shape [{n}, 4]")));
        }
        crate::btf::directions::pairs_from_rows(&directions.data)
            .map_err(|m| Error::format(dir.join("directions.npy"), m))?;
        let directions = directions.data.chunks_exact(4).map(|c| [c[0], c[1], c[2], c[3]]).collect();
        Ok(SampleImages { width: w, height: h, values: Values::Pixels(images.data), directions })
    }

    /// The images and directions of `btf`, held in memory: what [`SampleImages::open`] reads
    /// back from the directory an analysis of `btf` was written to (one copy of the pixels).
    pub fn from_btf(btf: &crate::btf::Btf) -> Self {
        let directions =
            btf.pairs().iter().map(|p| [p.light.theta, p.light.phi, p.view.theta, p.view.phi]).collect();
        let values = Values::Pixels(btf.pixels().to_vec());
        SampleImages { width: btf.width(), height: btf.height(), values, directions }
    }

    /// Number of images.
    pub fn len(&self) -> usize {
        self.directions.len()
    }

    /// Whether there are no images.
    pub fn is_empty(&self) -> bool {
        self.directions.is_empty()
    }

    /// Linear RGB of image `i` at texel (x, y) (which must lie inside).
    #[inline]
    pub fn rgb(&self, i: usize, x: usize, y: usize) -> [f32; 3] {
        match &self.values {
            Values::Pixels(pixels) => {
                let o = ((i * self.height + y) * self.width + x) * 3;
                [pixels[o].to_f32(), pixels[o + 1].to_f32(), pixels[o + 2].to_f32()]
            }
            Values::Factors(f) => f.rgb(i, y * self.width + x),
        }
    }

    /// Whether the values are computed from factors rather than read from images.
    pub fn is_factored(&self) -> bool {
        matches!(self.values, Values::Factors(_))
    }

    /// Image `i` as a picture.
    pub fn picture(&self, i: usize) -> Picture {
        let (w, h) = (self.width, self.height);
        Picture::from_linear(w, h, (0..w * h).map(|p| self.rgb(i, p % w, p / w)))
    }

    /// Image `i` copied through sample coordinates (clamped into the sample).
    pub fn through(&self, i: usize, width: usize, height: usize, uv: &[[i32; 2]]) -> Picture {
        let clamp = |v: i32, n: usize| v.clamp(0, n as i32 - 1) as usize;
        Picture::from_linear(
            width,
            height,
            uv.iter().map(|&[x, y]| self.rgb(i, clamp(x, self.width), clamp(y, self.height))),
        )
    }

    /// The probe of image `i` under `name`.
    fn probe(&self, name: &str, i: usize) -> Probe {
        let d = self.directions[i];
        Probe { name: name.to_string(), image: i, view: [d[2], d[3]], light: [d[0], d[1]] }
    }

    /// The default set: `head-on` (view and light nearest the normal), `light-45` (the view
    /// nearest the normal, the light nearest 45°) and `grazing` (that view, the light
    /// farthest from the normal), where the measured stack has them; one probe for a
    /// one-image BTF.
    pub fn default_probes(&self) -> Vec<Probe> {
        let by = |key: &dyn Fn(&[f32; 4]) -> f32| {
            (0..self.len()).min_by(|&a, &b| key(&self.directions[a]).total_cmp(&key(&self.directions[b])))
        };
        let head_on = by(&|d| d[0] + d[2]).unwrap_or(0);
        let view = self.directions[head_on][2];
        let from_view = |d: &[f32; 4]| 1000.0 * (d[2] - view).abs();
        let light_45 = by(&|d| from_view(d) + (d[0] - 45.0).abs()).unwrap_or(head_on);
        let grazing = by(&|d| from_view(d) - d[0]).unwrap_or(head_on);
        let mut probes = vec![self.probe("head-on", head_on)];
        for (name, i) in [("light-45", light_45), ("grazing", grazing)] {
            if probes.iter().all(|p| p.image != i) {
                probes.push(self.probe(name, i));
            }
        }
        probes
    }

    /// The measured images nearest each asked (view, light) pair, by summed angular
    /// distance of the two directions.
    pub fn probes_for(&self, pairs: &[([f32; 2], [f32; 2])]) -> Vec<Probe> {
        pairs
            .iter()
            .map(|&(view, light)| {
                let cost = |d: &[f32; 4]| angle(view, [d[2], d[3]]) + angle(light, [d[0], d[1]]);
                let i = (0..self.len())
                    .min_by(|&a, &b| cost(&self.directions[a]).total_cmp(&cost(&self.directions[b])))
                    .unwrap_or(0);
                let name =
                    format!("view {:.0},{:.0} light {:.0},{:.0}", view[0], view[1], light[0], light[1]);
                self.probe(&name, i)
            })
            .collect()
    }
}

/// Angle in degrees between two (θ, φ) directions given in degrees.
fn angle(a: [f32; 2], b: [f32; 2]) -> f32 {
    let unit = |[t, p]: [f32; 2]| {
        let (t, p) = (t.to_radians(), p.to_radians());
        glam::Vec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos())
    };
    unit(a).dot(unit(b)).clamp(-1.0, 1.0).acos().to_degrees()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn images(directions: Vec<[f32; 4]>) -> SampleImages {
        let n = directions.len();
        SampleImages { width: 2, height: 2, values: Values::Pixels(vec![f16::ZERO; n * 12]), directions }
    }

    #[test]
    fn default_probes_pick_head_on_45_and_grazing_lights_under_the_frontal_view() {
        let dome = images(vec![
            [30.0, 0.0, 0.0, 0.0],
            [0.0, 0.0, 0.0, 0.0],
            [45.0, 90.0, 0.0, 0.0],
            [75.0, 0.0, 0.0, 0.0],
            [75.0, 0.0, 60.0, 0.0],
            [45.0, 0.0, 30.0, 0.0],
        ]);
        let probes = dome.default_probes();
        let picked: Vec<(&str, usize)> = probes.iter().map(|p| (p.name.as_str(), p.image)).collect();
        assert_eq!(picked, [("head-on", 1), ("light-45", 2), ("grazing", 3)]);
        assert_eq!(probes[2].angles_tag(), "tv000_pv000_tl075_pl000");
        assert_eq!(images(vec![[0.0; 4]]).default_probes().len(), 1);
    }

    #[test]
    fn asked_pairs_map_to_the_nearest_measured_image() {
        let dome = images(vec![[0.0, 0.0, 0.0, 0.0], [60.0, 180.0, 30.0, 0.0], [60.0, 0.0, 30.0, 0.0]]);
        let probes = dome.probes_for(&[([28.0, 5.0], [58.0, -170.0])]);
        assert_eq!(probes[0].image, 1);
    }
}
