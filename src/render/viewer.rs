//! The interactive viewer: a winit window drawing the GPU renderer's passes
//! ([`super::gpu::passes::Passes`]) every frame, with an orbit camera, a light that circles
//! the model on its own, an overlay (frame rate, light angles, mode) and a key that saves
//! the frame.

use super::camera::{world_direction, Camera, Projection};
use super::gpu::context::Gpu;
use super::gpu::overlay::Overlay;
use super::gpu::passes::FrameTargets;
use super::gpu::{readback, Display, GpuLighting, GpuSample, GpuScene};
use super::overlay::TextImage;
use super::{Mode, Scene, Shot, ShotPlan};
use crate::{Error, Result};
use glam::Vec3;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;
use winit::application::ApplicationHandler;
use winit::event::{ElementState, KeyEvent, MouseButton, MouseScrollDelta, WindowEvent};
use winit::event_loop::{ActiveEventLoop, EventLoop};
use winit::keyboard::{KeyCode, PhysicalKey};
use winit::window::{Window, WindowId};

/// The keys, printed to stderr when the window opens.
pub const HELP: &str = "btfsynth view: left-drag rotates, scroll zooms; Space pauses the light, Up/Down \
raise/lower it; B: BTF / flat first image, M: vertex / pixel mode, T: texton false colour, O: overlay \
on/off, S: save the frame as PNG, Esc quits";

/// Degrees the light turns per second while not paused.
const LIGHT_SPEED: f32 = 40.0;

/// Seconds between overlay updates (its frame rate is averaged over them).
const OVERLAY_PERIOD: f32 = 0.5;

/// What the window starts with.
#[derive(Clone, Debug)]
pub struct ViewerOptions {
    /// How points between vertices are shaded at first (the M key switches).
    pub mode: Mode,
    /// The directional light, environment and shadows the window starts with.
    pub lighting: GpuLighting,
    /// Where the S key saves frames (`view-0000.png`, `view-0001.png`, …).
    pub save_dir: PathBuf,
}

/// Opens a window of `plan.size` showing `scene` with `sample` from `plan.view` under
/// `plan.light`, and runs until it is closed. Fails with one line if there is no display,
/// or if the scene would not fit the GPU (see [`GpuScene::new`]).
pub fn run(scene: Scene, sample: GpuSample, plan: &ShotPlan, options: ViewerOptions) -> Result<()> {
    let no_window = |e: &dyn std::fmt::Display| {
        // winit's OS errors start with the source location of winit itself: drop it.
        let text = e.to_string();
        let reason =
            text.strip_prefix("os error at ").and_then(|t| t.split_once(": ")).map_or(&*text, |(_, r)| r);
        Error::unavailable(format!("cannot open a window ({reason})"), crate::Remedy::Headless)
    };
    let event_loop = EventLoop::new().map_err(|e| no_window(&e))?;
    let mut app = App {
        setup: Some((scene, sample, options.lighting.clone())),
        plan: *plan,
        state: None,
        error: None,
        controls: Controls::new(plan, options.mode),
        save_dir: options.save_dir,
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
    overlay: bool,
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
            overlay: true,
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
            KeyCode::KeyO => self.overlay = !self.overlay,
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
            self.light.1 = (self.light.1 + LIGHT_SPEED * (now - self.last).as_secs_f32()).rem_euclid(360.0);
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

    /// The overlay's lines.
    fn overlay_text(&self, fps: f32, lighting: &GpuLighting) -> Vec<String> {
        let display = match self.display {
            Display::Btf => "BTF",
            Display::FirstImage => "FIRST IMAGE",
            Display::TextonFalseColour => "TEXTONS",
        };
        let mode = if self.mode == Mode::Pixel { "PIXEL" } else { "VERTEX" };
        let light = if lighting.sun > 0.0 {
            format!(
                "LIGHT {:.0},{:.0}{}",
                self.light.0,
                self.light.1,
                if self.paused { " PAUSED" } else { "" }
            )
        } else {
            "NO SUN".to_string()
        };
        let env = if lighting.environment.is_some() { " +ENV" } else { "" };
        vec![
            format!("{fps:.1} FPS"),
            format!("{light}{env}"),
            format!("VIEW {:.0},{:.0} {mode} {display}", self.view.0, self.view.1.rem_euclid(360.0)),
            "S:SAVE B/T/M/O:TOGGLE".to_string(),
        ]
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

/// Frames drawn since the overlay last changed.
struct FrameRate {
    since: Instant,
    frames: u32,
}

/// The window and what draws into it.
struct State {
    window: Arc<Window>,
    surface: wgpu::Surface<'static>,
    config: wgpu::SurfaceConfiguration,
    targets: FrameTargets,
    scene: GpuScene,
    overlay: Overlay,
    rate: FrameRate,
    /// The camera the environment was last shaded for: kept while the user drags, so that
    /// a drag on a large model does not reshade the environment at every step.
    environment_camera: Option<Camera>,
}

struct App {
    setup: Option<(Scene, GpuSample, GpuLighting)>,
    plan: ShotPlan,
    state: Option<State>,
    error: Option<Error>,
    controls: Controls,
    save_dir: PathBuf,
}

impl App {
    fn open(&mut self, event_loop: &ActiveEventLoop) -> Result<State> {
        let (scene, sample, lighting) =
            self.setup.take().ok_or_else(|| Error::internal("viewer resumed twice"))?;
        let (w, h) = self.plan.size;
        let attributes = Window::default_attributes()
            .with_title("btfsynth view")
            .with_inner_size(winit::dpi::PhysicalSize::new(w, h));
        let window = Arc::new(event_loop.create_window(attributes).map_err(|e| {
            Error::unavailable(format!("cannot open a window ({e})"), crate::Remedy::Headless)
        })?);
        let descriptor = wgpu::InstanceDescriptor::new_with_display_handle_from_env(Box::new(
            event_loop.owned_display_handle(),
        ));
        let instance = wgpu::Instance::new(descriptor);
        let surface = instance.create_surface(window.clone()).map_err(|e| {
            Error::unavailable(format!("cannot draw into the window: {e}"), crate::Remedy::Headless)
        })?;
        let gpu = Gpu::new(&instance, Some(&surface))?;
        let size = window.inner_size();
        let mut config = surface
            .get_default_config(&gpu.adapter, size.width.max(1), size.height.max(1))
            .ok_or_else(|| Error::gpu(format!("{} cannot draw into this window", gpu.name())))?;
        // The shader writes linear colour: an sRGB surface encodes it.
        config.format = config.format.add_srgb_suffix();
        surface.configure(&gpu.device, &config);
        let name = gpu.name();
        let frame = (config.width, config.height);
        let scene = GpuScene::new(gpu, (scene, sample), (Some(config.format), frame), lighting)?;
        let targets = FrameTargets::new(&scene.gpu.device, (config.width, config.height), scene.target);
        let overlay = Overlay::new(&scene.gpu.device, config.format);
        eprintln!(
            "drawing on {name} ({} samples per pixel; {})",
            scene.target.samples,
            scene.values.describe()
        );
        let rate = FrameRate { since: Instant::now(), frames: 0 };
        Ok(State { window, surface, config, targets, scene, overlay, rate, environment_camera: None })
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
        self.surface.configure(&self.scene.gpu.device, &self.config);
        self.targets = FrameTargets::new(&self.scene.gpu.device, (width, height), self.scene.target);
    }

    fn size(&self) -> (u32, u32) {
        (self.config.width, self.config.height)
    }

    fn draw(&mut self, controls: &Controls, plan: &ShotPlan) -> Result<()> {
        let frame = match self.surface.get_current_texture() {
            wgpu::CurrentSurfaceTexture::Success(t) | wgpu::CurrentSurfaceTexture::Suboptimal(t) => t,
            wgpu::CurrentSurfaceTexture::Outdated | wgpu::CurrentSurfaceTexture::Lost => {
                self.surface.configure(&self.scene.gpu.device, &self.config);
                return Ok(());
            }
            _ => return Ok(()),
        };
        self.update_overlay(controls);
        let shot = controls.shot(plan, self.scene.scene.mesh.bounds(), self.size());
        if !controls.dragging || self.environment_camera.is_none() {
            self.environment_camera = Some(shot.camera);
        }
        let environment_camera = self.environment_camera.unwrap_or(shot.camera);
        self.scene.prepare(&shot, controls.mode, controls.display, &environment_camera);
        let gpu = &self.scene.gpu;
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        let view = frame.texture.create_view(&Default::default());
        let background = wgpu::Color { r: 0.02, g: 0.02, b: 0.02, a: 1.0 };
        self.scene.passes.encode(&mut encoder, &view, &self.targets, background);
        if controls.overlay {
            self.overlay.encode(&gpu.queue, &mut encoder, &view, self.size());
        }
        gpu.queue.submit([encoder.finish()]);
        self.window.pre_present_notify();
        gpu.queue.present(frame);
        self.rate.frames += 1;
        gpu.check()
    }

    /// New overlay text every [`OVERLAY_PERIOD`], with the frame rate over that time.
    fn update_overlay(&mut self, controls: &Controls) {
        let elapsed = self.rate.since.elapsed().as_secs_f32();
        if self.rate.frames > 0 && elapsed < OVERLAY_PERIOD {
            return;
        }
        let fps = if elapsed > 0.0 { self.rate.frames as f32 / elapsed } else { 0.0 };
        let text = TextImage::new(&controls.overlay_text(fps, &self.scene.lighting));
        self.overlay.set_text(&self.scene.gpu.device, &self.scene.gpu.queue, &text);
        self.rate = FrameRate { since: Instant::now(), frames: self.rate.frames.min(1) };
    }

    /// Draws the current shot (without the overlay) offscreen and writes it as a PNG in
    /// `dir`, under the first free name `view-NNNN.png`.
    fn save(&mut self, controls: &Controls, plan: &ShotPlan, dir: &Path) -> Result<PathBuf> {
        let format = self.config.format;
        let swap = match format {
            wgpu::TextureFormat::Rgba8UnormSrgb | wgpu::TextureFormat::Rgba8Unorm => false,
            wgpu::TextureFormat::Bgra8UnormSrgb | wgpu::TextureFormat::Bgra8Unorm => true,
            other => return Err(Error::gpu(format!("cannot save frames of a {other:?} window"))),
        };
        let size = self.size();
        let shot = controls.shot(plan, self.scene.scene.mesh.bounds(), size);
        self.scene.prepare(&shot, controls.mode, controls.display, &shot.camera);
        self.environment_camera = Some(shot.camera);
        let gpu = &self.scene.gpu;
        let texture = gpu.device.create_texture(&wgpu::TextureDescriptor {
            label: Some("saved frame"),
            size: wgpu::Extent3d { width: size.0, height: size.1, depth_or_array_layers: 1 },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
            view_formats: &[],
        });
        let staging = readback::staging_buffer(&gpu.device, size, format);
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        let background = wgpu::Color { r: 0.02, g: 0.02, b: 0.02, a: 1.0 };
        let view = texture.create_view(&Default::default());
        self.scene.passes.encode(&mut encoder, &view, &self.targets, background);
        readback::copy(&mut encoder, &texture, &staging);
        gpu.queue.submit([encoder.finish()]);
        let mut bytes = readback::read_bytes(&gpu.device, &staging, size, 4)?;
        gpu.check()?;
        for p in bytes.chunks_exact_mut(4) {
            if swap {
                p.swap(0, 2);
            }
            p[3] = 255;
        }
        let path =
            (0..10_000).map(|i| dir.join(format!("view-{i:04}.png"))).find(|p| !p.exists()).ok_or_else(
                || Error::output_refused(dir, format!("{}: no free view-NNNN.png name left", dir.display())),
            )?;
        let (w, h) = (size.0 as usize, size.1 as usize);
        crate::fsutil::write_with_temp(&path, |tmp| {
            crate::btf::image_io::write_png8(tmp, w, h, &bytes, image::ExtendedColorType::Rgba8)
        })?;
        Ok(path)
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
                KeyCode::KeyS => match state.save(c, &self.plan, &self.save_dir) {
                    Ok(path) => eprintln!("saved {}", path.display()),
                    Err(e) => eprintln!("cannot save the frame: {e}"),
                },
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
                if let Err(e) = state.draw(c, &self.plan) {
                    self.fail(event_loop, e);
                }
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
