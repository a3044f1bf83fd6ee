//! The environment variables btfsynth reads, each with its one parser. A value is parsed
//! where it is used, which not every command reaches; [`check`] parses every one that is
//! set, so that a front end refuses a bad value before any work, whichever command runs
//! (the command line does, with exit code 2).
//!
//! - `BTFSYNTH_MEMORY`: the memory budget ([`crate::btf::source::memory_budget`]).
//! - `BTFSYNTH_DECODE_LIMIT`: the largest factored sample decoded when rendering
//!   ([`crate::render::material::decode_limit`]).
//! - `BTFSYNTH_GPU_MEMORY`: the GPU memory limit (`render::gpu::memory::limit`).
//! - `WGPU_BACKEND`: the wgpu backends tried ([`wgpu_backends`]).

use crate::Result;

/// Parses every variable of the module's list that is set; the first bad one is the error.
pub fn check() -> Result<()> {
    crate::btf::source::memory_budget()?;
    crate::render::material::decode_limit()?;
    #[cfg(feature = "gpu")]
    {
        crate::render::gpu::memory::limit_from_env()?;
        wgpu_backends()?;
    }
    Ok(())
}

/// The backends `WGPU_BACKEND` names (a comma-separated list: vulkan, gl, metal, dx12,
/// webgpu, noop and their aliases), or None where it is unset. A name wgpu does not know is
/// an error here: wgpu itself would log a warning, try no backend at all and report no
/// adapter, as if the drivers were missing.
#[cfg(feature = "gpu")]
pub fn wgpu_backends() -> Result<Option<wgpu::Backends>> {
    const NAME: &str = "WGPU_BACKEND";
    let Ok(text) = std::env::var(NAME) else { return Ok(None) };
    const KNOWN: [&str; 11] =
        ["vulkan", "vk", "dx12", "d3d12", "metal", "mtl", "opengl", "gles", "gl", "webgpu", "noop"];
    if text.split(',').all(|name| KNOWN.contains(&name.trim().to_lowercase().as_str())) {
        return Ok(Some(wgpu::Backends::from_comma_list(&text)));
    }
    Err(crate::Error::invalid(format!(
        "{NAME}='{text}': expected backend names separated by commas: vulkan, gl, metal, dx12, webgpu"
    )))
}
