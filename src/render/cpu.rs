//! The CPU renderer: primary and shadow rays through an obvhs BVH of the mesh, then the
//! shared shading core per pixel ([`Mode::Pixel`]) or per vertex ([`Mode::Vertex`]).

use super::ambient::{Ambient, AmbientCache};
use super::camera::Shot;
use super::environment::Environment;
use super::material::{Blend16, Material};
use super::output::Frame;
use super::scene::{Mode, Scene};
pub use super::tracer::{Hit, Tracer};
use glam::Vec3;
use rayon::prelude::*;

/// What the CPU renderer does besides shading.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RenderOptions {
    /// How points between vertices are shaded (per vertex or per pixel).
    pub mode: Mode,
    /// Trace shadow rays (per sample in pixel mode, per vertex in vertex mode), for the
    /// directional light and for the environment's light cells.
    pub shadows: bool,
    /// Primary rays per pixel, a square number: a jittered √spp × √spp grid.
    pub spp: u32,
    /// Strength of the directional light: 1 reproduces the sample's images, 0 leaves only
    /// the environment.
    pub sun: f32,
}

impl Default for RenderOptions {
    /// Pixel mode with shadows, 4 samples per pixel, the directional light at strength 1.
    fn default() -> Self {
        RenderOptions { mode: Mode::Pixel, shadows: true, spp: 4, sun: 1.0 }
    }
}

/// What a point's colour is made of, fixed for one shot.
struct Shading<'a> {
    scene: &'a Scene,
    material: &'a Material,
    tracer: &'a Tracer,
    shot: &'a Shot,
    options: RenderOptions,
    /// Per vertex, the directional light's blend (empty without a directional light).
    blends: Vec<Blend16>,
    /// Vertex mode: the colour of every vertex.
    vertex_colours: Option<Vec<Vec3>>,
    ambient: Option<&'a Ambient>,
}

impl Shading<'_> {
    /// The colour seen along a primary ray, or `None` if it misses the model.
    fn ray(&self, origin: Vec3, direction: Vec3) -> Option<Vec3> {
        let hit = self.tracer.closest(origin, direction)?;
        if hit.normal.dot(direction) >= 0.0 {
            return Some(Vec3::ZERO);
        }
        let corners = self.scene.mesh.triangles()[hit.triangle];
        if let Some(colours) = &self.vertex_colours {
            let c = corners.map(|v| colours[v as usize]);
            return Some(c[0] * hit.bary.x + c[1] * hit.bary.y + c[2] * hit.bary.z);
        }
        let mut colour = Vec3::ZERO;
        let light = self.shot.light;
        if !self.blends.is_empty()
            && hit.normal.dot(light) > 0.0
            && (!self.options.shadows || self.tracer.lit(hit.position, hit.normal, light))
        {
            let point = (hit.triangle, hit.bary, hit.position);
            colour +=
                self.options.sun * self.scene.shade_point(self.material, &self.blends, Mode::Pixel, point);
        }
        if let Some(ambient) = self.ambient {
            // Each vertex's environment patch covers its own copy: the chosen corners' only.
            let (uv, weights) = self.scene.point_uv(self.material, corners, hit.bary, hit.position);
            for (k, &v) in corners.iter().enumerate() {
                colour += weights[k] * ambient.at(v as usize, uv);
            }
        }
        Some(colour)
    }
}

/// Renders one shot: `options.spp` jittered rays per pixel, each shaded by the directional
/// light (where it faces the light and, with shadows, nothing blocks it) plus the
/// environment's share `ambient` (computed for this shot's camera, see
/// [`Ambient::compute`]). Points facing away from the camera are black.
pub fn render(
    scene: &Scene,
    material: &Material,
    tracer: &Tracer,
    shot: &Shot,
    options: RenderOptions,
    ambient: Option<&Ambient>,
) -> Frame {
    let blends = if options.sun > 0.0 { scene.vertex_blends(material, shot) } else { Vec::new() };
    let vertex_colours = (options.mode == Mode::Vertex).then(|| {
        let lit = (options.shadows && !blends.is_empty()).then(|| vertex_lit(scene, tracer, shot.light));
        let mut colours = if blends.is_empty() {
            vec![Vec3::ZERO; scene.mesh.vertex_count()]
        } else {
            scene.vertex_colours(material, &blends, lit.as_deref())
        };
        colours.iter_mut().enumerate().for_each(|(v, c)| {
            *c *= options.sun;
            if let Some(a) = ambient {
                *c += a.at(v, scene.uv[v]);
            }
        });
        colours
    });
    let shading = Shading { scene, material, tracer, shot, options, blends, vertex_colours, ambient };
    let (w, h) = (shot.camera.width as usize, shot.camera.height as usize);
    let strata = stratification(options.spp);
    let mut frame = Frame::new(w, h);
    frame.rgba.par_chunks_mut(w * 4).enumerate().for_each(|(y, row)| {
        for x in 0..w {
            let (mut sum, mut covered) = (Vec3::ZERO, 0u32);
            for k in 0..strata * strata {
                let (jx, jy) = jitter((x, y), k, strata);
                let (origin, direction) = shot.camera.ray(x as f32 + jx, y as f32 + jy);
                if let Some(c) = shading.ray(origin, direction) {
                    sum += c;
                    covered += 1;
                }
            }
            let n = (strata * strata) as f32;
            // Premultiplied by coverage: an edge pixel is the mean over all its samples.
            let colour = sum / n;
            row[x * 4..x * 4 + 4].copy_from_slice(&[colour.x, colour.y, colour.z, covered as f32 / n]);
        }
    });
    frame
}

/// The side of the sample grid for `spp` samples per pixel (spp is a square; anything else
/// is rounded down to one, and 0 counts as 1).
fn stratification(spp: u32) -> usize {
    ((spp.max(1) as f64).sqrt().floor() as usize).max(1)
}

/// The offset within pixel `(x, y)` of its sample `k` on a `strata × strata` grid, jittered
/// within its stratum (one sample per pixel goes through the centre).
fn jitter((x, y): (usize, usize), k: usize, strata: usize) -> (f32, f32) {
    if strata == 1 {
        return (0.5, 0.5);
    }
    let (i, j) = ((k % strata) as f32, (k / strata) as f32);
    let a = (y * 65_536 + x) as i64;
    let (u, v) = (crate::seeded::unit(17, a, k as i64, 0), crate::seeded::unit(17, a, k as i64, 1));
    ((i + u) / strata as f32, (j + v) / strata as f32)
}

/// True if `spp` samples per pixel can be stratified (a square number from 1 to 1024).
pub fn valid_spp(spp: u32) -> bool {
    (1..=1024).contains(&spp) && stratification(spp).pow(2) == spp as usize
}

/// Per vertex, whether the light reaches it (Tong §6 ignores occluded vertices).
pub fn vertex_lit(scene: &Scene, tracer: &Tracer, light: Vec3) -> Vec<bool> {
    let (positions, normals) = (scene.mesh.positions(), scene.normals());
    (0..positions.len())
        .into_par_iter()
        .with_min_len(1024)
        .map(|v| normals[v].dot(light) > 0.0 && tracer.lit(positions[v], normals[v], light))
        .collect()
}

/// One model to render in a sequence: its scene, tracer and (with an environment) what
/// lights it from every direction.
struct Subject<'a> {
    scene: &'a Scene,
    tracer: Tracer,
    shots: Vec<Shot>,
    ambient: Option<AmbientCache>,
}

impl<'a> Subject<'a> {
    fn new(
        scene: &'a Scene,
        material: &Material,
        plan: &super::ShotPlan,
        environment: Option<&Environment>,
        shadows: bool,
    ) -> Subject<'a> {
        let tracer = Tracer::new(&scene.mesh);
        let ambient = environment.map(|e| AmbientCache::new(scene, material, e.clone(), shadows));
        let shots = plan.shots(scene.mesh.bounds());
        Subject { scene, tracer, shots, ambient }
    }

    fn render(&mut self, material: &Material, i: usize, options: RenderOptions) -> Frame {
        let shot = self.shots[i];
        let tracer = Some(&self.tracer);
        let ambient =
            self.ambient.as_mut().map(|a| a.for_camera((self.scene, material), &shot.camera, tracer).0);
        render(self.scene, material, &self.tracer, &shot, options, ambient)
    }
}

/// Renders every shot of `plan` into `writer` under the directional light (at
/// `options.sun`) and `environment`; with `compare`, each frame is put beside the sample on
/// a flat quad ([`Scene::sample_quad`]) seen from the same direction under the same light.
/// Returns the mean seconds per frame (rendering only).
pub fn render_sequence(
    (scene, material): (&Scene, &Material),
    plan: &super::ShotPlan,
    options: RenderOptions,
    environment: Option<&Environment>,
    compare: bool,
    writer: &mut super::SequenceWriter,
    progress: &dyn crate::progress::Progress,
) -> crate::Result<f64> {
    let started = std::time::Instant::now();
    let mut model = Subject::new(scene, material, plan, environment, options.shadows);
    let quad = if compare { Some(Scene::sample_quad(material)?) } else { None };
    let mut quad = quad.as_ref().map(|q| Subject::new(q, material, plan, environment, false));
    let mut seconds = started.elapsed().as_secs_f64();
    progress.start("rendering", model.shots.len() as u64);
    for i in 0..model.shots.len() {
        let started = std::time::Instant::now();
        let mut frame = model.render(material, i, options);
        if let Some(q) = &mut quad {
            frame = frame.beside(&q.render(material, i, RenderOptions { mode: Mode::Pixel, ..options }));
        }
        seconds += started.elapsed().as_secs_f64();
        writer.push(&frame)?;
        progress.advance(1);
    }
    progress.finish();
    Ok(seconds / model.shots.len().max(1) as f64)
}
