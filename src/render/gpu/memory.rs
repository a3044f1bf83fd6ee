//! The GPU memory a scene will take, counted before anything is uploaded, and the limit it
//! is checked against: a scene that would not fit is refused with one line instead of a
//! wgpu error, an out-of-memory kill or minutes of decoding images for an atlas that the
//! GPU cannot hold.
//!
//! wgpu does not say how much memory an adapter has. The limit is `BTFSYNTH_GPU_MEMORY`
//! (`6G`, `512M`, bytes; `unlimited` turns the check off) when set; else, for a software
//! adapter (lavapipe, llvmpipe: its memory is the machine's), btfsynth's memory budget
//! (80% of `MemAvailable`, or `BTFSYNTH_MEMORY`); else the smaller of that budget and
//! [`DEFAULT_GPU_MEMORY`].

use crate::analysis::memory::gib;
use crate::btf::source::{memory_budget, parse_size_env};
use crate::{Error, Remedy, Result};

/// The environment variable that sets the GPU memory limit.
pub const GPU_MEMORY_ENV: &str = "BTFSYNTH_GPU_MEMORY";

/// The limit on a hardware adapter whose memory nobody named: 4 GiB, what nearly every
/// discrete or integrated GPU of recent years can give one application.
pub const DEFAULT_GPU_MEMORY: u64 = 4 << 30;

/// What a scene will upload, by item, in bytes.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Estimate {
    /// Each item's name and its size in bytes, in the order added.
    pub items: Vec<(String, u64)>,
}

impl Estimate {
    /// Adds an item.
    pub fn add(&mut self, name: impl Into<String>, bytes: u64) {
        self.items.push((name.into(), bytes));
    }

    /// All items together.
    pub fn total(&self) -> u64 {
        self.items.iter().map(|(_, b)| b).sum()
    }

    /// The largest item.
    pub fn largest(&self) -> Option<&(String, u64)> {
        self.items.iter().max_by_key(|(_, b)| *b)
    }

    /// Fails with one line naming the total, the largest item and `remedy` when the total
    /// exceeds `limit` (bytes, and where that figure comes from); `gpu` names the adapter.
    pub fn check(&self, gpu: &str, limit: Option<(u64, String)>, remedy: Remedy) -> Result<()> {
        let Some((limit, source)) = limit else { return Ok(()) };
        if self.total() <= limit {
            return Ok(());
        }
        let (name, bytes) = self.largest().cloned().unwrap_or_default();
        Err(Error::too_large(
            format!(
                "showing this scene on {gpu} would need about {} of GPU memory ({name}: {}), more than its {} \
                 limit ({source})",
                gib(self.total()),
                gib(bytes),
                gib(limit)
            ),
            remedy,
        ))
    }
}

/// The limit `BTFSYNTH_GPU_MEMORY` sets, where it is set (inside, None: `unlimited`).
pub fn limit_from_env() -> Result<Option<Option<(u64, String)>>> {
    std::env::var(GPU_MEMORY_ENV).ok().map(|text| parse_size_env(GPU_MEMORY_ENV, &text)).transpose()
}

/// The GPU memory limit for an adapter of `kind` (see the module notes).
pub fn limit(kind: wgpu::DeviceType) -> Result<Option<(u64, String)>> {
    if let Some(limit) = limit_from_env()? {
        return Ok(limit);
    }
    let budget = memory_budget()?;
    if kind == wgpu::DeviceType::Cpu {
        return Ok(budget.map(|(b, source)| (b, format!("a software adapter: {source}"))));
    }
    let default = (DEFAULT_GPU_MEMORY, format!("the default; set {GPU_MEMORY_ENV} to allow more"));
    Ok(Some(match budget {
        Some((b, source)) if b < DEFAULT_GPU_MEMORY => (b, source),
        _ => default,
    }))
}

/// Fails with one line when a buffer of `bytes` bound as storage exceeds `limits`.
pub fn check_binding(what: &str, bytes: u64, limits: &wgpu::Limits) -> Result<()> {
    let max = limits.max_storage_buffer_binding_size.min(limits.max_buffer_size);
    if bytes > max {
        return Err(Error::gpu(format!(
            "{what} need {} in one buffer but this GPU binds at most {}",
            gib(bytes),
            gib(max)
        )));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_scene_over_the_limit_is_one_line_naming_its_largest_item() {
        let mut e = Estimate::default();
        e.add("sample images as an atlas", 3 << 30);
        e.add("blends", 1 << 20);
        assert!(e.check("gpu", Some((4 << 30, "x".into())), Remedy::UploadFactors).is_ok());
        assert!(e.check("gpu", None, Remedy::UploadFactors).is_ok());
        let refused = e.check("gpu", Some((1 << 30, "x".into())), Remedy::UploadFactors).unwrap_err();
        assert!(matches!(refused, Error::TooLarge { remedy: Remedy::UploadFactors, .. }), "{refused:?}");
        let message = refused.to_string();
        assert!(message.contains("3.0 GiB of GPU memory (sample images as an atlas: 3.0 GiB)"), "{message}");
        assert!(
            message.contains("1.0 GiB limit (x); upload the sample's factors") && !message.contains('\n')
        );
    }

    #[test]
    fn a_binding_larger_than_the_adapter_binds_is_refused() {
        let limits = wgpu::Limits::default();
        let max = limits.max_storage_buffer_binding_size.min(limits.max_buffer_size);
        assert!(check_binding("image factors", max, &limits).is_ok());
        assert!(check_binding("image factors", max + 1, &limits)
            .unwrap_err()
            .to_string()
            .contains("binds at most"));
    }
}
