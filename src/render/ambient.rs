//! Image-based lighting with the BTF itself: the environment's share of a surface point's
//! colour, integrated over the measured light directions.
//!
//! The light cells are the Voronoi cells of the sample's light directions on the local
//! hemisphere (each direction owns the part of the hemisphere nearer to it than to any
//! other; the outermost ring's cells reach down to the horizon). Under an environment of
//! radiance L, image *i* of a view receives the weight (1/π) ∫_cell_i L(ω) dω (units in
//! [`super::environment`]), with the part of a cell beyond the dome's largest θ attenuated
//! by cos θ / cos θ_max as a directional light there would be. So the result is a sum over
//! measured images, each lit by exactly the light its cell receives: exact for the measured
//! data, not a constant ambient term. A one-light sample (a texture) is Lambertian instead:
//! its one weight is the irradiance over π, (1/π) ∫ L(ω) cos θ dω.
//!
//! Per vertex, the environment's samples are turned into the vertex's (s, t, n) frame and
//! dropped into the cell they fall in; the uniform part has the same weights everywhere
//! (computed once). With shadows, a cell whose measured direction is blocked by the model
//! (one ray per cell and vertex, [`CellVisibility`]) receives nothing.
//!
//! The weights do not depend on the camera, but the colour does, through the vertex's 4
//! nearest views. [`Ambient`] combines both into a small patch of sample texels around each
//! vertex's sample coordinate, covering every coordinate its triangles predict: a bilinear
//! lookup in the patch equals the sum of the bilinear lookups in all the images it blends
//! (lookups are linear), so both renderers shade per pixel from the patch at the cost of
//! one image.

use super::blend::Nearest4;
use super::camera::Camera;
use super::environment::Environment;
use super::material::Material;
use super::scene::Scene;
use super::tracer::Tracer;
use glam::{Vec2, Vec3};
use rayon::prelude::*;
use std::f32::consts::PI;

/// An environment ready to light one material: its uniform part already integrated over
/// the material's light cells.
pub struct AmbientLight {
    environment: Environment,
    /// The light cell of any local direction, from a table (no search per sample).
    cells: CellTable,
    /// Per light cell, (1/π) ∫_cell (cosine ratio) dω: a uniform sky's weight per unit
    /// radiance. For a one-light sample, 1 (the cosine-weighted hemisphere over π).
    uniform_weights: Vec<f32>,
}

/// Points of the quadrature of the hemisphere that measures the cells (about 0.2° apart).
const CELL_QUADRATURE_POINTS: usize = 1 << 19;

impl AmbientLight {
    /// Prepares `environment` for `material`.
    pub fn new(material: &Material, environment: Environment) -> AmbientLight {
        let lights = material.light_index();
        let uniform_weights = if lights.len() == 1 {
            vec![1.0]
        } else {
            // A Fibonacci spiral: equal-area points that, unlike a θ-φ grid, do not line up
            // with the rings of a dome (a grid biases cells whose edges follow its rows).
            let n = CELL_QUADRATURE_POINTS;
            let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
            let per_point = std::f32::consts::TAU / n as f32 / PI;
            (0..n)
                .into_par_iter()
                .fold(
                    || vec![0.0f64; lights.len()],
                    |mut weights, k| {
                        let z = 1.0 - (k as f32 + 0.5) / n as f32;
                        // in f64: k × golden reaches 10⁶, where an f32 is 0.1 rad coarse
                        let phi = (k as f64 * golden).rem_euclid(std::f64::consts::TAU) as f32;
                        let r = (1.0 - z * z).sqrt();
                        let q = Vec3::new(r * phi.cos(), r * phi.sin(), z);
                        weights[lights.nearest(q) as usize] +=
                            (per_point * lights.beyond_cosine_ratio(q)) as f64;
                        weights
                    },
                )
                .reduce(|| vec![0.0; lights.len()], |a, b| a.iter().zip(&b).map(|(x, y)| x + y).collect())
                .into_iter()
                .map(|w| w as f32)
                .collect()
        };
        AmbientLight { environment, cells: CellTable::new(lights), uniform_weights }
    }

    /// The environment.
    pub fn environment(&self) -> &Environment {
        &self.environment
    }

    /// A uniform sky's weight per unit radiance for each light cell (see the module notes).
    pub fn uniform_weights(&self) -> &[f32] {
        &self.uniform_weights
    }

    /// The RGB weight of every light cell for a point whose frame is `frame` (s, t, n as
    /// world vectors); `visible(i)` false removes cell i (in shadow).
    pub fn cell_weights(
        &self,
        material: &Material,
        frame: [Vec3; 3],
        visible: impl Fn(usize) -> bool,
    ) -> Vec<Vec3> {
        let lights = material.light_index();
        let env = &self.environment;
        let mut weights: Vec<Vec3> = self.uniform_weights.iter().map(|&w| env.uniform * w).collect();
        let [s, t, n] = frame;
        for sample in &env.samples {
            let d = sample.direction;
            let z = d.dot(n);
            if z <= 0.0 {
                continue;
            }
            let local = Vec3::new(d.dot(s), d.dot(t), z);
            if lights.len() == 1 {
                weights[0] += sample.power * (local.z / PI);
            } else {
                let cell = self.cells.cell(local);
                weights[cell] += sample.power * (lights.beyond_cosine_ratio(local) / PI);
            }
        }
        for (i, w) in weights.iter_mut().enumerate() {
            if !visible(i) {
                *w = Vec3::ZERO;
            }
        }
        weights
    }
}

/// The light cell of a local direction by table: an octahedral map of the hemisphere (the
/// direction's x and y over |x| + |y| + z), 512 texels a side, each holding the nearest
/// light to its centre. Only directions within a texel (about 0.2°) of a cell's edge can be
/// given to the neighbouring cell, which moves a sample by less than its own extent.
struct CellTable {
    side: usize,
    cells: Vec<u16>,
}

impl CellTable {
    const SIDE: usize = 512;

    fn new(lights: &super::blend::DirectionIndex) -> CellTable {
        let side = Self::SIDE;
        let cells = (0..side * side)
            .into_par_iter()
            .map(|k| {
                let u = ((k % side) as f32 + 0.5) / side as f32 * 2.0 - 1.0;
                let v = ((k / side) as f32 + 0.5) / side as f32 * 2.0 - 1.0;
                let d = Vec3::new(u, v, (1.0 - u.abs() - v.abs()).max(0.0)).normalize();
                lights.nearest(d) as u16
            })
            .collect();
        CellTable { side, cells }
    }

    /// The cell of `d` (z > 0, any length).
    fn cell(&self, d: Vec3) -> usize {
        let sum = d.x.abs() + d.y.abs() + d.z;
        let last = self.side as f32 - 1.0;
        let texel = |c: f32| (((c / sum) * 0.5 + 0.5) * self.side as f32).clamp(0.0, last) as usize;
        self.cells[texel(d.y) * self.side + texel(d.x)] as usize
    }
}

/// Per vertex, which light cells' measured directions the model does not block: one bit per
/// cell, one shadow ray each, traced for a vertex the first time a camera needs it.
pub struct CellVisibility {
    words_per_vertex: usize,
    bits: Vec<u64>,
    traced: Vec<bool>,
}

impl CellVisibility {
    /// Nothing traced yet, for `vertices` vertices and `cells` light cells.
    pub fn new(vertices: usize, cells: usize) -> CellVisibility {
        let words_per_vertex = cells.div_ceil(64);
        let bits = vec![0; vertices * words_per_vertex];
        CellVisibility { words_per_vertex, bits, traced: vec![false; vertices] }
    }

    /// Traces, for every vertex in `wanted` not yet traced and every light cell, a ray along
    /// the cell's measured direction turned into the vertex's frame.
    pub fn trace(&mut self, scene: &Scene, material: &Material, tracer: &Tracer, wanted: &[bool]) {
        let lights = material.light_index().units();
        let positions = scene.mesh.positions();
        let words = self.words_per_vertex;
        let chunks = self.bits.par_chunks_mut(words).zip(self.traced.par_iter_mut());
        chunks.enumerate().with_min_len(256).for_each(|(v, (bits, traced))| {
            if *traced || !wanted[v] {
                return;
            }
            let [s, t, n] = scene.frame(v);
            for (i, l) in lights.iter().enumerate() {
                let world = (s * l.x + t * l.y + n * l.z).normalize_or(n);
                if tracer.lit(positions[v], n, world) {
                    bits[i / 64] |= 1 << (i % 64);
                }
            }
            *traced = true;
        });
    }

    /// True if light cell `cell` reaches vertex `v` (which must have been traced).
    pub fn visible(&self, v: usize, cell: usize) -> bool {
        self.bits[v * self.words_per_vertex + cell / 64] >> (cell % 64) & 1 == 1
    }
}

/// A rectangle of sample texels: its first texel and its size. Texel positions are not
/// wrapped: a patch may reach past the sample's edge, where the lookup wraps or clamps.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TexelRect {
    /// Column of the first texel (may be negative or past the sample's width).
    pub x: i32,
    /// Row of the first texel (may be negative or past the sample's height).
    pub y: i32,
    /// Width in texels.
    pub width: u32,
    /// Height in texels.
    pub height: u32,
}

/// A patch larger than this many texels a side is cut (a degenerate triangle can predict
/// coordinates far away); lookups outside a patch clamp to its edge.
const MAX_PATCH_SIDE: u32 = 1024;

impl TexelRect {
    /// The texels a bilinear lookup needs anywhere in the box from `lo` to `hi`.
    pub fn covering(lo: Vec2, hi: Vec2) -> TexelRect {
        let (x0, y0) = (lo.x.floor(), lo.y.floor());
        let side = |a: f32, b: f32| ((b.floor() - a + 2.0).max(1.0) as u32).min(MAX_PATCH_SIDE);
        TexelRect { x: x0 as i32, y: y0 as i32, width: side(x0, hi.x), height: side(y0, hi.y) }
    }

    /// Number of texels.
    pub fn area(&self) -> usize {
        self.width as usize * self.height as usize
    }
}

/// The environment-lit colour of one view blend over a rectangle of texels: Σ over the
/// views and light cells of (view weight × cell weight) × image, row-major.
pub fn lit_texels(material: &Material, views: &Nearest4, weights: &[Vec3], rect: TexelRect) -> Vec<Vec3> {
    let mut terms: Vec<(usize, Vec3)> = Vec::with_capacity(4 * weights.len());
    for a in 0..4 {
        let wv = views.weight[a];
        if wv <= 0.0 {
            continue;
        }
        for (light, w) in weights.iter().enumerate() {
            if *w != Vec3::ZERO {
                if let Some(image) = material.image_of(views.index[a], light as u32) {
                    terms.push((image as usize * 3, *w * wv));
                }
            }
        }
    }
    (0..rect.area())
        .map(|k| {
            let (dx, dy) = ((k % rect.width as usize) as i64, (k / rect.width as usize) as i64);
            let block = material.texel_block(rect.x as i64 + dx, rect.y as i64 + dy);
            terms.iter().map(|&(offset, w)| w * material.at(block + offset)).sum()
        })
        .collect()
}

/// Per vertex, the rectangle of texels covering every sample coordinate its triangles
/// predict for points inside them ([`Scene::predict_uv`] is affine in the point, so the
/// predictions at the triangles' corners bound it).
pub fn patch_rects(scene: &Scene) -> Vec<TexelRect> {
    let positions = scene.mesh.positions();
    let mut bounds: Vec<(Vec2, Vec2)> = scene.uv.iter().map(|&uv| (uv, uv)).collect();
    for tri in scene.mesh.triangles() {
        for &v in tri {
            for &c in tri {
                let q = scene.predict_uv(v as usize, positions[c as usize]);
                let b = &mut bounds[v as usize];
                *b = (b.0.min(q), b.1.max(q));
            }
        }
    }
    bounds.into_iter().map(|(lo, hi)| TexelRect::covering(lo, hi)).collect()
}

/// The environment's share of every vertex's colour for one camera: per vertex a patch of
/// environment-lit texels around its sample coordinate.
pub struct Ambient {
    rects: Vec<TexelRect>,
    /// Where each vertex's texels start in `texels`.
    offsets: Vec<u32>,
    texels: Vec<Vec3>,
}

impl Ambient {
    /// The patches of the vertices of `scene` that `wanted` marks (all if `None`; the
    /// others' texels are 0), seen by `camera` under `light`, with the cells blocked in
    /// `visibility` (if given) removed.
    pub fn compute(
        scene: &Scene,
        material: &Material,
        light: &AmbientLight,
        camera: &Camera,
        (visibility, wanted): (Option<&CellVisibility>, Option<&[bool]>),
    ) -> Ambient {
        let rects = patch_rects(scene);
        let positions = scene.mesh.positions();
        let patches: Vec<Vec<Vec3>> = (0..positions.len())
            .into_par_iter()
            .with_min_len(64)
            .map(|v| {
                if wanted.is_some_and(|w| !w[v]) {
                    return vec![Vec3::ZERO; rects[v].area()];
                }
                let frame = scene.frame(v);
                let weights =
                    light.cell_weights(material, frame, |i| visibility.is_none_or(|vis| vis.visible(v, i)));
                let views = material.view_weights(scene.to_local(v, camera.towards_eye(positions[v])));
                lit_texels(material, &views, &weights, rects[v])
            })
            .collect();
        let mut offsets = Vec::with_capacity(patches.len());
        let mut texels = Vec::with_capacity(patches.iter().map(Vec::len).sum());
        for p in patches {
            offsets.push(texels.len() as u32);
            texels.extend(p);
        }
        Ambient { rects, offsets, texels }
    }

    /// Vertex `v`'s patch.
    pub fn rect(&self, v: usize) -> TexelRect {
        self.rects[v]
    }

    /// Where vertex `v`'s texels start in [`Ambient::texels`].
    pub fn offset(&self, v: usize) -> u32 {
        self.offsets[v]
    }

    /// Every patch's texels, one after the other, each row-major.
    pub fn texels(&self) -> &[Vec3] {
        &self.texels
    }

    /// The environment's colour at sample coordinate `uv` as vertex `v` sees it: bilinear
    /// in its patch (clamped to the patch's edge, which only a cut patch reaches).
    pub fn at(&self, v: usize, uv: Vec2) -> Vec3 {
        let r = self.rects[v];
        let base = self.offsets[v] as usize;
        let (fx, fy) = ((uv.x - r.x as f32).floor(), (uv.y - r.y as f32).floor());
        let (tx, ty) = (uv.x - r.x as f32 - fx, uv.y - r.y as f32 - fy);
        let clamp = |i: f32, n: u32| (i.max(0.0) as u32).min(n - 1) as usize;
        let texel =
            |x: f32, y: f32| self.texels[base + clamp(y, r.height) * r.width as usize + clamp(x, r.width)];
        let top = texel(fx, fy).lerp(texel(fx + 1.0, fy), tx);
        let bottom = texel(fx, fy + 1.0).lerp(texel(fx + 1.0, fy + 1.0), tx);
        top.lerp(bottom, ty)
    }
}

/// The environment's shading of one scene, kept while the camera stays: what a sequence
/// or a window recomputes only when the camera moves.
///
/// With shadows (a tracer), only the vertices a camera may show are shaded: the corners of
/// triangles the camera sees ([`Scene::seen_triangle_corners`]) and of the triangles around
/// those (a margin for samples off pixel centres); hidden vertices keep black patches. Their
/// light cells' shadow rays are traced once, the first time a camera shows them.
pub struct AmbientCache {
    light: AmbientLight,
    visibility: Option<CellVisibility>,
    last: Option<(Camera, Ambient)>,
}

impl AmbientCache {
    /// `environment` on `material`, with each light cell shadowed per vertex if `shadows`.
    pub fn new(scene: &Scene, material: &Material, environment: Environment, shadows: bool) -> AmbientCache {
        let light = AmbientLight::new(material, environment);
        let visibility =
            shadows.then(|| CellVisibility::new(scene.mesh.vertex_count(), material.light_index().len()));
        AmbientCache { light, visibility, last: None }
    }

    /// The environment's shading seen by `camera`, and whether it was computed now (else it
    /// is the last camera's). `tracer` (of the scene) is needed with shadows.
    pub fn for_camera(
        &mut self,
        (scene, material): (&Scene, &Material),
        camera: &Camera,
        tracer: Option<&Tracer>,
    ) -> (&Ambient, bool) {
        let fresh = self.last.as_ref().is_none_or(|(c, _)| c != camera);
        if fresh {
            let wanted = tracer.map(|t| grow(scene, scene.seen_triangle_corners(camera, t)));
            if let (Some(visibility), Some(tracer), Some(wanted)) = (&mut self.visibility, tracer, &wanted) {
                visibility.trace(scene, material, tracer, wanted);
            }
            let visibility = self.visibility.as_ref().filter(|_| tracer.is_some());
            let ambient =
                Ambient::compute(scene, material, &self.light, camera, (visibility, wanted.as_deref()));
            self.last = Some((*camera, ambient));
        }
        let (_, ambient) = self.last.as_ref().expect("computed above");
        (ambient, fresh)
    }
}

/// `marked` and the corners of every triangle with a marked corner.
fn grow(scene: &Scene, marked: Vec<bool>) -> Vec<bool> {
    let mut out = marked.clone();
    for tri in scene.mesh.triangles() {
        if tri.iter().any(|&v| marked[v as usize]) {
            tri.iter().for_each(|&v| out[v as usize] = true);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::btf::{Direction, DirectionPair, DirectionSet};

    fn frame_z_up() -> [Vec3; 3] {
        [Vec3::X, Vec3::Y, Vec3::Z]
    }

    #[test]
    fn a_uniform_sky_weights_cells_by_their_solid_angle() {
        let pairs = DirectionSet::Ubo81.pairs();
        let material = Material::new(1, 1, vec![0.5; pairs.len() * 3], pairs).unwrap();
        let light = AmbientLight::new(&material, Environment::uniform(Vec3::ONE));
        let total: f32 = light.uniform_weights().iter().sum::<f32>() * PI;
        // The hemisphere (2π) less what the cosine ratio removes beyond 75°:
        // ∫_{75°}^{90°} (1 − cos θ / cos 75°) sin θ dθ · 2π.
        let (c, s) = (75f32.to_radians().cos(), 0.5 * (75f32.to_radians().cos().powi(2)));
        let removed = std::f32::consts::TAU * (c - s / c);
        assert!((total - (std::f32::consts::TAU - removed)).abs() < 2e-3, "{total}");
        // Each cell against an independent quadrature: a 1024 × 4096 θ-φ grid on the
        // hemisphere, one point per cell jittered uniformly in area (so that cell edges
        // lining up with grid rows bias nothing), given to its nearest direction by brute force.
        let lights = material.light_index();
        let (rows, columns) = (1024, 4096);
        let mut reference = vec![0.0f64; lights.len()];
        for y in 0..rows {
            let step = std::f64::consts::FRAC_PI_2 / rows as f64;
            let (z0, z1) = ((step * y as f64).cos(), (step * (y + 1) as f64).cos());
            let solid_angle = std::f64::consts::TAU / columns as f64 * (z0 - z1);
            for x in 0..columns {
                let (u, v) = (crate::seeded::unit(6, y, x, 0) as f64, crate::seeded::unit(6, y, x, 1) as f64);
                let z = z0 - u * (z0 - z1);
                let phi = std::f64::consts::TAU * (x as f64 + v) / columns as f64;
                let r = (1.0 - z * z).sqrt();
                let q = Vec3::new((r * phi.cos()) as f32, (r * phi.sin()) as f32, z as f32);
                let nearest = (0..lights.len())
                    .max_by(|&a, &b| q.dot(lights.units()[a]).total_cmp(&q.dot(lights.units()[b])))
                    .unwrap();
                let ratio = (z / 75f64.to_radians().cos()).min(1.0);
                reference[nearest] += solid_angle * ratio / std::f64::consts::PI;
            }
        }
        for (i, (&w, &r)) in light.uniform_weights().iter().zip(&reference).enumerate() {
            assert!((w as f64 - r).abs() < 3e-3 * r, "cell {i}: {w} vs {r}");
        }
    }

    #[test]
    fn a_light_below_the_horizon_contributes_nothing() {
        let pairs = DirectionSet::Grid(16).pairs();
        let material = Material::new(1, 1, vec![1.0; pairs.len() * 3], pairs).unwrap();
        let below = Environment {
            uniform: Vec3::ZERO,
            samples: vec![super::super::environment::EnvSample {
                direction: Vec3::new(0.3, 0.2, -0.9).normalize(),
                power: Vec3::splat(5.0),
            }],
        };
        let light = AmbientLight::new(&material, below);
        assert!(light.cell_weights(&material, frame_z_up(), |_| true).iter().all(|w| *w == Vec3::ZERO));
    }

    #[test]
    fn a_one_light_texture_is_lambertian_under_the_environment() {
        let pair = DirectionPair { light: Direction::NORMAL, view: Direction::NORMAL };
        let material = Material::new(1, 1, vec![0.5, 0.5, 0.5], vec![pair]).unwrap();
        let sample = super::super::environment::EnvSample {
            direction: Vec3::new(0.6, 0.0, 0.8),
            power: Vec3::splat(PI),
        };
        let env = Environment { uniform: Vec3::splat(0.25), samples: vec![sample] };
        let w = AmbientLight::new(&material, env).cell_weights(&material, frame_z_up(), |_| true);
        assert!((w[0] - Vec3::splat(0.25 + 0.8)).length() < 1e-6, "{}", w[0]);
    }

    #[test]
    fn a_patch_lookup_equals_the_sum_of_image_lookups() {
        let (w, h) = (5, 4);
        let pairs = DirectionSet::Grid(9).pairs();
        let pixels = (0..pairs.len() * w * h * 3).map(|i| crate::seeded::unit(2, i as i64, 0, 0)).collect();
        let mut material = Material::new(w, h, pixels, pairs).unwrap();
        material.tileable = true;
        let light = AmbientLight::new(&material, Environment::sky());
        let frame = [Vec3::X, Vec3::NEG_Z, Vec3::Y];
        let weights = light.cell_weights(&material, frame, |i| i != 3);
        let views = material.view_weights(Vec3::new(0.2, 0.3, 0.9).normalize());
        let rect = TexelRect::covering(Vec2::new(-1.3, 2.2), Vec2::new(4.6, 5.9));
        let texels = lit_texels(&material, &views, &weights, rect);
        let ambient = Ambient { rects: vec![rect], offsets: vec![0], texels };
        for uv in [Vec2::new(-1.3, 2.2), Vec2::new(0.5, 3.25), Vec2::new(4.6, 5.9), Vec2::new(2.0, 4.0)] {
            let mut expected = Vec3::ZERO;
            for a in 0..4 {
                for (i, wi) in weights.iter().enumerate() {
                    if let Some(image) = material.image_of(views.index[a], i as u32) {
                        expected += views.weight[a] * *wi * material.texel(image, uv.x, uv.y);
                    }
                }
            }
            let got = ambient.at(0, uv);
            assert!((got - expected).length() < 1e-4, "{uv}: {got} vs {expected}");
        }
    }
}
