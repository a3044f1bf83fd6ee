//! Interleaved correction passes on a GPU (wgpu compute, `shaders/synth_pass.wgsl`): the
//! order-independent schedule of [`super::pass::run_interleaved_pass`], sub-pass (colour)
//! after sub-pass, one invocation per vertex of the colour. Each invocation gathers the
//! vertex's candidates, scores them and picks the winner exactly as the CPU does (same
//! candidates in the same order, same float operations in the same order, same early exits
//! and ties, the random draw of a vertex without candidates computed on the CPU from the
//! same seed), so a pass leaves the CPU's coordinates to the bit, and its statistics too.
//!
//! A sub-pass is a few dispatches over its vertices (in parts that share one scratch buffer:
//! 4,096 vertices on a software adapter, as many as 512 MiB hold on a hardware one, so that
//! a large GPU is not left mostly idle by small dispatches): one gathers each vertex's
//! candidates (and on a mesh blends its templates), then each of a few scores a batch of
//! them (Mesa's llvmpipe ends an invocation's loops after 65535 iterations in all,
//! `LOOP_BUDGET`), one lets each vertex take its winner, and one moves the choosy use
//! counts. One pass is one
//! command buffer: the state goes up before it and comes back after.
//!
//! The GPU form covers square-template passes under the interleaved order: on a plane (a
//! grid level) the `appearance` and `tong2002` presets on every level, and recipes built
//! like them — every own pixel compared ([`Mask::Full`]), with or without a parent template
//! (narrow or wide), the Γ, appearance or colour metric, argmin or choosy selection,
//! k-coherence or full search; on a mesh the same, each template pixel blending up to three
//! vertices' vectors (or, under Γ, textons) as `metric::known_parts` weighs them. Anything
//! else (sequential orders, round or isotropic neighbourhoods, masked
//! templates, the use penalty, kd-trees) has no GPU form and runs on the CPU (each level's
//! report says which, and why).

use super::candidates::{full_candidates, Search};
use super::engine::{PassStats, Select, State};
use super::job::PassJob;
use super::metric::known_parts;
use super::neighbourhood::{Mask, Neighbourhood, ParentTemplate, SquareMetric};
use super::pass::{Colouring, Schedule, VERTEX_SEED};
use super::sample::{AppearanceMap, SampleLevel};
use super::slot::{Slot, OUTSIDE};
use super::target::{Neighbourhoods, Shift, TargetLevel};
use crate::render::gpu::context::Gpu;
use crate::{Error, Result};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use std::sync::OnceLock;

/// Words of a mesh's template pixel in the shader's tables: three vertices, three weights.
const SLOT_WORDS: usize = 6;

/// Widest template the shader takes (wider ones run on the CPU): 17 texels, the widest
/// the GPU passes have been checked against the CPU with (the maps' border was 8 then).
const MAX_TEMPLATE: usize = 17;
const _: () = assert!(MAX_TEMPLATE <= 2 * AppearanceMap::PAD + 1);

/// Distinct shift texels and candidates of one vertex the smallest table holds: a plane's
/// 5 × 5 window with 11 candidates each, and more.
const MIN_ENTRIES: usize = 640;

/// The most a table may hold: a mesh vertex's patch of about 680 vertices with 11
/// candidates each (some 160 KB of scratch per vertex).
const MAX_ENTRIES: usize = 8192;

/// Vertices matched per dispatch on a software adapter: a sub-pass larger than this is
/// dispatched in parts (they share the scratch, [`Table::stride`] words per vertex). Lavapipe
/// runs on the CPU's few cores, where larger dispatches gain nothing but host memory.
const SOFTWARE_CHUNK: usize = 4096;

/// The scratch one dispatch may take on a hardware adapter (about 49,000 vertices of a
/// plane): on a large GPU, 4,096 vertices fill a few of its cores, and a 1024² plane's
/// sub-pass took 29 parts where 3 do.
const HARDWARE_SCRATCH: u64 = 512 << 20;

/// Loop iterations one score dispatch may spend per invocation: Mesa's llvmpipe (lavapipe)
/// ends every loop of an invocation once they have run 65535 iterations in all
/// (`LP_MAX_TGSI_LOOP_ITERATIONS`), so candidates are scored in batches that stay below.
/// Half of 48,000, which our estimate of a candidate's iterations let through on a mesh's
/// full search of 1,156 or more candidates (a one-level synthesis of a 40² sample): the
/// GPU then chose other texels than the CPU. The hash probes and the SIMD lanes' longest
/// loops are not in the estimate; at 24,000 every size measured (up to 96², 8,100
/// candidates, mesh and plane, Γ and appearance) gives the CPU's bytes.
const LOOP_BUDGET: usize = 24_000;

/// Bytes of each sub-pass's parameters in the uniform buffer (its dynamic offsets' alignment).
const PARAMS_STRIDE: u64 = 256;

/// Threads per workgroup (the shader's `@workgroup_size`).
const GROUP: u32 = 64;

/// Whether wgpu finds a hardware adapter (anything but a CPU one such as lavapipe or
/// llvmpipe), asked once per process. On Linux, only where a GPU device node exists: asking
/// Vulkan where there is none finds at most lavapipe, and Mesa's device-select layer prints
/// two error lines where no display session is set up (XDG_RUNTIME_DIR unset).
pub fn hardware_adapter() -> bool {
    static FOUND: OnceLock<bool> = OnceLock::new();
    *FOUND.get_or_init(|| {
        if cfg!(target_os = "linux") && !gpu_device_node() {
            return false;
        }
        let instance = |backends: Option<wgpu::Backends>| {
            let mut descriptor = wgpu::InstanceDescriptor::new_without_display_handle_from_env();
            if let Some(b) = backends {
                descriptor.backends = b;
            }
            wgpu::Instance::new(descriptor)
        };
        let options = wgpu::RequestAdapterOptions {
            power_preference: wgpu::PowerPreference::HighPerformance,
            ..Default::default()
        };
        let found = |instance: wgpu::Instance| {
            pollster::block_on(instance.request_adapter(&options))
                .is_ok_and(|a| a.get_info().device_type != wgpu::DeviceType::Cpu)
        };
        match crate::env::wgpu_backends() {
            Ok(Some(_)) => return found(instance(None)),
            // wgpu would try no backend: none is found (the command line refuses the value first).
            Err(_) => return false,
            Ok(None) => {}
        }
        found(instance(Some(wgpu::Backends::PRIMARY)))
    })
}

/// Whether Linux shows a GPU: a DRM node (/dev/dri/card*, renderD*), NVIDIA's device or
/// WSL's.
fn gpu_device_node() -> bool {
    let dri = std::fs::read_dir("/dev/dri").map(|entries| {
        entries.flatten().any(|e| {
            e.file_name().to_str().is_some_and(|n| n.starts_with("card") || n.starts_with("renderD"))
        })
    });
    dri.unwrap_or(false)
        || ["/dev/nvidiactl", "/dev/nvidia0", "/dev/dxg"].iter().any(|p| std::path::Path::new(p).exists())
}

/// The pass parameters, as `synth_pass.wgsl`'s `Params` (one copy per sub-pass).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, bytemuck::Pod, bytemuck::Zeroable)]
struct Params {
    grid_w: u32,
    grid_h: u32,
    side: u32,
    wraps: u32,
    sw: u32,
    sh: u32,
    tileable: u32,
    /// How far inside the sample's edges candidates stay (`TargetLevel::candidate_margin`).
    margin: u32,
    list_k: u32,
    list_stride: u32,
    metric: u32,
    dims: u32,
    map_stride: u32,
    textons: u32,
    parent: u32,
    p_side: u32,
    p_grid_w: u32,
    p_grid_h: u32,
    p_wraps: u32,
    p_sw: u32,
    p_sh: u32,
    p_map_stride: u32,
    p_textons: u32,
    choosy: u32,
    fresh: f32,
    full: u32,
    zero: u32,
    off_knn: u32,
    off_labels: u32,
    off_gamma: u32,
    off_map: u32,
    off_p_labels: u32,
    off_p_gamma: u32,
    off_p_map: u32,
    off_parents: u32,
    off_classes: u32,
    off_draws: u32,
    off_table: u32,
    class_offset: u32,
    class_count: u32,
    groups_x: u32,
    full_count: u32,
    stamp: u32,
    off_full: u32,
    batch: u32,
    mesh: u32,
    off_slots: u32,
    off_p_slots: u32,
    off_shift_start: u32,
    off_shifts: u32,
    cap_bits: u32,
    entries: u32,
    stride: u32,
    split: u32,
    query_words: u32,
    fallback: u32,
    p_fallback: u32,
    off_move: u32,
    _pad: [u32; 2],
}

/// A grid's shape: columns, rows, template side, whether it wraps.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Grid {
    width: usize,
    height: usize,
    template: usize,
    wraps: bool,
}

/// A level's templates as the shader reads them: the grid around each vertex, or a mesh's
/// stored pixels and patch vertices.
#[derive(Clone, Copy)]
enum Shape<'a> {
    Grid(Grid),
    Mesh { template: usize, slots: &'a [Slot], shift_start: &'a [u32], shifts: &'a [Shift] },
}

impl Shape<'_> {
    fn of(n: &Neighbourhoods) -> Shape<'_> {
        match *n {
            Neighbourhoods::Grid { width, height, template, wraps } => {
                Shape::Grid(Grid { width, height, template, wraps })
            }
            Neighbourhoods::Mesh { template, ref slots, ref shift_start, ref shifts } => {
                Shape::Mesh { template, slots, shift_start, shifts }
            }
        }
    }

    fn template(&self) -> usize {
        match *self {
            Shape::Grid(g) => g.template,
            Shape::Mesh { template, .. } => template,
        }
    }

    fn is_mesh(&self) -> bool {
        matches!(self, Shape::Mesh { .. })
    }

    /// The most forward shifts a vertex has: its window's pixels on a grid, its patch
    /// vertices on a mesh.
    fn most_shifts(&self) -> usize {
        match self {
            Shape::Grid(g) => g.template * g.template,
            Shape::Mesh { shift_start, .. } => {
                shift_start.windows(2).map(|w| (w[1] - w[0]) as usize).max().unwrap_or(0)
            }
        }
    }
}

/// A pass in its GPU form.
struct Form<'a> {
    metric: SquareMetric,
    shape: Shape<'a>,
    /// The parent templates and the coarser level's state and sample.
    parent: Option<(Shape<'a>, ParentTemplate, &'a State, &'a SampleLevel)>,
    choosy: Option<f32>,
    search: Search,
    colouring: &'a Colouring,
    seed: u64,
    /// [`Shape::most_shifts`] of `shape`, counted once (a mesh's is a pass over its vertices).
    most_shifts: usize,
}

impl Form<'_> {
    /// Pixels of the template and the parent template.
    fn pixels(&self) -> usize {
        let square = |s: Shape| s.template() * s.template();
        square(self.shape) + self.parent.map_or(0, |p| square(p.0))
    }

    /// Whether each candidate's pixel costs are computed side by side before they are
    /// summed: on a mesh, whose sub-passes have a few hundred vertices each, under
    /// k-coherence (a full search's candidates would take too much scratch).
    fn split(&self) -> bool {
        self.shape.is_mesh() && matches!(self.search, Search::KCoherence { .. })
    }
}

/// The GPU form of `job`, or why it has none.
fn form<'a>(job: &PassJob<'a>) -> std::result::Result<Form<'a>, String> {
    let shape = Shape::of(&job.target.neighbourhoods);
    let &Schedule::Interleaved { colouring, seed } = job.schedule else {
        return Err("a sequential visiting order".into());
    };
    let Neighbourhood::Square { metric, template } = job.pass.neighbourhood else {
        return Err("round or isotropic neighbourhoods".into());
    };
    if template.mask() != Mask::Full {
        return Err(format!("a template masked {:?}", template.mask()));
    }
    let choosy = match job.pass.select {
        Select::Argmin => None,
        Select::Choosy { strength } => Some(strength),
        Select::UsePenalty { .. } => return Err("the use penalty".into()),
    };
    let search = match job.search {
        s @ (Search::KCoherence { .. } | Search::Full) => s,
        Search::KdTrees => return Err("kd-tree candidates".into()),
    };
    let parent = match (template.parent(), job.coarse, job.coarse_sample) {
        (Some(kind), Some(coarse), Some(coarse_sample)) => {
            Some((parent_shape(job, kind, shape)?, kind, coarse, coarse_sample))
        }
        _ => None,
    };
    let most_shifts = shape.most_shifts();
    let form = Form { metric, shape, parent, choosy, search, colouring, seed, most_shifts };
    fits_the_shader(job, &form)?;
    Ok(form)
}

/// The templates a parent template of `kind` reads, where they are of `own`'s kind (grid or
/// mesh) and of the side the metric reads.
fn parent_shape<'a>(
    job: &PassJob<'a>,
    kind: ParentTemplate,
    own: Shape,
) -> std::result::Result<Shape<'a>, String> {
    let (shape, metric_template) = match kind {
        ParentTemplate::Narrow => {
            (job.target.parent_neighbourhoods.as_ref().map(Shape::of), job.target.parent_template)
        }
        ParentTemplate::Wide => {
            (job.coarser.map(|c| Shape::of(&c.neighbourhoods)), job.coarser.map_or(0, |c| c.template))
        }
    };
    let Some(shape) = shape.filter(|s| s.is_mesh() == own.is_mesh()) else {
        return Err("a parent template off the level's grid or mesh".into());
    };
    if shape.template() != metric_template || job.target.parents.len() != job.target.vertices {
        return Err("a parent template unlike its level's".into());
    }
    Ok(shape)
}

/// Whether `form` stays within what the shader holds: odd templates within the maps'
/// border, the candidate table, 16-bit coordinates, and the metric's maps on both levels.
fn fits_the_shader(job: &PassJob, form: &Form) -> std::result::Result<(), String> {
    let templates = std::iter::once(form.shape.template()).chain(form.parent.map(|p| p.0.template()));
    if templates.into_iter().any(|t| t > MAX_TEMPLATE || t % 2 == 0) {
        return Err(format!("a template wider than {MAX_TEMPLATE}"));
    }
    let table = Table::of(job, form);
    if table.entries > MAX_ENTRIES {
        return Err("more candidates per vertex than the shader's table holds".into());
    }
    // The gather's loops: each shift and its candidates, then the templates' pixels (prepared).
    if table.entries + table.query > LOOP_BUDGET {
        return Err("templates too large for one invocation's loops".into());
    }
    let samples = std::iter::once(job.sample).chain(form.parent.map(|p| p.3));
    if samples.into_iter().any(|s| s.width >= 1 << 16 || s.height >= 1 << 16 || s.width * s.height >= 1 << 29)
    {
        return Err("a sample level of 2^29 texels or 65536 a side".into());
    }
    let dims = |s: &SampleLevel| match form.metric {
        SquareMetric::Gamma => Some(0),
        _ => map_of(s, form.metric).map(|m| m.dims),
    };
    match (dims(job.sample), form.parent.map(|p| dims(p.3))) {
        (None, _) | (_, Some(None)) => Err("a sample level without the metric's map".into()),
        (Some(own), Some(Some(up))) if own != up => Err("maps of different dimensions on two levels".into()),
        _ => Ok(()),
    }
}

/// What a level's tables were built for.
#[derive(Clone, Copy, Debug, PartialEq)]
struct LevelKey {
    level: usize,
    metric: SquareMetric,
    parent: Option<ParentTemplate>,
    table: Table,
}

/// An invocation's candidate table (open addressing, 2^`bits` slots of two words) and list
/// (`entries` words), sized for the most forward shifts and candidates a vertex may have;
/// on a mesh, the `query` words of what the shader's `prepare` leaves of its templates
/// (blended vectors, or Γ terms).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Table {
    bits: u32,
    entries: usize,
    query: usize,
    /// Under [`Form::split`]: each entry's pixel costs.
    costs: usize,
}

impl Table {
    /// The table `form` needs on `job`'s level: each forward shift, and each of its
    /// candidates under k-coherence, at least [`MIN_ENTRIES`]; the table at most two
    /// thirds full, so that probing stays short.
    fn of(job: &PassJob, form: &Form) -> Table {
        let per_shift = match form.search {
            Search::KCoherence { k } => k.min(job.sample.k) + 1,
            _ => 1,
        };
        let entries = (form.most_shifts * per_shift).max(MIN_ENTRIES);
        let pixels = form.pixels();
        let query = pixels * query_words(job.sample, form) as usize;
        let costs = if form.split() { entries * pixels } else { 0 };
        Table { bits: (entries * 3 / 2).next_power_of_two().trailing_zeros(), entries, query, costs }
    }

    /// Scratch words per invocation (the shader's `P.stride`): table, list, count, best,
    /// prepared template pixels and pixel costs.
    fn stride(&self) -> usize {
        2 * (1 << self.bits) + self.entries + 5 + self.query + self.costs
    }
}

/// A level's buffers: its static tables (sample, parent, colouring), the state and what the
/// passes write.
struct LevelBuffers {
    key: LevelKey,
    params: wgpu::Buffer,
    state: wgpu::Buffer,
    pass_data: wgpu::Buffer,
    counts: wgpu::Buffer,
    outs: wgpu::Buffer,
    readback: wgpu::Buffer,
    /// The sub-passes' parts: (class, offset in the concatenated classes, vertices).
    parts: Vec<(usize, u32, u32)>,
    /// Candidates a score dispatch takes per vertex, and the most such dispatches a pass
    /// may need (slots of the batch starts).
    batch: u32,
    batches: usize,
    bind_group: wgpu::BindGroup,
    /// The tables' word offsets (and the parameters that do not change between passes).
    base: Params,
    vertices: usize,
}

/// Words of scratch per template pixel of a mesh, where `prepare` leaves what each candidate
/// compares with: the blended vector, or under Γ the pixel's three textons and s·s (the
/// `Term` of [`super::metric::GammaMetric`]; its weights stay in the tables). None on a grid.
fn query_words(sample: &SampleLevel, form: &Form) -> u32 {
    match (form.shape.is_mesh(), form.metric) {
        (false, _) => 0,
        (true, SquareMetric::Gamma) => 4,
        (true, metric) => map_of(sample, metric).map_or(0, |m| m.dims as u32),
    }
}

/// The sample level's map for `metric` (none for Γ).
fn map_of(sample: &SampleLevel, metric: SquareMetric) -> Option<&AppearanceMap> {
    match metric {
        SquareMetric::Gamma => None,
        SquareMetric::Appearance => sample.appearance.as_ref(),
        SquareMetric::Colour => sample.colour.as_ref(),
    }
}

/// Appends `words` to `tables`, returning their offset.
fn push(tables: &mut Vec<u32>, words: impl IntoIterator<Item = u32>) -> u32 {
    let at = tables.len() as u32;
    tables.extend(words);
    at
}

/// A sample level's labels, Γ and map for `metric` in `tables`: their offsets and the
/// map's row stride (floats per row / dims).
fn push_sample(tables: &mut Vec<u32>, s: &SampleLevel, metric: SquareMetric) -> [u32; 4] {
    let labels = push(tables, s.labels.iter().map(|&l| u32::from(l)));
    let gamma = match metric {
        SquareMetric::Gamma => push(tables, s.gamma.iter().map(|g| g.to_bits())),
        _ => 0,
    };
    let (map, stride) = match map_of(s, metric) {
        Some(m) => {
            (push(tables, m.values().iter().map(|v| v.to_bits())), (s.width + 2 * AppearanceMap::PAD) as u32)
        }
        None => (0, 0),
    };
    [labels, gamma, map, stride]
}

/// The GPU, the pass pipelines, and the buffers of the level last run.
pub struct GpuSynth {
    gpu: Gpu,
    layout: wgpu::BindGroupLayout,
    /// The shader's entry points: gather, pixel_costs, score, finish, apply_counts.
    pipelines: [wgpu::ComputePipeline; 5],
    level: Option<LevelBuffers>,
    /// Whether the adapter is a software one (lavapipe, llvmpipe; see [`chunk_of`]).
    software: bool,
    /// The last dispatch's stamp (each marks its candidate tables' slots as its own).
    stamp: u32,
}

impl GpuSynth {
    /// Opens the GPU ([`Gpu::headless`]: `WGPU_BACKEND` picks a backend) and builds the
    /// pipelines; one error line where wgpu finds no adapter.
    pub fn new() -> Result<GpuSynth> {
        let gpu = Gpu::headless()?;
        let (layout, pipelines) = gpu.scoped("build the synthesis pipelines", || {
            let device = &gpu.device;
            let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some("synth_pass.wgsl"),
                source: wgpu::ShaderSource::Wgsl(include_str!("../../../shaders/synth_pass.wgsl").into()),
            });
            let layout = bind_group_layout(device);
            let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: Some("synth pass"),
                bind_group_layouts: &[Some(&layout)],
                immediate_size: 0,
            });
            let pipeline = |entry: &str| {
                device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                    label: Some(entry),
                    layout: Some(&pipeline_layout),
                    module: &module,
                    entry_point: Some(entry),
                    compilation_options: Default::default(),
                    cache: None,
                })
            };
            Ok((layout, ["gather", "pixel_costs", "score", "finish", "apply_counts"].map(pipeline)))
        })?;
        let software = gpu.adapter.get_info().device_type == wgpu::DeviceType::Cpu;
        Ok(GpuSynth { gpu, layout, pipelines, level: None, software, stamp: 0 })
    }

    /// The adapter's name and backend.
    pub fn name(&self) -> String {
        self.gpu.name()
    }

    /// Runs `job` on the GPU, leaving in `state` what the CPU pass would: its statistics,
    /// or (inner error) why the pass has no GPU form and must run on the CPU.
    pub(crate) fn run(
        &mut self,
        job: &PassJob,
        state: &mut State,
    ) -> Result<std::result::Result<PassStats, String>> {
        let form = match form(job) {
            Ok(form) => form,
            Err(why) => return Ok(Err(why)),
        };
        let table = Table::of(job, &form);
        let key = LevelKey { level: job.level, metric: form.metric, parent: form.parent.map(|p| p.1), table };
        let level = match self.level.take() {
            Some(level) if level.key == key => level,
            other => {
                // The last level's buffers go before this one's are made.
                drop(other);
                let chunk = chunk_of(self.software, &self.gpu.device.limits(), table);
                let plan = plan_level(job, &form, key, chunk);
                if let Err(why) = fits(&self.gpu.device.limits(), &plan) {
                    return Ok(Err(why));
                }
                self.gpu.scoped("hold the synthesis buffers", || Ok(self.upload(plan)))?
            }
        };
        let stats = self.dispatch(&level, job, &form, state);
        self.level = Some(level);
        stats.map(Ok)
    }

    /// A level's buffers, its tables uploaded.
    fn upload(&self, plan: LevelPlan) -> LevelBuffers {
        use wgpu::util::DeviceExt;
        use wgpu::BufferUsages as U;
        let device = &self.gpu.device;
        let init = |label, words: &[u32], usage| {
            device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents: bytemuck::cast_slice(words),
                usage,
            })
        };
        let empty = |label, bytes: usize, usage| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: (bytes.max(4) as u64).next_multiple_of(4),
                usage,
                mapped_at_creation: false,
            })
        };
        let vertices = plan.vertices;
        let buffers = [
            empty("synth params", plan.parts.len() * PARAMS_STRIDE as usize, U::UNIFORM | U::COPY_DST),
            empty("synth state", vertices * 8, U::STORAGE | U::COPY_DST | U::COPY_SRC),
            init("synth coarse state", &plan.coarse, U::STORAGE),
            init("synth tables", &plan.tables, U::STORAGE),
            empty("synth pass data", (3 * vertices + 1) * 4, U::STORAGE | U::COPY_DST),
            empty("synth counts", plan.texels * 4, U::STORAGE | U::COPY_DST),
            empty("synth outputs", vertices * 16, U::STORAGE | U::COPY_SRC),
            empty("synth candidate lists", plan.scratch_bytes, U::STORAGE),
            init("synth batch starts", &batch_starts(plan.batch, plan.batches), U::UNIFORM),
        ];
        let bind_group = bind_group(device, &self.layout, &buffers);
        let [params, state, _, _, pass_data, counts, outs, _, _] = buffers;
        LevelBuffers {
            key: plan.key,
            params,
            state,
            pass_data,
            counts,
            outs,
            readback: empty("synth readback", vertices * 24, U::MAP_READ | U::COPY_DST),
            parts: plan.parts,
            batch: plan.batch,
            batches: plan.batches,
            bind_group,
            base: plan.base,
            vertices,
        }
    }

    /// One pass: the state up, one dispatch per colour (and the choosy counts moved after
    /// each), the state and the choices back.
    fn dispatch(
        &mut self,
        level: &LevelBuffers,
        job: &PassJob,
        form: &Form,
        state: &mut State,
    ) -> Result<PassStats> {
        let sample = job.sample;
        let (params, batches) = pass_params(level, job, form);
        let mut slots = vec![0u8; level.parts.len() * PARAMS_STRIDE as usize];
        let mut groups = Vec::new();
        for (i, &(_, offset, count)) in level.parts.iter().enumerate() {
            // A dispatch may have at most 65535 workgroups a side.
            let total = count.div_ceil(GROUP);
            let x = total.clamp(1, 65535);
            groups.push((x, total.div_ceil(x)));
            self.stamp = self.stamp.wrapping_add(1).max(1);
            let p =
                Params { class_offset: offset, class_count: count, groups_x: x, stamp: self.stamp, ..params };
            let at = i * PARAMS_STRIDE as usize;
            slots[at..at + std::mem::size_of::<Params>()].copy_from_slice(bytemuck::bytes_of(&p));
        }
        let queue = &self.gpu.queue;
        queue.write_buffer(&level.params, 0, &slots);
        queue.write_buffer(&level.state, 0, bytemuck::cast_slice(&pack_state(state)));
        queue.write_buffer(&level.pass_data, 0, bytemuck::cast_slice(&pass_words(job, form, state)));
        if form.choosy.is_some() {
            let mut counts = vec![0u32; sample.width * sample.height];
            for &[x, y] in &state.uv {
                counts[y as usize * sample.width + x as usize] += 1;
            }
            queue.write_buffer(&level.counts, 0, bytemuck::cast_slice(&counts));
        }
        let encoder = self.encode(level, &groups, batches, (form.choosy.is_some(), form.split()));
        queue.submit([encoder.finish()]);
        let words = read_words(&self.gpu, &level.readback)?;
        self.gpu.check()?;
        Ok(take_choices(level.vertices, &words, form, state))
    }

    /// The pass's commands: each part of a sub-pass gathers (and, `split`, computes every
    /// candidate's pixel costs side by side), scores in `batches` batches and takes its
    /// winners against the counts as the sub-pass found them; then the counts move
    /// (`choosy`); at the end the state and the outputs are copied for reading.
    fn encode(
        &self,
        level: &LevelBuffers,
        groups: &[(u32, u32)],
        batches: usize,
        (choosy, split): (bool, bool),
    ) -> wgpu::CommandEncoder {
        let mut encoder = self.gpu.device.create_command_encoder(&Default::default());
        {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("synth sub-passes"),
                timestamp_writes: None,
            });
            let [gather, pixel_costs, score, finish, apply] = &self.pipelines;
            // One invocation per vertex of the part, or (pixel_costs) per candidate (up to
            // the table's) of each of its vertices.
            let candidates = (level.key.table.entries as u32).div_ceil(GROUP);
            let mut run = |pipeline: &wgpu::ComputePipeline, part: usize, batch: usize| {
                pass.set_pipeline(pipeline);
                let offsets = [(part as u64 * PARAMS_STRIDE) as u32, (batch as u64 * PARAMS_STRIDE) as u32];
                pass.set_bind_group(0, &level.bind_group, &offsets);
                let (x, y) = match pipeline == pixel_costs {
                    true => (candidates, level.parts[part].2),
                    false => groups[part],
                };
                pass.dispatch_workgroups(x, y, 1);
            };
            let mut first = 0;
            for class in level.parts.chunk_by(|a, b| a.0 == b.0) {
                let parts = first..first + class.len();
                first = parts.end;
                for part in parts.clone() {
                    run(gather, part, 0);
                    if split {
                        run(pixel_costs, part, 0);
                    }
                    (0..batches).for_each(|b| run(score, part, b));
                    run(finish, part, 0);
                }
                if choosy {
                    parts.for_each(|part| run(apply, part, 0));
                }
            }
        }
        let state_bytes = level.vertices as u64 * 8;
        encoder.copy_buffer_to_buffer(&level.state, 0, &level.readback, 0, state_bytes);
        encoder.copy_buffer_to_buffer(
            &level.outs,
            0,
            &level.readback,
            state_bytes,
            level.vertices as u64 * 16,
        );
        encoder
    }
}

/// What a level's buffers hold, before they exist.
struct LevelPlan {
    key: LevelKey,
    /// The sample level's (and the parent's) tables, the colouring and the full candidates.
    tables: Vec<u32>,
    /// The coarser level's final state, packed (two words where there is no parent).
    coarse: Vec<u32>,
    /// The tables' word offsets and the parameters that do not change between passes.
    base: Params,
    parts: Vec<(usize, u32, u32)>,
    batch: u32,
    batches: usize,
    vertices: usize,
    texels: usize,
    scratch_bytes: usize,
}

/// The tables, parts and batches of `job`'s level under `form`.
fn plan_level(job: &PassJob, form: &Form, key: LevelKey, chunk: usize) -> LevelPlan {
    let (target, sample) = (job.target, job.sample);
    let mut tables = Vec::new();
    let lists = match form.parent {
        Some(_) => sample.knn_two_level.as_ref().unwrap_or(&sample.knn),
        None => &sample.knn,
    };
    let mut base = Params { off_knn: push(&mut tables, lists.iter().copied()), ..Params::default() };
    [base.off_labels, base.off_gamma, base.off_map, base.map_stride] =
        push_sample(&mut tables, sample, form.metric);
    let mut coarse = vec![0u32; 2];
    if let Some((_, _, coarse_state, coarse_sample)) = form.parent {
        [base.off_p_labels, base.off_p_gamma, base.off_p_map, base.p_map_stride] =
            push_sample(&mut tables, coarse_sample, form.metric);
        base.off_parents = push(&mut tables, target.parents.iter().map(|p| p.vertex));
        (base.p_sw, base.p_sh) = (coarse_sample.width as u32, coarse_sample.height as u32);
        base.p_textons = coarse_sample.textons as u32;
        base.p_fallback = coarse_sample.default_texton().into();
        base.parent = 1;
        coarse = pack_state(coarse_state);
    }
    base.off_classes = push(&mut tables, form.colouring.classes.iter().flatten().copied());
    base.off_full = push(&mut tables, full_candidates(sample, square_margin(target)));
    push_templates(&mut tables, &mut base, form);
    (base.cap_bits, base.entries, base.stride) =
        (key.table.bits, key.table.entries as u32, key.table.stride() as u32);
    (base.sw, base.sh, base.tileable) = (sample.width as u32, sample.height as u32, sample.tileable.into());
    (base.margin, base.list_stride, base.textons) =
        (square_margin(target) as u32, sample.k as u32, sample.textons as u32);
    base.metric = u32::from(form.metric != SquareMetric::Gamma);
    base.dims = map_of(sample, form.metric).map_or(0, |m| m.dims as u32);
    (base.query_words, base.fallback) = (query_words(sample, form), sample.default_texton().into());
    let (batch, batches) = batching(job, form, base.dims as usize);
    let widest = form.colouring.classes.iter().map(Vec::len).max().unwrap_or(0).min(chunk);
    LevelPlan {
        key,
        tables,
        coarse,
        base,
        parts: parts_of(form.colouring, chunk),
        batch,
        batches,
        vertices: target.vertices,
        texels: sample.width * sample.height,
        scratch_bytes: widest * key.table.stride() * 4,
    }
}

/// The level's templates (and the parent's) into `base`: a grid's shape, or a mesh's pixels
/// and forward shifts pushed onto `tables`.
fn push_templates(tables: &mut Vec<u32>, base: &mut Params, form: &Form) {
    let own = form.shape;
    base.side = own.template() as u32;
    match own {
        Shape::Grid(g) => {
            (base.grid_w, base.grid_h, base.wraps) = (g.width as u32, g.height as u32, g.wraps.into())
        }
        Shape::Mesh { template, slots, shift_start, shifts } => {
            base.mesh = 1;
            base.off_slots = push_slots(tables, slots, template);
            base.off_shift_start = push(tables, shift_start.iter().copied());
            let words = shifts.iter().flat_map(|&(u, [x, y])| [u, x.to_bits(), y.to_bits()]);
            base.off_shifts = push(tables, words);
        }
    }
    let Some((parent, ..)) = form.parent else { return };
    base.p_side = parent.template() as u32;
    match parent {
        Shape::Grid(g) => {
            (base.p_grid_w, base.p_grid_h, base.p_wraps) = (g.width as u32, g.height as u32, g.wraps.into())
        }
        Shape::Mesh { template, slots, .. } => base.off_p_slots = push_slots(tables, slots, template),
    }
}

/// A mesh's template pixels (`template`² per vertex) as the shader reads them: each as
/// [`known_parts`] leaves it (no vertex unknown), its three vertices ([`OUTSIDE`] for a part
/// it lacks) and their weights, or `SKIP` where the metric compares nothing.
fn push_slots(tables: &mut Vec<u32>, slots: &[Slot], template: usize) -> u32 {
    const SKIP: u32 = OUTSIDE - 1;
    let at = push(tables, slots.iter().flat_map(|_| [SKIP, 0, 0, 0, 0, 0]));
    for (v, vertex_slots) in slots.chunks_exact(template * template).enumerate() {
        let start = at as usize + v * template * template * SLOT_WORDS;
        for (i, parts, count) in known_parts(vertex_slots, None) {
            let words = &mut tables[start + SLOT_WORDS * i..start + SLOT_WORDS * (i + 1)];
            for (a, &(vertex, weight)) in parts.iter().enumerate() {
                let (vertex, weight) = if a < count { (vertex, weight) } else { (OUTSIDE, 0.0) };
                (words[a], words[3 + a]) = (vertex, weight.to_bits());
            }
        }
    }
    at
}

/// Vertices matched per dispatch with `table`: [`SOFTWARE_CHUNK`] on a `software` adapter,
/// else as many as [`HARDWARE_SCRATCH`] holds; within `limits`, in whole workgroups. Each
/// sub-pass's vertices are independent, so the parts give the same result at any size.
fn chunk_of(software: bool, limits: &wgpu::Limits, table: Table) -> usize {
    let stride = table.stride() as u64 * 4;
    let budget = if software { SOFTWARE_CHUNK as u64 * stride } else { HARDWARE_SCRATCH };
    let bytes = budget.min(limits.max_storage_buffer_binding_size).min(limits.max_buffer_size);
    ((bytes / stride) as usize / GROUP as usize * GROUP as usize).max(GROUP as usize)
}

/// The sub-passes' parts of at most `chunk` vertices: (class, offset in the concatenated
/// classes, vertices).
fn parts_of(colouring: &Colouring, chunk: usize) -> Vec<(usize, u32, u32)> {
    let mut parts = Vec::new();
    let mut offset = 0u32;
    for (c, class) in colouring.classes.iter().enumerate() {
        for part in class.chunks(chunk) {
            parts.push((c, offset, part.len() as u32));
            offset += part.len() as u32;
        }
    }
    parts
}

/// Candidates a score dispatch takes per vertex (within [`LOOP_BUDGET`] loop iterations:
/// each template pixel, and each of its map's values), and the most dispatches a pass may
/// need.
fn batching(job: &PassJob, form: &Form, dims: usize) -> (u32, usize) {
    let per_pixel = if form.metric == SquareMetric::Gamma || form.split() { 1 } else { 1 + dims };
    let batch = (LOOP_BUDGET / (form.pixels() * per_pixel + 16)).max(1) as u32;
    let most =
        full_candidates(job.sample, square_margin(job.target)).len().max(Table::of(job, form).entries) as u32;
    (batch, most.div_ceil(batch) as usize)
}

/// Whether `plan`'s buffers fit the adapter's `limits`; why not, if not.
fn fits(limits: &wgpu::Limits, plan: &LevelPlan) -> std::result::Result<(), String> {
    let storage = [
        plan.tables.len() * 4,
        plan.vertices * 16,
        (3 * plan.vertices + 1) * 4,
        plan.texels * 4,
        plan.coarse.len() * 4,
        plan.scratch_bytes,
    ];
    let largest = storage.into_iter().max().unwrap_or(0) as u64;
    let uniform = plan.parts.len().max(plan.batches) as u64 * PARAMS_STRIDE;
    let readback = plan.vertices as u64 * 24;
    if largest > limits.max_storage_buffer_binding_size.min(limits.max_buffer_size)
        || uniform.max(readback) > limits.max_buffer_size
    {
        return Err(format!("{} bytes exceed the adapter's buffers", largest.max(uniform).max(readback)));
    }
    Ok(())
}

/// Each score dispatch's first candidate, one uniform slot each.
fn batch_starts(batch: u32, batches: usize) -> Vec<u32> {
    (0..batches as u32)
        .flat_map(|b| {
            std::iter::once(b * batch).chain(std::iter::repeat_n(0, PARAMS_STRIDE as usize / 4 - 1))
        })
        .collect()
}

/// How far inside the sample's edges the square template's candidates stay.
fn square_margin(target: &TargetLevel) -> usize {
    target.candidate_margin(target.template / 2)
}

/// The parameters every sub-pass of the pass shares, and how many score dispatches it needs.
fn pass_params(level: &LevelBuffers, job: &PassJob, form: &Form) -> (Params, usize) {
    let sample = job.sample;
    let margin = square_margin(job.target);
    let mut params = level.base;
    params.off_draws = 0;
    params.off_table = level.vertices as u32;
    params.off_move = 2 * level.vertices as u32 + 1;
    params.choosy = form.choosy.is_some().into();
    params.fresh = 1.0 + job.pass.coherence_bias;
    (params.full, params.list_k) = match form.search {
        Search::KCoherence { k } => (0, k.min(sample.k) as u32),
        _ => (1, 0),
    };
    params.full_count = match form.search {
        Search::Full => full_candidates(sample, margin).len() as u32,
        _ => 0,
    };
    params.batch = level.batch;
    params.split = form.split().into();
    let most = match form.search {
        Search::Full => params.full_count.max(1),
        _ => form.most_shifts as u32 * params.list_k.max(1),
    };
    (params, (most.div_ceil(level.batch) as usize).min(level.batches))
}

/// The pass's own data: each vertex's draw (where it has no candidate), then the choosy
/// factor by use count, then each vertex's factor on moving ([`PassJob::move_costs`]). A
/// vertex's own coordinate is the forward shift of its own pixel, and stays as it is until
/// the vertex's sub-pass: where it is a candidate texel, the vertex has a candidate and
/// draws nothing. Only the others draw (as the CPU would: seeded
/// by the pass and the vertex), or all of them where a full search has no candidate at all.
fn pass_words(job: &PassJob, form: &Form, state: &State) -> Vec<u32> {
    let (sample, margin) = (job.sample, square_margin(job.target));
    let no_full = form.search == Search::Full && full_candidates(sample, margin).is_empty();
    let draws: Vec<u32> = state
        .uv
        .par_iter()
        .enumerate()
        .map(|(v, &[x, y])| {
            if !no_full && sample.is_candidate(x.into(), y.into(), margin) {
                return 0;
            }
            let mut rng = ChaCha8Rng::seed_from_u64(form.seed ^ (v as u64).wrapping_mul(VERTEX_SEED));
            let [x, y] = super::start::random_texel(sample, margin, &mut rng);
            y as u32 * sample.width as u32 + x as u32
        })
        .collect();
    let vertices = state.uv.len();
    let table = match form.choosy {
        Some(strength) => choosy_factors(vertices, sample, margin, strength),
        None => vec![1.0; vertices + 1],
    };
    let moves = job.move_costs.map_or_else(|| vec![1.0; vertices], <[f32]>::to_vec);
    draws.into_iter().chain(table.iter().chain(&moves).map(|f| f.to_bits())).collect()
}

/// Puts the pass's read-back `words` (the packed state, then four outputs per vertex) into
/// `state`; its statistics, summed in the CPU's order: sub-pass by sub-pass, vertex by
/// vertex.
fn take_choices(vertices: usize, words: &[u32], form: &Form, state: &mut State) -> PassStats {
    let (packed, outs) = words.split_at(2 * vertices);
    for (v, w) in packed.chunks_exact(2).enumerate() {
        state.uv[v] = [(w[0] & 0xffff) as i32, (w[0] >> 16) as i32];
        state.labels[v] = w[1] as u16;
    }
    let (mut figure, mut compared) = (0.0f64, 0usize);
    for &v in form.colouring.classes.iter().flatten() {
        figure += f32::from_bits(outs[4 * v as usize]) as f64;
        compared += outs[4 * v as usize + 1] as usize;
    }
    let n = vertices.max(1) as f64;
    PassStats { mean_best: figure / n, mean_candidates: compared as f64 / n }
}

/// The bind group of `buffers`, in `synth_pass.wgsl`'s binding order (the parameters and
/// the batch starts bound one slot wide, at dynamic offsets).
fn bind_group(
    device: &wgpu::Device,
    layout: &wgpu::BindGroupLayout,
    buffers: &[wgpu::Buffer; 9],
) -> wgpu::BindGroup {
    let slot = |binding: u32, size: u64| wgpu::BindGroupEntry {
        binding,
        resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
            buffer: &buffers[binding as usize],
            offset: 0,
            size: wgpu::BufferSize::new(size),
        }),
    };
    let mut entries: Vec<wgpu::BindGroupEntry> = (1..8)
        .map(|binding| wgpu::BindGroupEntry {
            binding,
            resource: buffers[binding as usize].as_entire_binding(),
        })
        .collect();
    entries.insert(0, slot(0, std::mem::size_of::<Params>() as u64));
    entries.push(slot(8, 16));
    device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("synth pass"),
        layout,
        entries: &entries,
    })
}

/// Per vertex: x | y << 16, then the label.
fn pack_state(state: &State) -> Vec<u32> {
    state
        .uv
        .iter()
        .zip(&state.labels)
        .flat_map(|(&[x, y], &l)| [x as u32 | (y as u32) << 16, u32::from(l)])
        .collect()
}

/// The choosy factor by use count m (the vertex's own use left out), 0 ..= `vertices`:
/// [`super::engine::Usage`]'s fair-share factor, computed the same way.
fn choosy_factors(vertices: usize, sample: &SampleLevel, radius: usize, strength: f32) -> Vec<f32> {
    let candidates = full_candidates(sample, radius).len().max(1);
    let fair = (vertices as f32 / candidates as f32).max(1.0);
    (0..=vertices as u32)
        .map(|m| {
            let excess = (m as f32 / fair - 1.0).max(0.0);
            1.0 + strength * excess * excess
        })
        .collect()
}

/// Waits for `buffer`'s copies and reads it as words.
fn read_words(gpu: &Gpu, buffer: &wgpu::Buffer) -> Result<Vec<u32>> {
    let failed =
        |what: String| Error::gpu(format!("reading the synthesis back from {} failed: {what}", gpu.name()));
    let (tx, rx) = std::sync::mpsc::channel();
    buffer.map_async(wgpu::MapMode::Read, .., move |r| {
        let _ = tx.send(r);
    });
    gpu.device.poll(wgpu::PollType::wait_indefinitely()).map_err(|e| failed(e.to_string()))?;
    rx.recv().map_err(|e| failed(e.to_string()))?.map_err(|e| failed(e.to_string()))?;
    let words = {
        let data = buffer.get_mapped_range(..).map_err(|e| failed(e.to_string()))?;
        bytemuck::cast_slice::<u8, u32>(&data).to_vec()
    };
    buffer.unmap();
    Ok(words)
}

/// `synth_pass.wgsl`'s bindings: the parameters (one slot per sub-pass, a dynamic offset),
/// the state, the coarser state, the tables, the pass data, the counts and the outputs.
fn bind_group_layout(device: &wgpu::Device) -> wgpu::BindGroupLayout {
    let storage = |binding, read_only| wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Storage { read_only },
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    };
    let uniform = |binding, size: usize| wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Uniform,
            has_dynamic_offset: true,
            min_binding_size: wgpu::BufferSize::new(size as u64),
        },
        count: None,
    };
    device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("synth pass"),
        entries: &[
            uniform(0, std::mem::size_of::<Params>()),
            storage(1, false),
            storage(2, true),
            storage(3, true),
            storage(4, true),
            storage(5, false),
            storage(6, false),
            storage(7, false),
            uniform(8, 16),
        ],
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::engine::tests::periodic_sample;
    use crate::synth::engine::Usage;

    /// The shader indexes the appearance maps with its own copy of their border.
    #[test]
    fn the_shaders_map_border_is_the_maps() {
        let source = include_str!("../../../shaders/synth_pass.wgsl");
        assert!(source.contains(&format!("const PAD: i32 = {};", AppearanceMap::PAD)));
    }

    /// The table the shader reads is the CPU's fair-share factor for every use count.
    #[test]
    fn the_choosy_table_is_the_cpus_factor() {
        let mut sample = periodic_sample(4);
        sample.tileable = false;
        let (radius, vertices, strength) = (2usize, 700usize, 0.3f32);
        let table = choosy_factors(vertices, &sample, radius, strength);
        // Texel 0 used m times by other vertices, the vertex itself elsewhere.
        for m in [0usize, 1, 2, 5, 9, 40, 300, 700] {
            let uv: Vec<[i32; 2]> = (0..vertices).map(|v| if v < m { [0, 0] } else { [5, 5] }).collect();
            let state = State::new(vec![0; vertices], uv);
            let usage = Usage::new(&sample, &state, radius, Select::Choosy { strength });
            assert_eq!(usage.factor(0, [5, 5], 0).to_bits(), table[m].to_bits(), "m = {m}");
            if m > 0 {
                assert_eq!(usage.factor(0, [0, 0], 0).to_bits(), table[m - 1].to_bits(), "own use, m = {m}");
            }
        }
    }

    /// A plane's smallest table keeps the sizes the shader had before tables grew (1,024
    /// slots, 640 entries); dispatches are 4,096 vertices on a software adapter and fill
    /// `HARDWARE_SCRATCH` on a hardware one, in whole workgroups, within the binding limit.
    #[test]
    fn dispatches_fit_their_scratch_in_whole_workgroups() {
        let plane = Table { bits: 10, entries: MIN_ENTRIES, query: 0, costs: 0 };
        assert_eq!(plane.stride(), 2693);
        let mesh = Table { bits: 11, entries: 1200, query: 612, costs: 1200 * 34 };
        let limits = wgpu::Limits { max_storage_buffer_binding_size: 4 << 30, ..wgpu::Limits::default() };
        let limits = wgpu::Limits { max_buffer_size: 4 << 30, ..limits };
        for table in [plane, mesh] {
            let bytes = table.stride() as u64 * 4;
            assert_eq!(chunk_of(true, &limits, table), SOFTWARE_CHUNK);
            let hardware = chunk_of(false, &limits, table);
            assert_eq!(hardware % GROUP as usize, 0);
            assert!(hardware as u64 * bytes <= HARDWARE_SCRATCH, "{table:?}");
            assert!((hardware + GROUP as usize) as u64 * bytes > HARDWARE_SCRATCH, "{table:?}");
            // A device whose bindings hold 64 MiB gets smaller dispatches, software or not.
            let small = wgpu::Limits { max_storage_buffer_binding_size: 64 << 20, ..limits.clone() };
            for software in [true, false] {
                assert!(chunk_of(software, &small, table) as u64 * bytes <= 64 << 20, "{table:?}");
            }
        }
        assert_eq!(chunk_of(false, &limits, plane), 49_792);
    }
}
