//! Memory estimates before work: every stage of an analysis predicts its peak from the
//! sizes it will touch, and an analysis that would not fit is refused with one line before
//! anything is decoded or allocated.
//!
//! The budget is 80% of `MemAvailable` (/proc/meminfo), or what the environment variable
//! `BTFSYNTH_MEMORY` says (`6G`, `512M`, `1500000000`; `unlimited` turns the check off).
//! Estimates count the large arrays of each stage (images, bases, filter responses, the
//! feature matrix k-means clusters, appearance vectors) and leave out what is small beside
//! them; measured peaks are within about 20% of them (see `benches/big_btf.sh`).

use super::params::AnalysisParams;
use super::pyramid::level_sizes;
use crate::{Error, Remedy, Result};
use std::path::Path;

/// One stage's predicted peak.
#[derive(Clone, Debug, PartialEq)]
pub struct Stage {
    /// What the stage does, for messages (e.g. "decoding the images").
    pub name: String,
    /// Predicted peak of the stage in bytes.
    pub bytes: u64,
}

pub use crate::btf::source::{gib, memory_budget as budget, MEMORY_ENV};

/// The stage with the largest peak.
pub fn peak(stages: &[Stage]) -> Option<&Stage> {
    stages.iter().max_by_key(|s| s.bytes)
}

/// Fails, naming `path`, the stage and the estimate, when the largest stage of `stages`
/// would not fit in the budget; `what` says what was to be done ("analysing 400x400
/// texels × 22801 images from the file's factors"), `remedy` what to do instead.
pub fn check(path: &Path, what: &str, stages: &[Stage], remedy: Remedy) -> Result<()> {
    let Some(stage) = peak(stages) else { return Ok(()) };
    check_against(path, what, stage, remedy, budget()?)
}

fn check_against(
    path: &Path,
    what: &str,
    stage: &Stage,
    remedy: Remedy,
    budget: Option<(u64, String)>,
) -> Result<()> {
    match budget {
        Some((limit, source)) if stage.bytes > limit => Err(Error::too_large(
            format!(
                "{}: {what} would need about {} at its peak ({}), more than the {} budget ({source})",
                path.display(),
                gib(stage.bytes),
                stage.name,
                gib(limit)
            ),
            remedy,
        )),
        _ => Ok(()),
    }
}

/// Whether `bytes` more may be allocated now within the budget: 80% of the memory available
/// at this moment, or the `BTFSYNTH_MEMORY` budget less what this process holds (its
/// resident set); always where the check is off or the budget unknown. For choices that
/// change how fast, never what, an analysis computes.
pub fn fits_now(bytes: u64) -> bool {
    match budget() {
        Ok(Some((limit, _))) if std::env::var_os(MEMORY_ENV).is_some() => {
            bytes.saturating_add(resident().unwrap_or(0)) <= limit
        }
        Ok(Some((limit, _))) => bytes <= limit,
        _ => true,
    }
}

/// This process' resident set in bytes (Linux), if known.
fn resident() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = text.lines().find(|l| l.starts_with("VmRSS:"))?;
    Some(line.split_whitespace().nth(1)?.parse::<u64>().ok()? * 1024)
}

/// Levels whose texton stages need at most this together run side by side freely; beyond
/// it, only where side by side they need no more than the largest level alone (see
/// [`levels_side_by_side`]), so that running them together never raises a large
/// analysis' peak.
pub const BESIDE_FREELY: u64 = 256 << 20;

/// What the texton stages of levels of `sizes` allocate at once beyond the images they
/// read, with a basis of at most `rank` components, when the coarser levels run one after
/// the other beside the finest once it is filtered (its clustering, appearance vectors
/// and Γ): the memory that running them side by side needs.
pub fn levels_side_by_side(sizes: &[(usize, usize)], rank: usize, params: &AnalysisParams) -> u64 {
    let Some((&finest, coarser)) = sizes.split_first() else { return 0 };
    let finest = level_phases(finest, rank as u64, params);
    let beside = coarser.iter().map(|&size| level_phases(size, rank as u64, params).own()).max().unwrap_or(0);
    let after_filtering = finest.clustering.max(finest.appearance);
    (finest.components + finest.filtering).max(finest.components + after_filtering + beside)
}

/// What the texton stages of levels of `sizes` allocate at most beyond the images they
/// read when they run one after the other: the largest level's own.
pub fn levels_in_turn(sizes: &[(usize, usize)], rank: usize, params: &AnalysisParams) -> u64 {
    sizes.iter().map(|&size| level_phases(size, rank as u64, params).own()).max().unwrap_or(0)
}

/// Bytes of one level's texton stage in its three phases (see [`super::textons`]), each
/// beside the basis' `components`.
struct LevelPhases {
    components: u64,
    /// The features, the kernels' and the planes' spectra, the responses waiting.
    filtering: u64,
    /// The features and what k-means copies or reduces them to.
    clustering: u64,
    /// The appearance vectors' work arrays, made once the features are dropped.
    appearance: u64,
}

impl LevelPhases {
    fn own(&self) -> u64 {
        self.components + self.filtering.max(self.clustering).max(self.appearance)
    }
}

fn level_phases((width, height): (usize, usize), rank: u64, params: &AnalysisParams) -> LevelPhases {
    let texels = (width * height) as u64;
    let filters = params.filters.len() as u64;
    let threads = rayon::current_num_threads() as u64;
    let blocks = rank + 1;
    let features = texels * blocks * 3 * filters * 4;
    // The planes' responses are made a few filters at a time (see
    // `features::texton_features`): with more planes than filters the kernels' spectra are
    // held and a few planes transformed at a time, else every plane's spectrum is held and
    // a run of kernels' made at a time; each thread also holds a product spectrum.
    let planes = 3 * blocks;
    let (group, spectra) = match planes > filters {
        true => (threads.min(planes), filters + threads.min(planes)),
        false => (planes, planes + (super::features::WAITING_VALUES as u64 / (planes * texels)).max(1)),
    };
    let spectrum = super::convolve::spectrum_bytes(&params.filters, width, height);
    let waiting = (super::features::WAITING_VALUES as u64).max(group * texels).min(group * filters * texels);
    let filtering = features + (spectra + threads) * spectrum + waiting * 4;
    // A reduced level also holds its sketch, its orthonormal basis and its coordinates; a
    // level of more pixels than k-means fits on copies the fitted ones.
    let reduced = features / 4 > super::reduce::REDUCE_ABOVE as u64;
    let fit_points = super::kmeans::DEFAULT_FIT_POINTS as u64;
    let copied = match reduced {
        true => 3 * texels * super::reduce::PROJECTED_DIMS as u64 * 4,
        false if texels > fit_points => fit_points * blocks * 3 * filters * 4,
        false => 0,
    };
    // Made after the features are dropped: the pixels' colours and their centred copy, then
    // the neighbourhoods' sketch (dims + 10 columns, in f32 and as f64 while
    // orthonormalised) and the vectors; the neighbourhoods themselves are streamed.
    let dims = params.appearance_dims as u64;
    let appearance = texels * (blocks * 3 * 4 * 2 + (dims + 10) * (4 + 8 + 4) + dims * 4);
    LevelPhases { components: blocks * texels * 3 * 4, filtering, clustering: features + copied, appearance }
}

/// Values of one level's texton stage: the images (or the low-rank rows) it reads, `held`
/// besides, and its own arrays.
fn level_stage(size: (usize, usize), rank: u64, params: &AnalysisParams, held: u64, images: u64) -> u64 {
    held + images + level_phases(size, rank, params).own()
}

/// What the selection allocates to filter its components one after the other, beyond
/// them: a component's responses (and one colour's while they are made), and the kernel
/// spectra it caches for the rest of the selection.
fn selection_filtering((width, height): (usize, usize), params: &AnalysisParams) -> u64 {
    let filters = params.filters.len() as u64;
    let responses = 3 * filters * (width * height) as u64 * 4 * 2;
    responses + filters * super::convolve::spectrum_bytes(&params.filters, width, height)
}

/// Stages of [`super::pipeline::analyze`] on `images` decoded images of `width × height`.
pub fn decoded_stages(images: usize, (width, height): (usize, usize), params: &AnalysisParams) -> Vec<Stage> {
    let n = images as u64;
    let stack = n * (width * height * 3) as u64 * 2;
    let mut stages = vec![Stage { name: "decoding the images".into(), bytes: stack }];
    let d = (width * height * 3) as u64;
    if images > params.selected {
        // The selection's basis streams the images as f32 rows, a block at a time (all of
        // them up to the exact limit): the block, its centred copy and two sketches of
        // 74 columns (in f32, and in f64 while orthonormalised).
        let exact = super::basis::BasisOptions::default().exact_limit as u64;
        let block = if n <= exact { n * d } else { (d * 256).max(1 << 22) };
        let sketch = n * 74 * (4 + 8 + 4);
        let basis = 64.min(n) * d * 4 + sketch;
        stages.push(Stage {
            name: "selecting representative images".into(),
            bytes: stack + (2 * block * 4 + sketch).max(basis + selection_filtering((width, height), params)),
        });
    }
    let selected = n.min(params.selected as u64);
    // The centred images span at most one dimension fewer than there are.
    let rank = (params.basis_rank as u64).min(selected.saturating_sub(1));
    for (l, &(w, h)) in level_sizes(width, height, params.levels).iter().enumerate() {
        let texels = (w * h) as u64;
        // The selected images as f32 rows and their centred copy.
        let level_images = 2 * selected * texels * 3 * 4;
        stages.push(Stage {
            name: format!("textons of level {l} ({w}x{h})"),
            bytes: level_stage((w, h), rank, params, stack, level_images),
        });
    }
    stages
}

/// Stages of [`super::pipeline::analyze_low_rank`]: `images` images of `width × height`
/// held as `rank` rows, with `held` bytes besides (the sample's factors); `streamed`
/// gives the sketch columns and batch of a streamed basis.
pub fn low_rank_stages(
    images: usize,
    rank: usize,
    (width, height): (usize, usize),
    params: &AnalysisParams,
    held: u64,
    streamed: Option<super::basis::StreamOptions>,
) -> Vec<Stage> {
    let (n, q) = (images as u64, rank as u64);
    let d = (width * height * 3) as u64;
    let rows = q * d * 4 + n * q * 4;
    let mut stages = vec![Stage { name: "reading the factors".into(), bytes: held }];
    if let Some(s) = streamed {
        let l = s.rank.min(images) as u64;
        // The sketch in f32, its orthonormalisation in f64, one batch as f32 and f16.
        let sketch = d * l * (4 + 8) + s.batch as u64 * d * (4 + 2) * 2;
        stages.push(Stage { name: "streaming a basis of the images".into(), bytes: held + sketch });
    }
    if images > params.selected {
        let components = 64.min(q) * d * 4 * 2;
        stages.push(Stage {
            name: "selecting representative images".into(),
            bytes: held + rows + components + selection_filtering((width, height), params),
        });
    }
    let selected = images.min(params.selected);
    let rank_kept = params.basis_rank.min(selected.saturating_sub(1)).min(rank) as u64;
    for (l, &(w, h)) in level_sizes(width, height, params.levels).iter().enumerate() {
        let texels = (w * h) as u64;
        let level_rows = q * texels * 3 * 4;
        stages.push(Stage {
            name: format!("textons of level {l} ({w}x{h})"),
            bytes: level_stage((w, h), rank_kept, params, held + rows, level_rows),
        });
    }
    stages
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::btf::source::parse_size_env;

    #[test]
    fn budgets_parse_with_units_or_turn_off() {
        let parse_budget = |text| parse_size_env(MEMORY_ENV, text);
        assert_eq!(parse_budget("6G").unwrap().unwrap().0, 6 << 30);
        assert_eq!(parse_budget("512M").unwrap().unwrap().0, 512 << 20);
        assert_eq!(parse_budget("1.5GiB").unwrap().unwrap().0, 3 << 29);
        assert_eq!(parse_budget("1000").unwrap().unwrap().0, 1000);
        assert!(parse_budget("unlimited").unwrap().is_none());
        for bad in ["", "-1G", "6X", "G"] {
            assert!(parse_budget(bad).is_err(), "{bad}");
        }
        // A tiny budget reads as what it is, not as 0.0 GiB.
        let sizes = [1, 100, 5000, 3 << 20, 3 << 30].map(gib);
        assert_eq!(sizes, ["1 byte", "100 bytes", "5 KiB", "3 MiB", "3.0 GiB"]);
    }

    #[test]
    fn an_absurd_declared_size_is_refused_without_allocating() {
        // 100,000² texels × 22,801 images: the estimate alone says no, long before any
        // array exists (a real attempt would need exabytes).
        let params = AnalysisParams::default();
        let stages = decoded_stages(22_801, (100_000, 100_000), &params);
        let stage = peak(&stages).unwrap();
        assert!(stage.bytes > 1 << 50, "{stage:?}");
        let budget = Some((6u64 << 30, "BTFSYNTH_MEMORY=6G".to_string()));
        let e = check_against(Path::new("huge.btf"), "analysing it", stage, Remedy::Crop, budget)
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("huge.btf: analysing it would need about"), "{e}");
        assert!(e.contains("more than the 6.0 GiB budget (BTFSYNTH_MEMORY=6G)"), "{e}");
        assert!(!e.contains('\n'), "{e}");
        // The factor path of the same size is smaller but still refused.
        let stages = low_rank_stages(22_801, 97, (100_000, 100_000), &params, 1 << 30, None);
        let s = peak(&stages).unwrap();
        assert!(s.bytes > 1 << 40 && s.name.starts_with("textons of level 0"), "{s:?}");
    }

    #[test]
    fn the_factor_path_of_a_ubo2014_material_fits_where_decoding_does_not() {
        let params = AnalysisParams::default();
        let decoded = peak(&decoded_stages(22_801, (400, 400), &params)).unwrap().bytes;
        let factors = peak(&low_rank_stages(22_801, 97, (400, 400), &params, 64 << 20, None)).unwrap().bytes;
        // The decoded f16 stack alone is 20.4 GiB.
        assert!(decoded > 20 << 30, "{}", gib(decoded));
        assert!(factors < 6 << 30, "{}", gib(factors));
    }

    #[test]
    fn the_selection_streams_the_stack_instead_of_copying_it_twice() {
        let params = AnalysisParams::default();
        // The UBO2014 case of issue #21, killed by the kernel at 24.3 GB when the selection
        // held the 192² crop of 22,801 images as f32 rows twice besides the f16 stack; the
        // rows are now streamed, so the stack (4.7 GiB) and a few sketches remain.
        let stages = decoded_stages(22_801, (192, 192), &params);
        let gib_of = |s: &Stage| s.bytes as f64 / (1u64 << 30) as f64;
        let selection = stages.iter().find(|s| s.name == "selecting representative images").unwrap();
        assert!((4.7..5.2).contains(&gib_of(selection)), "{selection:?}");
        let stage = peak(&stages).unwrap();
        assert!(gib_of(stage) < 6.0, "{stage:?}");
        let few = decoded_stages(256, (64, 64), &params);
        assert!(few.iter().all(|s| s.name != "selecting representative images"), "{few:?}");
    }

    #[test]
    fn a_photographs_levels_are_estimated_with_its_one_image() {
        // One image has no principal components: its features are one block of 3 × 48
        // columns (151 MB at 512²), not two, which also made the estimate count a reduction
        // that never runs (1.4 GiB). Measured (docs/big-btf.md): 216 MiB with the levels in
        // turn, 261 MiB side by side, the process' own pages included.
        let params = AnalysisParams::default();
        let stage = peak(&decoded_stages(1, (512, 512), &params)).cloned().unwrap();
        let mib = stage.bytes >> 20;
        assert!((170..260).contains(&mib) && stage.name.starts_with("textons of level 0"), "{stage:?}");
        let sizes = level_sizes(512, 512, 3);
        let (beside, in_turn) = (levels_side_by_side(&sizes, 0, &params), levels_in_turn(&sizes, 0, &params));
        // Side by side, the coarser levels run beside the finest's clustering, not its
        // filtering: they add less than the finest needs alone.
        assert!(in_turn < beside && beside < 2 * in_turn, "{} beside, {} in turn", gib(beside), gib(in_turn));
        // A 192² crop of a UBO2014 material (rank 32): its finest level alone sets the
        // peak, which side by side would raise, so its levels run in turn.
        let sizes = level_sizes(192, 192, 3);
        let (beside, in_turn) =
            (levels_side_by_side(&sizes, 32, &params), levels_in_turn(&sizes, 32, &params));
        assert!(beside > in_turn.max(BESIDE_FREELY), "{} beside, {} in turn", gib(beside), gib(in_turn));
    }

    #[test]
    fn an_analysis_beyond_the_budget_is_refused_naming_the_stack() {
        let (path, advice) = (Path::new("big.btf"), Remedy::Crop);
        let budget = || Some((8u64 << 30, "80% of the 10.0 GiB available".to_string()));
        let stage = |bytes: u64| Stage { name: "textons of level 0 (400x400)".into(), bytes };
        let e = check_against(path, "analysing it", &stage(20 << 30), advice.clone(), budget()).unwrap_err();
        assert!(matches!(e, Error::TooLarge { remedy: Remedy::Crop, .. }), "{e:?}");
        let e = e.to_string();
        assert!(e.contains("big.btf") && e.contains("20.0 GiB") && e.ends_with("(a crop)"), "{e}");
        assert!(check_against(path, "analysing it", &stage(4 << 30), advice.clone(), budget()).is_ok());
        let no_figure = check_against(path, "analysing it", &stage(u64::MAX), advice, None);
        assert!(no_figure.is_ok(), "no figure from the platform: no refusal");
    }
}
