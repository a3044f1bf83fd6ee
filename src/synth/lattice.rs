//! Whether a sample is a lattice of one element (tiles, bricks, a weave) and, if so, its two
//! periods: the near-regular textures of Liu, Lin and Hays (2004), whose elements stay whole
//! only where copies are placed in phase with one another.

use super::metric::Metric;
use super::sample::SampleLevel;

/// Two independent periods of a sample, in texels of the level they were found on scaled to
/// the finest level: the sample repeats (nearly) when shifted by either.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lattice {
    /// The periods, `[x, y]` each, the more pronounced first.
    pub periods: [[f32; 2]; 2],
}

impl Lattice {
    /// The periods in texels of a level `factor` times coarser than the finest.
    pub fn scaled(&self, factor: f32) -> Lattice {
        Lattice { periods: self.periods.map(|p| p.map(|v| v / factor)) }
    }

    /// The same lattice spanned by its two shortest independent periods (Gauss' reduction),
    /// so that whole periods along each reach everywhere in few steps and the cell they span
    /// is the element's own.
    pub fn reduced(&self) -> Lattice {
        let length2 = |p: [f32; 2]| p[0] * p[0] + p[1] * p[1];
        let [mut a, mut b] = self.periods;
        for _ in 0..16 {
            if length2(a) > length2(b) {
                std::mem::swap(&mut a, &mut b);
            }
            let m = ((a[0] * b[0] + a[1] * b[1]) / length2(a).max(f32::MIN_POSITIVE)).round();
            if m == 0.0 {
                break;
            }
            b = [b[0] - m * a[0], b[1] - m * a[1]];
        }
        Lattice { periods: [a, b] }
    }

    /// The shift by `n` periods of each, rounded to whole texels.
    pub fn shift(&self, n: [i64; 2]) -> [i64; 2] {
        let [a, b] = self.periods;
        [0, 1].map(|axis| (n[0] as f32 * a[axis] + n[1] as f32 * b[axis]).round() as i64)
    }
}

/// The largest side of the level the lattice is looked for on: periods of at least
/// [`SHORTEST_PERIOD`] texels there, the direct autocorrelation cheap (80² texels × 41 × 81
/// shifts, about 20 M products).
const SEARCH_SIDE: usize = 80;
/// Shorter shifts are the element's own extent, not a period.
const SHORTEST_PERIOD: f32 = 3.0;
/// How far a lattice's periods and their sum or difference must each stand above the ring
/// around them (a quarter of the period away, at least 2 texels) in the structure's
/// autocorrelation, on the scale where 1 is the shift by nothing. A ridge (grain, stripes:
/// one direction only) stands no higher than its own ring, and two chance peaks of an
/// organic material have no third at their sum. On the 23 photographs of
/// ../shared/data/textures (64 texels a side at most): a tiled floor 0.29, a burlap weave
/// 0.16, the other 21 at most 0.043 (a brick wall seen at an angle), or no pair at all.
/// Through block means of the finest level (a surface's one level): the floor 0.21, the
/// weave 0.21, the other 21 at most 0.06.
const PROMINENCE: f32 = 0.2;
/// Periods less than this far from parallel (the sine of their angle) are one direction.
const INDEPENDENT: f32 = 0.5;

/// The sample's lattice, if it has one, looked for in its structure: how unlike each texel
/// is to its right and lower neighbours under `metric_of` its level. Structure rather than
/// the texels themselves, since a tiled floor's tiles differ in tone but not in where their
/// joints are. It is taken on the finest of `levels` at most 80 texels a side; where there
/// is none (a surface's single level of a large sample), on the coarsest level, averaged over
/// square blocks down to at most 80 a side: a joint's line survives the averaging, and the
/// periods are the same whatever the level. `None` also where `metric_of` gives no metric.
pub fn detect<'a, M: Metric>(
    levels: &'a [SampleLevel],
    metric_of: impl Fn(&'a SampleLevel) -> Option<M>,
) -> Option<Lattice> {
    let (level, block) = match levels.iter().find(|l| l.width.max(l.height) <= SEARCH_SIDE) {
        Some(level) => (level, 1),
        None => {
            let level = levels.last()?;
            (level, level.width.max(level.height).div_ceil(SEARCH_SIDE))
        }
    };
    let factor = levels.first()?.width as f32 / level.width as f32 * block as f32;
    let fine = structure(level.width, level.height, &metric_of(level)?);
    let (image, width, height) = block_means(&fine, level.width, level.height, block);
    let periods = periods_of(&image, width, height)?;
    Some(Lattice { periods: periods.map(|p| p.map(|v| v * factor)) }.reduced())
}

/// The two periods of a `width × height` structure image, if it has a lattice.
fn periods_of(image: &[f32], width: usize, height: usize) -> Option<[[f32; 2]; 2]> {
    let correlation = Autocorrelation::of(image, width, height);
    let (score, periods) = best_pair(&correlation.peaks())?;
    (score >= PROMINENCE).then(|| periods.map(|p| correlation.refined(p)))
}

/// An image averaged over `block × block` squares (the last row and column of blocks over
/// what is left), with its new width and height.
fn block_means(image: &[f32], width: usize, height: usize, block: usize) -> (Vec<f32>, usize, usize) {
    if block <= 1 {
        return (image.to_vec(), width, height);
    }
    let (w, h) = (width.div_ceil(block), height.div_ceil(block));
    let mut sum = vec![0.0f32; w * h];
    let mut count = vec![0u32; w * h];
    for (p, &v) in image.iter().enumerate() {
        let b = (p / width / block) * w + p % width / block;
        sum[b] += v;
        count[b] += 1;
    }
    (sum.iter().zip(&count).map(|(s, &n)| s / n.max(1) as f32).collect(), w, h)
}

/// Peaks looked at as periods: a lattice's two periods and their sum or difference are
/// among its most prominent.
const PAIRED_PEAKS: usize = 8;

/// Of the most prominent peaks, the two independent ones whose weakest of themselves and
/// their sum or difference (a third peak of any lattice they span, the harmonic a pair of
/// chance peaks lacks) is the most prominent, and that prominence.
fn best_pair(peaks: &[Peak]) -> Option<(f32, [[i64; 2]; 2])> {
    let top = &peaks[..peaks.len().min(PAIRED_PEAKS)];
    let near = |target: [i64; 2]| {
        let mirrored = |s: [i64; 2]| [[s[0], s[1]], [-s[0], -s[1]]];
        peaks
            .iter()
            .filter(|p| {
                mirrored(p.shift)
                    .iter()
                    .any(|m| (m[0] - target[0]).abs() <= 1 && (m[1] - target[1]).abs() <= 1)
            })
            .map(|p| p.prominence)
            .fold(f32::NEG_INFINITY, f32::max)
    };
    let mut best: Option<(f32, [[i64; 2]; 2])> = None;
    for (i, a) in top.iter().enumerate() {
        for b in &top[i + 1..] {
            if sine(a.shift, b.shift).abs() < INDEPENDENT {
                continue;
            }
            let sum = [a.shift[0] + b.shift[0], a.shift[1] + b.shift[1]];
            let difference = [a.shift[0] - b.shift[0], a.shift[1] - b.shift[1]];
            let third = near(sum).max(near(difference));
            let score = a.prominence.min(b.prominence).min(third);
            if best.is_none_or(|(s, _)| score > s) {
                best = Some((score, [a.shift, b.shift]));
            }
        }
    }
    best
}

/// Per texel, its distance to its right neighbour plus to its lower one (0 on the last
/// column and row).
pub(crate) fn structure<M: Metric>(width: usize, height: usize, metric: &M) -> Vec<f32> {
    let (w, h) = (width as i32, height as i32);
    let mut out = vec![0.0; width * height];
    for y in 0..h {
        for x in 0..w {
            let right = if x + 1 < w { metric.texel_distance([x, y], [x + 1, y]) } else { 0.0 };
            let below = if y + 1 < h { metric.texel_distance([x, y], [x, y + 1]) } else { 0.0 };
            out[(y * w + x) as usize] = (right + below).sqrt();
        }
    }
    out
}

/// The ring a peak is measured against: a quarter of its length away, at least 2 texels.
fn ring_radius(length: f32) -> f32 {
    (length / 4.0).max(2.0)
}

fn sine(a: [i64; 2], b: [i64; 2]) -> f32 {
    let cross = (a[0] * b[1] - a[1] * b[0]) as f32;
    cross / ((a[0] as f32).hypot(a[1] as f32) * (b[0] as f32).hypot(b[1] as f32)).max(f32::MIN_POSITIVE)
}

#[derive(Clone, Copy, Debug)]
struct Peak {
    shift: [i64; 2],
    prominence: f32,
}

/// Normalised autocorrelation of an image over the shifts that keep half of it overlapping
/// (`dy` ≥ 0 only: a shift and its opposite correlate alike).
struct Autocorrelation {
    reach: [i64; 2],
    values: Vec<f32>,
}

impl Autocorrelation {
    fn of(image: &[f32], width: usize, height: usize) -> Self {
        let mean = image.iter().sum::<f32>() / image.len().max(1) as f32;
        let centred: Vec<f32> = image.iter().map(|v| v - mean).collect();
        let reach = [(width / 2) as i64, (height / 2) as i64];
        let (w, h) = (width as i64, height as i64);
        let at = |x: i64, y: i64| centred[(y * w + x) as usize];
        let mut values = Vec::with_capacity(((2 * reach[0] + 1) * (reach[1] + 1)) as usize);
        for dy in 0..=reach[1] {
            for dx in -reach[0]..=reach[0] {
                let (mut sum, mut n) = (0.0f64, 0usize);
                for y in 0..h - dy {
                    for x in (-dx).max(0)..(w - dx).min(w) {
                        sum += f64::from(at(x, y) * at(x + dx, y + dy));
                        n += 1;
                    }
                }
                values.push((sum / n.max(1) as f64) as f32);
            }
        }
        let zero = values[reach[0] as usize].max(f32::MIN_POSITIVE);
        values.iter_mut().for_each(|v| *v /= zero);
        Autocorrelation { reach, values }
    }

    /// The value at a shift; opposite shifts alike, `None` out of reach.
    fn at(&self, [dx, dy]: [i64; 2]) -> Option<f32> {
        let (dx, dy) = if dy < 0 { (-dx, -dy) } else { (dx, dy) };
        let [rx, ry] = self.reach;
        (dx.abs() <= rx && dy <= ry).then(|| self.values[(dy * (2 * rx + 1) + dx + rx) as usize])
    }

    /// Local maxima (over the 5×5 shifts around them) at least [`SHORTEST_PERIOD`] long, the
    /// most prominent first.
    fn peaks(&self) -> Vec<Peak> {
        let [rx, ry] = self.reach;
        let mut out = Vec::new();
        for dy in 0..=ry {
            for dx in -rx..=rx {
                let length = (dx as f32).hypot(dy as f32);
                if length < SHORTEST_PERIOD || (dy == 0 && dx < 0) {
                    continue;
                }
                let value = self.values[(dy * (2 * rx + 1) + dx + rx) as usize];
                let around = (-2..=2).flat_map(|j| (-2..=2).map(move |i| [dx + i, dy + j]));
                if around.filter_map(|s| self.at(s)).any(|v| v > value) {
                    continue;
                }
                let radius = ring_radius(length);
                if dx.abs() as f32 + radius > rx as f32 || dy as f32 + radius > ry as f32 {
                    // Too few texels overlap at this shift for its ring to be measured.
                    continue;
                }
                out.push(Peak { shift: [dx, dy], prominence: value - self.ring_max([dx, dy], radius) });
            }
        }
        out.sort_by(|a, b| b.prominence.total_cmp(&a.prominence));
        out
    }

    /// The highest value on 16 shifts around `shift`, a quarter of its length away.
    fn ring_max(&self, shift: [i64; 2], radius: f32) -> f32 {
        (0..16)
            .filter_map(|i| {
                let angle = i as f32 * std::f32::consts::TAU / 16.0;
                let at = [shift[0] as f32 + radius * angle.cos(), shift[1] as f32 + radius * angle.sin()];
                self.at(at.map(|v| v.round() as i64))
            })
            .fold(f32::NEG_INFINITY, f32::max)
    }

    /// A peak's shift to a fraction of a texel: a parabola through it and its neighbours
    /// along each axis.
    fn refined(&self, shift: [i64; 2]) -> [f32; 2] {
        let centre = self.at(shift).unwrap_or(0.0);
        [0, 1].map(|axis| {
            let mut step = [0, 0];
            step[axis] = 1;
            let side = |sign: i64| self.at([shift[0] + sign * step[0], shift[1] + sign * step[1]]);
            let fraction = match (side(-1), side(1)) {
                (Some(lo), Some(hi)) if lo + hi - 2.0 * centre < 0.0 => {
                    (0.5 * (lo - hi) / (lo + hi - 2.0 * centre)).clamp(-0.5, 0.5)
                }
                _ => 0.0,
            };
            shift[axis] as f32 + fraction
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::metric::AppearanceMetric;
    use crate::synth::sample::AppearanceMap;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    const SIDE: usize = 64;

    /// The periods found in a one-channel image, if any.
    fn periods(image: impl Fn(usize, usize, &mut ChaCha8Rng) -> f32) -> Option<[[f32; 2]; 2]> {
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let values: Vec<f32> = (0..SIDE * SIDE).map(|p| image(p % SIDE, p / SIDE, &mut rng)).collect();
        let map = AppearanceMap::new(SIDE, SIDE, 1, &values, false);
        let image = structure(SIDE, SIDE, &AppearanceMetric { map: &map, template: 5 });
        periods_of(&image, SIDE, SIDE).map(|p| Lattice { periods: p }.reduced().periods)
    }

    /// Tiles 16 texels a side, each its own tone, between light joints one texel wide.
    fn tiles(x: usize, y: usize, rng: &mut ChaCha8Rng) -> f32 {
        let joint = x % 16 == 0 || y % 16 == 0;
        let tone = [0.2, 0.45, 0.3, 0.6, 0.25, 0.5, 0.35, 0.4][(x / 16 + 3 * (y / 16)) % 8];
        (if joint { 1.0 } else { tone }) + rng.random_range(-0.05..0.05)
    }

    #[test]
    fn a_tiled_floor_has_its_tiles_periods() {
        let found = periods(tiles).expect("a lattice");
        let near = |p: [f32; 2], q: [f32; 2]| (p[0] - q[0]).hypot(p[1] - q[1]) < 0.6;
        let either = |q: [f32; 2]| found.iter().any(|&p| near(p, q) || near(p, [-q[0], -q[1]]));
        assert!(either([16.0, 0.0]) && either([0.0, 16.0]), "{found:?}");
    }

    #[test]
    fn noise_stripes_and_blotches_have_no_lattice() {
        assert_eq!(periods(|_, _, rng| rng.random_range(0.0..1.0)), None);
        // Stripes repeat along one direction only: a ridge, not a lattice.
        assert_eq!(periods(|x, _, rng| (x % 8 < 3) as u8 as f32 + rng.random_range(-0.05..0.05)), None);
        // Blotches at random places.
        let centres: Vec<[f32; 2]> = {
            let mut rng = ChaCha8Rng::seed_from_u64(9);
            (0..12)
                .map(|_| [rng.random_range(0.0..SIDE as f32), rng.random_range(0.0..SIDE as f32)])
                .collect()
        };
        let blotches = |x: usize, y: usize, rng: &mut ChaCha8Rng| {
            let near = centres.iter().any(|c| (c[0] - x as f32).hypot(c[1] - y as f32) < 5.0);
            near as u8 as f32 + rng.random_range(-0.05..0.05)
        };
        assert_eq!(periods(blotches), None);
    }

    /// A floor too large to search directly (a surface's single level): its structure
    /// averaged over blocks still shows its tiles' periods, and noise still shows none.
    #[test]
    fn a_large_floor_is_found_through_block_means() {
        const LARGE: usize = 200;
        let found = |image: &dyn Fn(usize, usize, &mut ChaCha8Rng) -> f32| {
            let mut rng = ChaCha8Rng::seed_from_u64(5);
            let values: Vec<f32> =
                (0..LARGE * LARGE).map(|p| image(p % LARGE, p / LARGE, &mut rng)).collect();
            let map = AppearanceMap::new(LARGE, LARGE, 1, &values, false);
            let fine = structure(LARGE, LARGE, &AppearanceMetric { map: &map, template: 5 });
            let block = LARGE.div_ceil(SEARCH_SIDE);
            let (image, w, h) = block_means(&fine, LARGE, LARGE, block);
            assert!(w.max(h) <= SEARCH_SIDE);
            periods_of(&image, w, h)
                .map(|p| Lattice { periods: p.map(|q| q.map(|v| v * block as f32)) }.reduced())
        };
        let floor = found(&|x, y, rng| tiles(x * 16 / 40, y * 16 / 40, rng)).expect("a lattice");
        let lengths = floor.periods.map(|p| p[0].hypot(p[1]));
        assert!(lengths.iter().all(|l| (l - 40.0).abs() < 1.5), "{floor:?}");
        assert_eq!(found(&|_, _, rng| rng.random_range(0.0..1.0)), None);
    }

    #[test]
    fn reduction_keeps_the_lattice_and_shortens_its_periods() {
        let skewed = Lattice { periods: [[16.0, 0.0], [48.0, 16.0]] }.reduced();
        assert_eq!(skewed.periods, [[16.0, 0.0], [0.0, 16.0]]);
        assert_eq!(skewed.shift([2, -1]), [32, -16]);
        assert_eq!(skewed.scaled(4.0).periods, [[4.0, 0.0], [0.0, 4.0]]);
    }
}
