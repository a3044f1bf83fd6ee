//! Where a synthesis runs its passes: on the CPU, or on a GPU through wgpu compute
//! ([`super::gpu`], feature `gpu`). The GPU runs the passes that have a GPU form (interleaved
//! square-template passes, on planes and meshes; see [`super::gpu`]) and gives the
//! CPU's coordinates to the bit; every other pass runs on the CPU, and each level's report
//! says which ran where.

use super::candidates::Search;
use super::engine::{PassStats, State};
use super::job::PassJob;
use super::neighbourhood::Neighbourhood;
use super::recipe::{pass_search, Preset, VisitOrder};
use crate::Result;

/// Where synthesis passes run.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Device {
    /// On a GPU where the machine has a hardware adapter; on the CPU where it has none, or
    /// only a software one (Mesa's lavapipe or llvmpipe, slower than the CPU path), and for
    /// full-search passes, which the CPU runs faster.
    #[default]
    Auto,
    /// On the CPU.
    Cpu,
    /// On a GPU, software adapters included; an error where wgpu finds no adapter.
    Gpu,
}

/// Why [`Device::Auto`] leaves a GPU closed for `preset` with `search` asked,
/// if it does: no pass has a GPU form (an interleaved square-template pass), or every pass
/// that has one runs a full search
/// ([`AUTO_FULL_SEARCH`]).
pub(crate) fn why_auto_keeps_the_cpu(preset: &Preset, search: Search) -> Option<&'static str> {
    let mut passes = preset.all_passes().filter(|p| {
        matches!(p.neighbourhood, Neighbourhood::Square { .. }) && p.order == VisitOrder::Interleaved
    });
    let first = passes.next();
    if first.is_none() {
        return Some("no pass has a GPU form");
    }
    let full = |p: &super::recipe::Pass| pass_search(p, search) == Search::Full;
    (first.is_some_and(full) && passes.all(full)).then_some(AUTO_FULL_SEARCH)
}

/// Why [`Device::Auto`] runs full-search passes on the CPU: the GPU form gives each vertex
/// one invocation that scores every candidate texel in turn, so a sub-pass fills few of a
/// GPU's cores. A 128² plane with a full search took 34 s on an NVIDIA H200 and 3.8 s on
/// its host's 16 cores (docs/speed.md).
const AUTO_FULL_SEARCH: &str = "a full search, which the CPU runs faster";

/// Runs the passes that can run on the GPU there, and counts per level which ran where.
pub(crate) struct Runner {
    /// Whether the GPU was chosen by [`Device::Auto`] (which leaves full searches to the CPU).
    #[cfg(feature = "gpu")]
    auto: bool,
    /// Why no GPU is open, for the reports ("" under [`Device::Cpu`], which asked for none).
    why_no_gpu: String,
    #[cfg(feature = "gpu")]
    gpu: Option<super::gpu::GpuSynth>,
    on_gpu: usize,
    on_cpu: usize,
    why_cpu: Option<String>,
}

impl Runner {
    /// Opens the GPU `device` asks for: [`Device::Gpu`] always (failing with one line where
    /// wgpu finds no adapter), [`Device::Auto`] where nothing keeps it on the CPU (`keep`,
    /// from [`why_auto_keeps_the_cpu`]) and the machine has a hardware adapter.
    pub(crate) fn open(device: Device, keep: Option<&'static str>) -> Result<Runner> {
        #[cfg(feature = "gpu")]
        let (gpu, why_no_gpu) = open_gpu(device, keep)?;
        #[cfg(not(feature = "gpu"))]
        let why_no_gpu = match device {
            Device::Gpu => {
                return Err(crate::Error::gpu(
                    "this btfsynth was built without the GPU (cargo feature `gpu`)",
                ))
            }
            Device::Auto => "built without the GPU".into(),
            Device::Cpu => String::new(),
        };
        #[cfg(not(feature = "gpu"))]
        let _ = keep;
        Ok(Runner {
            #[cfg(feature = "gpu")]
            auto: device == Device::Auto,
            why_no_gpu,
            #[cfg(feature = "gpu")]
            gpu,
            on_gpu: 0,
            on_cpu: 0,
            why_cpu: None,
        })
    }

    /// Runs `job` on the GPU if one is open and the pass has a GPU form there (and, under
    /// [`Device::Auto`], is no full search), updating `state`; `None` if it is the CPU's.
    pub(crate) fn pass(&mut self, job: &PassJob, state: &mut State) -> Result<Option<PassStats>> {
        #[cfg(feature = "gpu")]
        if let Some(gpu) = &mut self.gpu {
            let ran = match self.auto && job.search == Search::Full {
                true => Err(AUTO_FULL_SEARCH.to_string()),
                false => gpu.run(job, state)?.map_err(|why| format!("no GPU form: {why}")),
            };
            match ran {
                Ok(stats) => {
                    self.on_gpu += 1;
                    return Ok(Some(stats));
                }
                Err(why) => {
                    self.why_cpu.get_or_insert(why);
                }
            }
        }
        let _ = (job, state);
        self.on_cpu += 1;
        Ok(None)
    }

    /// Where the passes of the level just finished ran, in words (for its report), and a
    /// fresh count for the next level.
    pub(crate) fn level_done(&mut self) -> String {
        let (on_gpu, on_cpu, why) = (self.on_gpu, self.on_cpu, self.why_cpu.take());
        (self.on_gpu, self.on_cpu) = (0, 0);
        let name = self.gpu_name();
        let why = why.unwrap_or_default();
        match (name, on_gpu, on_cpu) {
            (Some(name), g, 0) if g > 0 => format!("gpu ({name})"),
            (Some(_), 0, _) => format!("cpu ({why})"),
            (Some(name), g, c) => {
                format!("gpu ({name}) for {g} of {} passes, cpu for the others ({why})", g + c)
            }
            (None, _, _) if self.why_no_gpu.is_empty() => "cpu".into(),
            (None, _, _) => format!("cpu ({})", self.why_no_gpu),
        }
    }

    fn gpu_name(&self) -> Option<String> {
        #[cfg(feature = "gpu")]
        if let Some(gpu) = &self.gpu {
            return Some(gpu.name());
        }
        None
    }
}

/// The GPU `device` asks for (see [`Runner::open`]), or why there is none ("" under
/// [`Device::Cpu`]).
#[cfg(feature = "gpu")]
fn open_gpu(device: Device, keep: Option<&'static str>) -> Result<(Option<super::gpu::GpuSynth>, String)> {
    use super::gpu::{hardware_adapter, GpuSynth};
    Ok(match device {
        Device::Cpu => (None, String::new()),
        Device::Gpu => (Some(GpuSynth::new()?), String::new()),
        Device::Auto => match keep {
            Some(why) => (None, why.into()),
            None if !hardware_adapter() => (None, "no hardware GPU adapter".into()),
            // A GPU that is there but does not open is no reason to fail: the CPU gives the
            // same bytes.
            None => match GpuSynth::new() {
                Ok(gpu) => (Some(gpu), String::new()),
                Err(e) => {
                    tracing::warn!("synthesizing on the CPU: {e}");
                    (None, format!("the GPU did not open: {e}"))
                }
            },
        },
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `auto` may open a GPU for the presets with a GPU form (`appearance` and `tong2002`, on
    /// a plane or a mesh) under k-coherence, and keeps the CPU for a full search and for the
    /// others.
    #[test]
    fn auto_keeps_the_cpu_for_full_searches_and_presets_without_a_gpu_form() {
        for preset in Preset::all() {
            let has_form = ["appearance", "tong2002"].contains(&preset.name.as_str());
            let k = why_auto_keeps_the_cpu(&preset, Search::KCoherence { k: 11 });
            let full = why_auto_keeps_the_cpu(&preset, Search::Full);
            match has_form {
                true => assert_eq!((k, full), (None, Some(AUTO_FULL_SEARCH)), "{}", preset.name),
                false => assert_eq!(k, Some("no pass has a GPU form"), "{}", preset.name),
            }
        }
    }
}
