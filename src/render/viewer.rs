//! The interactive viewer: a winit window drawing the GPU renderer's passes
//! ([`super::gpu::passes::Passes`]) every frame, with an orbit camera and a light that
//! circles the model on its own.

use super::camera::{world_direction, Camera, Projection};
use super::gpu::context::Gpu;
use super::gpu::passes::{self, FrameSettings, Passes};
use super::gpu::{display_blends, Display};
use super::{Material, Mode, Scene, Shot, ShotPlan};
use crate::{Error, Result};
use glam::Vec3;
use std::sync::Arc;
use std::time::Instant;
use winit::application::ApplicationHandler;
use winit::event::{ElementState, KeyEvent, MouseButton, MouseScrollDelta, WindowEvent};
use winit::event_loop::{ActiveEventLoop, EventLoop};
use winit::keyboard::{KeyCode, PhysicalKey};
use winit::window::{Window, WindowId};

/// The keys, printed to stderr when the window opens.
pub const HELP: &str = "btfsynth view: left-drag rotates, scroll zooms; Space pauses the light, Up/Down \
raise/lower it; B: BTF / flat first image, M: vertex / pixel mode, T: texton false colour, Esc quits";

/// Degrees the light turns per second while not paused.
const LIGHT_SPEED: f32 = 40.0;

/// Opens a window of `plan.size` showing `scene` from `plan.view` under `plan.light`, and
/// runs until it is closed. Fails with one line if there is no display.
pub fn run(scene: Scene, material: Material, plan: &ShotPlan, mode: Mode) -> Result<()> {
    let no_window = |e: &dyn std::fmt::Display| {
        // winit's OS errors start with the source location of winit itself: drop it.
        let text = e.to_string();
        let reason =
            text.strip_prefix("os error at ").and_then(|t| t.split_once(": ")).map_or(&*text, |(_, r)| r);
        Error::invalid(format!("cannot open a window ({reason}); render offscreen with --headless -o DIR"))
    };
    let event_loop = EventLoop::new().map_err(|e| no_window(&e))?;
    let mut app = App {
        setup: Some((scene, material)),
        plan: *plan,
        state: None,
        error: None,
        controls: Controls::new(plan, mode),
    };
    eprintln!("{HELP}");
    event_loop.run_app(&mut app).map_err(|e| no_window(&e))?;
    app.error.map_or(Ok(()), Err)
}

/// What the user steers.
struct Controls {
    /// Camera direction (θ, φ) in degrees and distance factor (1 frames the model).
    view: (f32, f32),
    zoom: f32,
    light: (f32, f32),
    paused: bool,
    mode: Mode,
    display: Display,
    dragging: bool,
    cursor: Option<(f64, f64)>,
    last: Instant,
}

impl Controls {
    fn new(plan: &ShotPlan, mode: Mode) -> Controls {
        Controls {
            view: plan.view,
            zoom: 1.0,
            light: plan.light,
            paused: false,
            mode,
            display: Display::Btf,
            dragging: false,
            cursor: None,
            last: Instant::now(),
        }
    }

    fn key(&mut self, code: KeyCode) {
        match code {
            KeyCode::Space => self.paused = !self.paused,
            KeyCode::ArrowUp => self.light.0 = (self.light.0 - 5.0).max(0.0),
            KeyCode::ArrowDown => self.light.0 = (self.light.0 + 5.0).min(180.0),
            KeyCode::KeyB => self.display = toggle(self.display, Display::FirstImage),
            KeyCode::KeyT => self.display = toggle(self.display, Display::TextonFalseColour),
            KeyCode::KeyM => self.mode = if self.mode == Mode::Pixel { Mode::Vertex } else { Mode::Pixel },
            _ => {}
        }
    }

    fn moved(&mut self, (x, y): (f64, f64)) {
        if let (true, Some((x0, y0))) = (self.dragging, self.cursor) {
            self.view.1 -= (x - x0) as f32 * 0.3;
            self.view.0 = (self.view.0 - (y - y0) as f32 * 0.3).clamp(1.0, 179.0);
        }
        self.cursor = Some((x, y));
    }

    /// Advances the light by the time since the last frame.
    fn tick(&mut self) {
        let now = Instant::now();
        if !self.paused {
            self.light.1 += LIGHT_SPEED * (now - self.last).as_secs_f32();
        }
        self.last = now;
    }

    fn shot(&self, plan: &ShotPlan, bounds: (Vec3, Vec3), size: (u32, u32)) -> Shot {
        let shot = ShotPlan { size, view: self.view, light: self.light, frames: 1, ..*plan }.shots(bounds)[0];
        Shot {
            camera: zoomed(shot.camera, self.zoom, bounds),
            light: world_direction(self.light.0, self.light.1),
        }
    }
}

fn toggle(current: Display, other: Display) -> Display {
    if current == other {
        Display::Btf
    } else {
        other
    }
}

/// The camera moved `zoom` times its distance from the target (orthographic: image scaled).
fn zoomed(mut camera: Camera, zoom: f32, (lo, hi): (Vec3, Vec3)) -> Camera {
    let radius = 0.5 * (hi - lo).length();
    let distance = (camera.eye - camera.target).length() * zoom;
    camera.eye = camera.target + (camera.eye - camera.target).normalize() * distance;
    if let Projection::Orthographic { half_height } = &mut camera.projection {
        *half_height *= zoom;
    }
    camera.near = (distance - radius * 1.5).max(distance * 1e-3);
    camera.far = distance + radius * 1.5;
    camera
}

/// The window and what draws into it.
struct State {
    window: Arc<Window>,
    surface: wgpu::Surface<'static>,
    config: wgpu::SurfaceConfiguration,
    depth: wgpu::TextureView,
    gpu: Gpu,
    passes: Passes,
    scene: Scene,
    material: Material,
}

struct App {
    setup: Option<(Scene, Material)>,
    plan: ShotPlan,
    state: Option<State>,
    error: Option<Error>,
    controls: Controls,
}

impl App {
    fn open(&mut self, event_loop: &ActiveEventLoop) -> Result<State> {
        let (scene, material) = self.setup.take().ok_or_else(|| Error::invalid("viewer resumed twice"))?;
        let (w, h) = self.plan.size;
        let attributes = Window::default_attributes()
            .with_title("btfsynth view")
            .with_inner_size(winit::dpi::PhysicalSize::new(w, h));
        let window = Arc::new(
            event_loop
                .create_window(attributes)
                .map_err(|e| Error::invalid(format!("cannot open a window ({e}); use --headless -o DIR")))?,
        );
        let descriptor = wgpu::InstanceDescriptor::new_with_display_handle_from_env(Box::new(
            event_loop.owned_display_handle(),
        ));
        let instance = wgpu::Instance::new(descriptor);
        let surface = instance.create_surface(window.clone()).map_err(|e| {
            Error::invalid(format!("cannot draw into the window: {e}; use --headless -o DIR"))
        })?;
        let gpu = Gpu::new(&instance, Some(&surface))?;
        let size = window.inner_size();
        let mut config = surface
            .get_default_config(&gpu.adapter, size.width.max(1), size.height.max(1))
            .ok_or_else(|| Error::invalid(format!("{} cannot draw into this window", gpu.name())))?;
        // The shader writes linear colour: an sRGB surface encodes it.
        config.format = config.format.add_srgb_suffix();
        surface.configure(&gpu.device, &config);
        let passes = Passes::new(&gpu.device, &gpu.queue, &scene, &material, config.format)?;
        let depth = passes::depth_texture(&gpu.device, (config.width, config.height), false);
        eprintln!("drawing on {}", gpu.name());
        Ok(State { window, surface, config, depth, gpu, passes, scene, material })
    }

    fn fail(&mut self, event_loop: &ActiveEventLoop, e: Error) {
        self.error = Some(e);
        event_loop.exit();
    }
}

impl State {
    fn resize(&mut self, width: u32, height: u32) {
        if width == 0 || height == 0 {
            return;
        }
        self.config.width = width;
        self.config.height = height;
        self.surface.configure(&self.gpu.device, &self.config);
        self.depth = passes::depth_texture(&self.gpu.device, (width, height), false);
    }

    fn draw(&mut self, controls: &Controls, plan: &ShotPlan) {
        let frame = match self.surface.get_current_texture() {
            wgpu::CurrentSurfaceTexture::Success(t) | wgpu::CurrentSurfaceTexture::Suboptimal(t) => t,
            wgpu::CurrentSurfaceTexture::Outdated | wgpu::CurrentSurfaceTexture::Lost => {
                self.surface.configure(&self.gpu.device, &self.config);
                return;
            }
            _ => return,
        };
        let shot = controls.shot(plan, self.scene.mesh.bounds(), (self.config.width, self.config.height));
        let blends = display_blends(&self.scene, &self.material, &shot, controls.display);
        let false_colour = controls.display == Display::TextonFalseColour;
        let settings = FrameSettings { mode: controls.mode, false_colour, shadows: true };
        self.passes.prepare(&self.gpu.queue, &shot, &blends, settings);
        let mut encoder = self.gpu.device.create_command_encoder(&Default::default());
        let view = frame.texture.create_view(&Default::default());
        let background = wgpu::Color { r: 0.02, g: 0.02, b: 0.02, a: 1.0 };
        self.passes.encode(&mut encoder, &view, &self.depth, background);
        self.gpu.queue.submit([encoder.finish()]);
        self.window.pre_present_notify();
        self.gpu.queue.present(frame);
    }
}

impl ApplicationHandler for App {
    fn resumed(&mut self, event_loop: &ActiveEventLoop) {
        if self.state.is_some() {
            return;
        }
        match self.open(event_loop) {
            Ok(state) => self.state = Some(state),
            Err(e) => self.fail(event_loop, e),
        }
    }

    fn window_event(&mut self, event_loop: &ActiveEventLoop, _id: WindowId, event: WindowEvent) {
        let Some(state) = self.state.as_mut() else { return };
        let c = &mut self.controls;
        match event {
            WindowEvent::CloseRequested => event_loop.exit(),
            WindowEvent::Resized(size) => state.resize(size.width, size.height),
            WindowEvent::KeyboardInput {
                event: KeyEvent { physical_key: PhysicalKey::Code(code), state: ElementState::Pressed, .. },
                ..
            } => match code {
                KeyCode::Escape => event_loop.exit(),
                code => c.key(code),
            },
            WindowEvent::MouseInput { button: MouseButton::Left, state: pressed, .. } => {
                c.dragging = pressed == ElementState::Pressed;
            }
            WindowEvent::CursorMoved { position, .. } => c.moved((position.x, position.y)),
            WindowEvent::MouseWheel { delta, .. } => {
                let lines = match delta {
                    MouseScrollDelta::LineDelta(_, y) => y,
                    MouseScrollDelta::PixelDelta(p) => p.y as f32 / 40.0,
                };
                c.zoom = (c.zoom * 0.9f32.powf(lines)).clamp(0.05, 20.0);
            }
            WindowEvent::RedrawRequested => {
                c.tick();
                state.draw(c, &self.plan);
            }
            _ => {}
        }
    }

    fn about_to_wait(&mut self, _event_loop: &ActiveEventLoop) {
        if let Some(state) = &self.state {
            state.window.request_redraw();
        }
    }
}
