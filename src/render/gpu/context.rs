//! Finding a GPU: an adapter (headless, or compatible with a window's surface) and a device
//! with the adapter's own limits, since a BTF atlas needs large textures.

use crate::{Error, Result};

/// What to tell a user whose machine has no adapter at all.
pub const NO_ADAPTER: &str = "no GPU adapter found (wgpu found no Vulkan, Metal, DX12 or GL device); on \
Debian/Ubuntu install the software drivers: apt-get install mesa-vulkan-drivers libvulkan1 libegl1 \
libegl-mesa0 libgl1-mesa-dri";

/// A device and its queue, and the name of the adapter they run on.
pub struct Gpu {
    pub device: wgpu::Device,
    pub queue: wgpu::Queue,
    pub adapter: wgpu::Adapter,
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
            pollster::block_on(instance.request_adapter(&options)).map_err(|_| Error::invalid(NO_ADAPTER))?;
        let descriptor = wgpu::DeviceDescriptor {
            label: Some("btfsynth"),
            required_limits: adapter.limits(),
            ..Default::default()
        };
        let (device, queue) = pollster::block_on(adapter.request_device(&descriptor))
            .map_err(|e| Error::invalid(format!("cannot open the GPU {}: {e}", adapter.get_info().name)))?;
        Ok(Gpu { device, queue, adapter })
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
        if wgpu::Backends::from_env().is_some() {
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
