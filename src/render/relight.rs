//! The sample itself under any view and light, rectified: the same W×H frame as the stack's
//! images (pixel (x, y) always shows the same point of the reference plane, Bonn
//! convention), through the same shading core as the renderers, so an interpolated or
//! extrapolated pair can be compared with a measurement pixel for pixel.

use super::ambient::{lit_texels, AmbientLight, TexelRect};
use super::material::Material;
use super::output::Frame;
use glam::Vec3;

/// The sample's frame in the world, for environments: lying flat and facing up (+Y), its
/// tangent s along +X and t = n × s along −Z (as [`super::Scene::sample_quad`] lies).
pub const SAMPLE_FRAME: [Vec3; 3] = [Vec3::X, Vec3::NEG_Z, Vec3::Y];

/// The sample seen from `view` (a unit vector in its (s, t, n) frame) under a directional
/// light towards `light` of strength `sun` (if any) plus `environment` (if any): one
/// linear RGBA pixel per texel, alpha 1.
pub fn relight(
    material: &Material,
    view: Vec3,
    light: Option<(Vec3, f32)>,
    environment: Option<&AmbientLight>,
) -> Frame {
    let (w, h) = (material.width(), material.height());
    let rect = TexelRect { x: 0, y: 0, width: w as u32, height: h as u32 };
    let views = material.view_weights(view);
    let mut colours = match environment {
        Some(env) => lit_texels(material, &views, &env.cell_weights(material, SAMPLE_FRAME, |_| true), rect),
        None => vec![Vec3::ZERO; w * h],
    };
    if let Some((direction, strength)) = light {
        let blend = material.blend(view, direction);
        for (k, c) in colours.iter_mut().enumerate() {
            *c += strength * material.shade(&blend, (k % w) as f32, (k / w) as f32);
        }
    }
    let mut frame = Frame::new(w, h);
    for (p, c) in frame.rgba.chunks_exact_mut(4).zip(colours) {
        p.copy_from_slice(&[c.x, c.y, c.z, 1.0]);
    }
    frame
}
