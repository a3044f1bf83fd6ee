//! Cameras, lights and the sequence of shots a render or the headless viewer takes.
//!
//! World directions are given as (θ, φ) in degrees with +Y up: θ is the angle from +Y, φ
//! the azimuth about Y from +Z towards +X. So a view of `90,0` looks at the model from +Z,
//! level with its centre, and a light of `0,0` lights it from straight above.

use glam::{Mat4, Vec3};

/// How the camera projects.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Projection {
    /// A pinhole with this vertical field of view, in degrees.
    Perspective {
        /// Vertical field of view in degrees (the orbit camera's is [`FOV_Y_DEG`]).
        fov_y_deg: f32,
    },
    /// Parallel rays; the image is `2 × half_height` model units tall.
    Orthographic {
        /// Half the image's height in model units; the width follows the aspect ratio.
        half_height: f32,
    },
}

/// A camera: where it is, what it looks at, and the image it makes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    /// Position of the camera in world (model) units.
    pub eye: Vec3,
    /// The point the camera looks at, in world units.
    pub target: Vec3,
    /// Roughly up in the image (made orthogonal to the view).
    pub up: Vec3,
    /// Perspective or orthographic, with its field of view or height.
    pub projection: Projection,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Depth range the scene occupies (for the GPU's depth buffer).
    pub near: f32,
    /// Far end of that depth range, in world units from the eye.
    pub far: f32,
}

/// One frame to render: a camera and a directional light (unit vector towards the light).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Shot {
    /// The camera that takes the frame.
    pub camera: Camera,
    /// Unit world vector towards the directional light.
    pub light: Vec3,
}

/// The unit world vector of (θ, φ) degrees (see the module documentation).
pub fn world_direction(theta_deg: f32, phi_deg: f32) -> Vec3 {
    let (t, p) = (theta_deg.to_radians(), phi_deg.to_radians());
    Vec3::new(t.sin() * p.sin(), t.cos(), t.sin() * p.cos())
}

/// Default vertical field of view of the orbit camera, in degrees.
pub const FOV_Y_DEG: f32 = 30.0;

impl Camera {
    /// A camera on the sphere around a bounding ball (`centre`, `radius`), in world direction
    /// `towards_eye` from the centre, framing the whole ball.
    pub fn framing(
        centre: Vec3,
        radius: f32,
        towards_eye: Vec3,
        orthographic: bool,
        size: (u32, u32),
    ) -> Camera {
        let aspect = size.0 as f32 / size.1 as f32;
        let radius = radius.max(1e-6) * 1.05;
        let half = (FOV_Y_DEG * 0.5).to_radians();
        // The ball must fit the narrower of the two angles.
        let fit = if aspect < 1.0 { (half.tan() * aspect).atan() } else { half };
        let distance = radius / fit.sin();
        let projection = if orthographic {
            Projection::Orthographic { half_height: radius / aspect.min(1.0) }
        } else {
            Projection::Perspective { fov_y_deg: FOV_Y_DEG }
        };
        let up = if towards_eye.normalize().y.abs() > 0.999 { Vec3::NEG_Z } else { Vec3::Y };
        Camera {
            eye: centre + towards_eye.normalize() * distance,
            target: centre,
            up,
            projection,
            width: size.0,
            height: size.1,
            near: (distance - radius * 1.5).max(distance * 1e-3),
            far: distance + radius * 1.5,
        }
    }

    /// Right, up and forward unit vectors.
    pub fn basis(&self) -> (Vec3, Vec3, Vec3) {
        let forward = (self.target - self.eye).normalize();
        let right = forward.cross(self.up).normalize();
        (right, right.cross(forward), forward)
    }

    /// The ray through image point (x, y) in pixels (pixel (i, j)'s centre is at
    /// (i + 0.5, j + 0.5); rows run down): origin and unit direction.
    pub fn ray(&self, x: f32, y: f32) -> (Vec3, Vec3) {
        let (right, up, forward) = self.basis();
        let ndc_x = 2.0 * x / self.width as f32 - 1.0;
        let ndc_y = 1.0 - 2.0 * y / self.height as f32;
        let aspect = self.width as f32 / self.height as f32;
        match self.projection {
            Projection::Perspective { fov_y_deg } => {
                let t = (fov_y_deg * 0.5).to_radians().tan();
                let d = forward + right * (ndc_x * t * aspect) + up * (ndc_y * t);
                (self.eye, d.normalize())
            }
            Projection::Orthographic { half_height } => {
                let o = self.eye + right * (ndc_x * half_height * aspect) + up * (ndc_y * half_height);
                (o, forward)
            }
        }
    }

    /// Unit vector from `p` towards the viewer.
    pub fn towards_eye(&self, p: Vec3) -> Vec3 {
        match self.projection {
            Projection::Perspective { .. } => (self.eye - p).normalize_or(Vec3::Z),
            Projection::Orthographic { .. } => (self.eye - self.target).normalize(),
        }
    }

    /// World to clip space as wgpu expects it (depth 0–1, y up), matching [`Camera::ray`].
    pub fn view_proj(&self) -> Mat4 {
        let (_, up, forward) = self.basis();
        let view = glam::camera::rh::view::look_to_mat4(self.eye, forward, up);
        let aspect = self.width as f32 / self.height as f32;
        let proj = match self.projection {
            Projection::Perspective { fov_y_deg } => glam::camera::rh::proj::directx::perspective(
                fov_y_deg.to_radians(),
                aspect,
                self.near,
                self.far,
            ),
            Projection::Orthographic { half_height } => {
                let (w, h) = (half_height * aspect, half_height);
                glam::camera::rh::proj::directx::orthographic(-w, w, -h, h, self.near, self.far)
            }
        };
        proj * view
    }
}

/// What moves across a sequence.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Orbit {
    /// The light circles the model at its elevation (φ advances 360°/frames per frame).
    Light,
    /// The camera circles the model at its elevation.
    View,
    /// Both circle.
    Both,
    /// Nothing moves: every frame is the same shot.
    None,
}

/// A sequence of shots around a model.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShotPlan {
    /// Image width and height in pixels (default 512²).
    pub size: (u32, u32),
    /// Number of shots (default 1); an orbit turns 360°/frames per frame.
    pub frames: usize,
    /// Light direction (θ, φ) in degrees at frame 0.
    pub light: (f32, f32),
    /// Camera direction (θ, φ) in degrees at frame 0.
    pub view: (f32, f32),
    /// What circles the model across the frames (default none).
    pub orbit: Orbit,
    /// Parallel projection instead of perspective (default false).
    pub orthographic: bool,
}

impl Default for ShotPlan {
    /// 512², one frame, light from (45°, 45°), camera from (70°, 0°), perspective.
    fn default() -> Self {
        ShotPlan {
            size: (512, 512),
            frames: 1,
            light: (45.0, 45.0),
            view: (70.0, 0.0),
            orbit: Orbit::None,
            orthographic: false,
        }
    }
}

impl ShotPlan {
    /// The shots around a model bounded by `bounds` (min, max).
    pub fn shots(&self, bounds: (Vec3, Vec3)) -> Vec<Shot> {
        let centre = 0.5 * (bounds.0 + bounds.1);
        let radius = 0.5 * (bounds.1 - bounds.0).length();
        (0..self.frames)
            .map(|i| {
                let turn = 360.0 * i as f32 / self.frames as f32;
                let (light_turn, view_turn) = match self.orbit {
                    Orbit::Light => (turn, 0.0),
                    Orbit::View => (0.0, turn),
                    Orbit::Both => (turn, turn),
                    Orbit::None => (0.0, 0.0),
                };
                let towards_eye = world_direction(self.view.0, self.view.1 + view_turn);
                Shot {
                    camera: Camera::framing(centre, radius, towards_eye, self.orthographic, self.size),
                    light: world_direction(self.light.0, self.light.1 + light_turn),
                }
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rays_and_view_projection_agree() {
        for orthographic in [false, true] {
            let cam = Camera::framing(
                Vec3::new(1.0, 2.0, 3.0),
                2.0,
                world_direction(60.0, 30.0),
                orthographic,
                (40, 20),
            );
            let vp = cam.view_proj();
            for (x, y) in [(0.5, 0.5), (20.0, 10.0), (39.5, 3.25)] {
                let (o, d) = cam.ray(x, y);
                let p = o + d * (cam.near + cam.far) * 0.5;
                let clip = vp * p.extend(1.0);
                let (nx, ny) = (clip.x / clip.w, clip.y / clip.w);
                let px = ((nx + 1.0) * 0.5 * 40.0, (1.0 - ny) * 0.5 * 20.0);
                assert!((px.0 - x).abs() < 1e-3 && (px.1 - y).abs() < 1e-3, "{px:?} vs ({x}, {y})");
                assert!((0.0..=1.0).contains(&(clip.z / clip.w)));
            }
        }
    }

    #[test]
    fn world_directions_follow_the_documented_convention() {
        assert!((world_direction(0.0, 123.0) - Vec3::Y).length() < 1e-6);
        assert!((world_direction(90.0, 0.0) - Vec3::Z).length() < 1e-6);
        assert!((world_direction(90.0, 90.0) - Vec3::X).length() < 1e-6);
    }
}
