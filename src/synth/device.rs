//! Where a synthesis runs its passes: on the CPU, or on a GPU through wgpu compute
//! ([`super::gpu`], feature `gpu`). The GPU runs the passes that have a GPU form (interleaved
//! square-template passes on a plane, see [`super::gpu`]) and gives the CPU's coordinates to
//! the bit; every other pass runs on the CPU, and each level's report says which ran where.

use super::engine::{PassStats, State};
use super::job::PassJob;
use super::neighbourhood::Neighbourhood;
use super::recipe::{Preset, VisitOrder};
use super::target::{Neighbourhoods, TargetLevel};
use crate::Result;

/// Where synthesis passes run.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Device {
    /// On a GPU where the machine has a hardware adapter; on the CPU where it has none, or
    /// only a software one (Mesa's lavapipe or llvmpipe, slower than the CPU path).
    #[default]
    Auto,
    /// On the CPU.
    Cpu,
    /// On a GPU, software adapters included; an error where wgpu finds no adapter.
    Gpu,
}

/// Whether any pass of `preset` on `targets` may have a GPU form: a plane level and an
/// interleaved square-template pass.
pub(crate) fn may_use_gpu(targets: &[TargetLevel], preset: &Preset) -> bool {
    let plane = targets.iter().any(|t| matches!(t.neighbourhoods, Neighbourhoods::Grid { .. }));
    let pass = preset.all_passes().any(|p| {
        p.order == VisitOrder::Interleaved && matches!(p.neighbourhood, Neighbourhood::Square { .. })
    });
    plane && pass
}

/// Runs the passes that can run on the GPU there, and counts per level which ran where.
pub(crate) struct Runner {
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
    /// wgpu finds no adapter), [`Device::Auto`] where `wanted` (some pass may run there)
    /// and the machine has a hardware adapter.
    pub(crate) fn open(device: Device, wanted: bool) -> Result<Runner> {
        #[cfg(feature = "gpu")]
        let (gpu, why_no_gpu) = open_gpu(device, wanted)?;
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
        let _ = wanted;
        Ok(Runner {
            why_no_gpu,
            #[cfg(feature = "gpu")]
            gpu,
            on_gpu: 0,
            on_cpu: 0,
            why_cpu: None,
        })
    }

    /// Runs `job` on the GPU if one is open and the pass has a GPU form there, updating
    /// `state`; `None` if it is the CPU's to run.
    pub(crate) fn pass(&mut self, job: &PassJob, state: &mut State) -> Result<Option<PassStats>> {
        #[cfg(feature = "gpu")]
        if let Some(gpu) = &mut self.gpu {
            match gpu.run(job, state)? {
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
        match (name, on_gpu, on_cpu) {
            (Some(name), g, 0) if g > 0 => format!("gpu ({name})"),
            (Some(_), 0, _) => format!("cpu (no GPU form: {})", why.unwrap_or_default()),
            (Some(name), g, c) => format!(
                "gpu ({name}) for {g} of {} passes, cpu for the others (no GPU form: {})",
                g + c,
                why.unwrap_or_default()
            ),
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
fn open_gpu(device: Device, wanted: bool) -> Result<(Option<super::gpu::GpuSynth>, String)> {
    use super::gpu::{hardware_adapter, GpuSynth};
    Ok(match device {
        Device::Cpu => (None, String::new()),
        Device::Gpu => (Some(GpuSynth::new()?), String::new()),
        Device::Auto if !wanted => (None, "no pass has a GPU form".into()),
        Device::Auto if !hardware_adapter() => (None, "no hardware GPU adapter".into()),
        // A GPU that is there but does not open is no reason to fail: the CPU gives the same
        // bytes.
        Device::Auto => match GpuSynth::new() {
            Ok(gpu) => (Some(gpu), String::new()),
            Err(e) => {
                tracing::warn!("synthesizing on the CPU: {e}");
                (None, format!("the GPU did not open: {e}"))
            }
        },
    })
}
