//! Finding a GPU: an adapter (headless, or compatible with a window's surface) and a device
//! with the adapter's own limits, since a BTF atlas needs large textures.

use crate::{Error, Result};
use std::sync::{Arc, Mutex};

/// What to tell a user whose machine has no adapter at all.
pub const NO_ADAPTER: &str = "no GPU adapter found (wgpu found no Vulkan, Metal, DX12 or GL device); on \
Debian/Ubuntu install the software drivers: apt-get install mesa-vulkan-drivers libvulkan1 libegl1 \
libegl-mesa0 libgl1-mesa-dri";

/// A device and its queue, and the name of the adapter they run on.
pub struct Gpu {
    /// The device that owns every buffer, texture and pipeline of the scene.
    pub device: wgpu::Device,
    /// The device's command queue.
    pub queue: wgpu::Queue,
    /// The adapter the device runs on (its name goes into reports).
    pub adapter: wgpu::Adapter,
    /// The first error wgpu reported outside an error scope (instead of panicking).
    errors: Arc<Mutex<Option<String>>>,
}

/// The formats and sample count this adapter renders with.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Formats {
    /// Offscreen colour target: Rgba32Float where it is renderable, else Rgba16Float (GL).
    pub target: wgpu::TextureFormat,
    /// The sample images: Rgba16Float where it can be sampled, else Rgba32Float.
    pub images: wgpu::TextureFormat,
    /// The camera's depth buffer and the shadow map.
    pub depth: wgpu::TextureFormat,
}

/// A wgpu error as one line (its messages are indented blocks over several lines).
pub fn one_line(error: &dyn std::fmt::Display) -> String {
    error.to_string().split_whitespace().collect::<Vec<_>>().join(" ")
}

impl Gpu {
    /// An adapter able to present to `surface` if given (any adapter otherwise); `WGPU_BACKEND`
    /// (e.g. `vulkan`, `gl`) restricts which backends are tried.
    pub fn new(instance: &wgpu::Instance, surface: Option<&wgpu::Surface<'_>>) -> Result<Gpu> {
        let options = wgpu::RequestAdapterOptions {
            power_preference: wgpu::PowerPreference::HighPerformance,
            compatible_surface: surface,
            ..Default::default()
        };
        let adapter =
            pollster::block_on(instance.request_adapter(&options)).map_err(|_| Error::gpu(NO_ADAPTER))?;
        // Multisampled float targets need the adapter's own format capabilities, beyond
        // what WebGPU guarantees everywhere.
        let specific = wgpu::Features::TEXTURE_ADAPTER_SPECIFIC_FORMAT_FEATURES;
        let descriptor = wgpu::DeviceDescriptor {
            label: Some("btfsynth"),
            required_limits: adapter.limits(),
            required_features: adapter.features() & specific,
            ..Default::default()
        };
        let (device, queue) = pollster::block_on(adapter.request_device(&descriptor))
            .map_err(|e| Error::gpu(format!("cannot open the GPU {}: {e}", adapter.get_info().name)))?;
        let errors = Arc::new(Mutex::new(None));
        let slot = errors.clone();
        device.on_uncaptured_error(Arc::new(move |e: wgpu::Error| {
            if let Ok(mut first) = slot.lock() {
                first.get_or_insert_with(|| one_line(&e));
            }
        }));
        Ok(Gpu { device, queue, adapter, errors })
    }

    /// Fails with the first error wgpu reported since the last call, if any.
    pub fn check(&self) -> Result<()> {
        match self.errors.lock().ok().and_then(|mut e| e.take()) {
            Some(e) => Err(Error::gpu(format!("the GPU {} failed: {e}", self.name()))),
            None => Ok(()),
        }
    }

    /// Runs `build` (creating pipelines, textures, buffers) and turns any validation or
    /// memory error it causes into one error line.
    pub fn scoped<T>(&self, what: &str, build: impl FnOnce() -> Result<T>) -> Result<T> {
        let memory = self.device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
        let validation = self.device.push_error_scope(wgpu::ErrorFilter::Validation);
        let built = build();
        let invalid = pollster::block_on(validation.pop());
        let out_of_memory = pollster::block_on(memory.pop());
        if let Some(e) = invalid.or(out_of_memory) {
            return Err(Error::gpu(format!("{} cannot {what}: {}", self.name(), one_line(&e))));
        }
        built
    }

    /// The formats to render with on this adapter (GL cannot render to Rgba32Float).
    pub fn formats(&self) -> Result<Formats> {
        use wgpu::{TextureFormat as F, TextureUsages as U};
        let allows = |f: F, usage: U| self.format_features(f).allowed_usages.contains(usage);
        let first = |candidates: &[F], usage: U, what: &str| {
            candidates.iter().copied().find(|&f| allows(f, usage)).ok_or_else(|| {
                Error::gpu(format!("{} supports none of {candidates:?} as {what}", self.name()))
            })
        };
        Ok(Formats {
            target: first(
                &[F::Rgba32Float, F::Rgba16Float],
                U::RENDER_ATTACHMENT | U::COPY_SRC,
                "a colour target",
            )?,
            images: first(
                &[F::Rgba16Float, F::Rgba32Float],
                U::TEXTURE_BINDING | U::COPY_DST,
                "sampled images",
            )?,
            depth: first(
                &[F::Depth32Float, F::Depth24Plus],
                U::RENDER_ATTACHMENT | U::TEXTURE_BINDING,
                "a depth buffer",
            )?,
        })
    }

    /// What the device may do with `format`: the adapter's own capabilities where the device
    /// has them enabled, else those of them that WebGPU guarantees.
    fn format_features(&self, format: wgpu::TextureFormat) -> wgpu::TextureFormatFeatures {
        let adapter = self.adapter.get_texture_format_features(format);
        if self.device.features().contains(wgpu::Features::TEXTURE_ADAPTER_SPECIFIC_FORMAT_FEATURES) {
            return adapter;
        }
        let guaranteed = format.guaranteed_format_features(self.device.features());
        wgpu::TextureFormatFeatures {
            allowed_usages: adapter.allowed_usages & guaranteed.allowed_usages,
            flags: adapter.flags & guaranteed.flags,
        }
    }

    /// The most samples per pixel up to 4 that `colour` and `depth` both support (with a
    /// resolve of `colour`): 4 on most adapters, 1 where multisampling is missing.
    pub fn msaa_samples(&self, colour: wgpu::TextureFormat, depth: wgpu::TextureFormat) -> u32 {
        let (c, d) = (self.format_features(colour), self.format_features(depth));
        let resolvable = c.flags.contains(wgpu::TextureFormatFeatureFlags::MULTISAMPLE_RESOLVE);
        if resolvable && c.flags.sample_count_supported(4) && d.flags.sample_count_supported(4) {
            4
        } else {
            1
        }
    }

    /// A device with no window: `WGPU_BACKEND` (e.g. `vulkan`, `gl`) if set, else the native
    /// APIs first and GL only if they find nothing (probing GL without a display logs noise).
    pub fn headless() -> Result<Gpu> {
        let instance = |backends: Option<wgpu::Backends>| {
            let mut descriptor = wgpu::InstanceDescriptor::new_without_display_handle_from_env();
            if let Some(b) = backends {
                descriptor.backends = b;
            }
            wgpu::Instance::new(descriptor)
        };
        if crate::env::wgpu_backends()?.is_some() {
            return Gpu::new(&instance(None), None);
        }
        Gpu::new(&instance(Some(wgpu::Backends::PRIMARY)), None)
            .or_else(|_| Gpu::new(&instance(Some(wgpu::Backends::SECONDARY)), None))
    }

    /// The adapter's name and backend, e.g. "llvmpipe (LLVM 19.1.7, 256 bits) (Vulkan)".
    pub fn name(&self) -> String {
        let info = self.adapter.get_info();
        format!("{} ({:?})", info.name, info.backend)
    }
}
