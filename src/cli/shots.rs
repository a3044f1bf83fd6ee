//! Options that `render` and `view` share: which surface, which shots, which shading.

use super::hints::with_force_hint;
use anyhow::Result;
use btfsynth::render::scene::{open_surface, Scene};
use btfsynth::render::{Environment, FrameFormat, Mode, Orbit, ShotPlan};
use glam::Vec3;
use std::path::PathBuf;

/// The most frames of one run: every frame's thumbnail stays in memory until the contact
/// sheet is drawn (256 pixels wide, up to 1 MiB each).
pub const MAX_FRAMES: usize = 1000;

/// The surface map, the camera and light, and the shading mode.
#[derive(clap::Args, Clone, Debug)]
pub struct ShotArgs {
    /// The surface map to render (a PLY from `btfsynth synth`).
    pub surface: PathBuf,
    /// The analysis directory [default: the one named in the surface map's header, found
    /// relative to the surface map, else at its absolute path].
    #[arg(long, value_name = "DIR")]
    pub analysis: Option<PathBuf>,
    /// Use the analysis even if its fingerprint differs from the one the surface map was
    /// synthesized from (an analysis of another sample).
    #[arg(long)]
    pub force_analysis: bool,
    /// Image size in pixels.
    #[arg(long, value_name = "WxH", default_value = "512x512", value_parser = parse_size)]
    pub size: (u32, u32),
    /// Number of frames, 1 to 1000 (each is kept as a thumbnail for the contact sheet).
    /// With more than one and no --view-orbit, the light orbits.
    #[arg(long, default_value_t = 1, value_parser = super::in_range(1, MAX_FRAMES))]
    pub frames: usize,
    /// The light circles the model at its --light elevation, one turn over the frames.
    #[arg(long)]
    pub light_orbit: bool,
    /// The camera circles the model at its --view elevation, one turn over the frames.
    #[arg(long)]
    pub view_orbit: bool,
    /// Light direction θ,φ in degrees: θ from the world's +Y (up), φ about Y from +Z
    /// towards +X (at frame 0 of an orbit).
    #[arg(long, value_name = "θ,φ", default_value = "45,45", value_parser = parse_angles)]
    pub light: (f32, f32),
    /// Camera direction θ,φ in degrees from the model's centre (same convention as --light).
    #[arg(long, value_name = "θ,φ", default_value = "70,0", value_parser = parse_angles)]
    pub view: (f32, f32),
    /// Parallel projection instead of a 30° perspective camera.
    #[arg(long)]
    pub orthographic: bool,
    /// Shading between vertices.
    #[arg(long, value_enum, default_value_t = Mode::Pixel)]
    pub mode: Mode,
}

/// What lights the model besides (or instead of) the directional light.
#[derive(clap::Args, Clone, Debug)]
pub struct LightingArgs {
    /// Light from every direction, integrated over the sample's measured light directions:
    /// `uniform` (a white sky of radiance 1), `sky` (a clear sky, with the sun along
    /// --light), or an equirectangular .exr/.hdr map (+Y up, top row the zenith, column 0
    /// towards +Z). A map or `uniform` replaces the directional light; `sky` keeps it.
    #[arg(long, value_name = "uniform|sky|FILE")]
    pub env: Option<String>,
    /// Add a uniform sky of radiance F, so that nothing is black: 1 lights a plane facing up
    /// as much as the directional light does at normal incidence.
    #[arg(long, value_name = "F", default_value_t = 0.0, value_parser = parse_ambient, allow_negative_numbers = true)]
    pub ambient: f32,
}

impl LightingArgs {
    /// The environment map file, if `--env` names one (an input).
    pub fn env_file(&self) -> Option<&std::path::Path> {
        match self.env.as_deref() {
            None | Some("uniform" | "sky" | "sky+sun") => None,
            Some(file) => Some(std::path::Path::new(file)),
        }
    }

    /// The directional light's strength (0 or 1) and the environment, if any.
    pub fn lighting(&self) -> Result<(f32, Option<Environment>)> {
        let (sun, env) = match self.env.as_deref() {
            None => (1.0, None),
            Some("uniform") => (0.0, Some(Environment::uniform(Vec3::ONE))),
            Some("sky" | "sky+sun") => (1.0, Some(Environment::sky())),
            Some(file) => (0.0, Some(Environment::open(std::path::Path::new(file))?)),
        };
        let env = match (env, self.ambient) {
            (env, a) if a <= 0.0 => env,
            (Some(e), a) => Some(e.with_uniform(Vec3::splat(a))),
            (None, a) => Some(Environment::uniform(Vec3::splat(a))),
        };
        Ok((sun, env))
    }
}

/// A radiance: finite and not negative.
fn parse_ambient(s: &str) -> Result<f32, String> {
    match s.trim().parse::<f32>() {
        Ok(v) if v.is_finite() && v >= 0.0 => Ok(v),
        _ => Err(format!("'{s}': expected a radiance of 0 or more, e.g. 0.2")),
    }
}

/// How a sequence is written (the output directory itself is each command's own flag:
/// `render` always needs one, `view` only with `--headless`).
#[derive(clap::Args, Clone, Debug)]
pub struct OutputArgs {
    /// Frame file format: exr (linear f32 RGBA) or png (8-bit sRGB).
    #[arg(long, value_enum, default_value_t = FrameFormat::Exr)]
    pub format: FrameFormat,
    /// Replace the output directory if it exists.
    #[arg(long)]
    pub force: bool,
}

impl ShotArgs {
    /// The shots the options describe.
    pub fn plan(&self) -> ShotPlan {
        let orbit = match (self.light_orbit, self.view_orbit) {
            (true, true) => Orbit::Both,
            (false, true) => Orbit::View,
            (true, false) => Orbit::Light,
            (false, false) if self.frames > 1 => Orbit::Light,
            (false, false) => Orbit::None,
        };
        ShotPlan {
            size: self.size,
            frames: self.frames,
            light: self.light,
            view: self.view,
            orbit,
            orthographic: self.orthographic,
        }
    }

    /// The surface map and the analysis directory to render it with, checked against each
    /// other unless `--force-analysis`.
    pub fn open_surface(&self) -> anyhow::Result<(Scene, PathBuf)> {
        open_surface(&self.surface, self.analysis.as_deref(), !self.force_analysis).map_err(with_force_hint)
    }

    /// Refuses an output directory that is, holds or lies inside an input: the surface map,
    /// the analysis (as given, or `resolved` from the map) or the environment map.
    pub fn check_output(
        &self,
        output: &std::path::Path,
        lighting: &LightingArgs,
        resolved: Option<&std::path::Path>,
    ) -> anyhow::Result<()> {
        let inputs: Vec<&std::path::Path> =
            [Some(self.surface.as_path()), self.analysis.as_deref(), lighting.env_file(), resolved]
                .into_iter()
                .flatten()
                .collect();
        Ok(btfsynth::fsutil::check_not_input("-o", output, &inputs)?)
    }

    /// The `--mode` value as typed.
    pub fn mode_name(&self) -> &'static str {
        match self.mode {
            Mode::Pixel => "pixel",
            Mode::Vertex => "vertex",
        }
    }
}

/// `WxH`, both positive (at most 16384).
pub fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let bad = || format!("'{s}': expected WxH with positive integers up to 16384, e.g. 1024x768");
    let (w, h) = s.split_once(['x', 'X']).ok_or_else(bad)?;
    match (w.trim().parse::<u32>(), h.trim().parse::<u32>()) {
        (Ok(w), Ok(h)) if (1..=16384).contains(&w) && (1..=16384).contains(&h) => Ok((w, h)),
        _ => Err(bad()),
    }
}

/// `θ,φ` in degrees, θ in [0, 180] and φ in [-360, 360] (as [`btfsynth::btf::Direction`] takes it).
pub fn parse_angles(s: &str) -> Result<(f32, f32), String> {
    let bad =
        || format!("'{s}': expected θ,φ in degrees, θ from 0 to 180 and φ from -360 to 360, e.g. 45,30");
    let (t, p) = s.split_once(',').ok_or_else(bad)?;
    match (t.trim().parse::<f32>(), p.trim().parse::<f32>()) {
        (Ok(t), Ok(p)) if (0.0..=180.0).contains(&t) && (-360.0..=360.0).contains(&p) => Ok((t, p)),
        _ => Err(bad()),
    }
}
