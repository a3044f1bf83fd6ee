//! Which sampled directions, and how much of each (Tong §6): the 4 nearest sampled view
//! directions and the 4 nearest light directions by angle, combined into 4 × 4 images.
//!
//! **Weights.** Normalised inverse angular distance, *minus the fifth's*:
//! wᵢ ∝ 1/dᵢ − 1/d₅. Plain inverse distance jumps when the fifth-nearest direction replaces
//! the fourth (the newcomer arrives with weight 1/d₄, not 0); subtracting 1/d₅ makes the
//! leaving and the arriving direction both weigh 0 at the swap, so the blend is continuous
//! as a light or the camera moves. Barycentric weights would need a triangulation of each
//! dome; this scheme works on any direction set (UBO, Bonn, a grid, a hand-made manifest).
//! A query within [`EXACT_RADIANS`] of a sampled direction returns that direction alone.
//!
//! **Beyond the dome.** A measured dome stops short of the horizon (Bonn: θ ≤ 75°). A query
//! beyond its largest θ would find its nearest directions partly on inner rings, towards
//! the pole, whose images are lit more steeply and shadowed less. Instead, such a query is
//! moved onto the outermost θ at its own azimuth and blended among the *rim* (the
//! directions within half a typical spacing of the largest θ) only. To keep the blend
//! continuous, the inner directions fade out over a band just inside the largest θ: their
//! angular distances get a penalty that grows from 0 to infinity across the band, and the
//! weights above stay continuous under any continuous distance. [`Material`] attenuates a
//! light beyond the dome by the ratio of cosines ([`DirectionIndex::beyond_cosine_ratio`]).
//!
//! [`Material`]: super::Material

use glam::Vec3;

/// Directions closer than this (≈ 0.0006°) count as the same: an exact hit.
pub const EXACT_RADIANS: f32 = 1e-5;

/// Up to four directions (indices into a [`DirectionIndex`]) and their weights, which sum
/// to 1. Unused entries have weight 0.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Nearest4 {
    /// The directions' indices in the [`DirectionIndex`].
    pub index: [u32; 4],
    /// Their weights, 0–1, summing to 1.
    pub weight: [f32; 4],
}

/// Angular cells of the lookup grid: θ in 2.5° rows, φ in 5° columns (finer cells, fewer
/// candidates per query).
const THETA_CELLS: usize = 36;
const PHI_CELLS: usize = 72;

/// A set of sampled directions on the upper hemisphere, with a grid of candidate lists so
/// that a query examines a handful of directions instead of all of them.
#[derive(Clone, Debug)]
pub struct DirectionIndex {
    units: Vec<Vec3>,
    /// Per (θ, φ) cell, every direction that can be among the 5 nearest of a query in it.
    cells: Vec<Vec<u32>>,
    /// cos of each row's upper θ edge: row r holds the queries with cos θ in
    /// (row_cos[r], row_cos[r − 1]], found without an acos.
    row_cos: [f32; THETA_CELLS - 1],
    rim: Rim,
}

/// The outermost ring of a dome and the band inside it where inner directions fade out.
#[derive(Clone, Debug)]
struct Rim {
    /// The largest θ of the set, in radians.
    theta_max: f32,
    /// Width of the fade band inside `theta_max`, in radians.
    fade: f32,
    /// cos(theta_max − fade): queries with a smaller z are in the band or beyond.
    band_cos: f32,
    /// The directions within half a typical spacing of `theta_max`, by azimuth.
    members: Vec<u32>,
    /// The members' azimuths in [0, 2π), ascending.
    azimuths: Vec<f32>,
    is_member: Vec<bool>,
}

impl Rim {
    fn new(units: &[Vec3]) -> Rim {
        let thetas: Vec<f32> = units.iter().map(|u| u.z.clamp(-1.0, 1.0).acos()).collect();
        let theta_max = thetas.iter().copied().fold(0.0, f32::max);
        // Typical angular spacing: the side of the solid angle per direction on the cap.
        let cap = std::f32::consts::TAU * (1.0 - theta_max.cos());
        let spacing = (cap / units.len() as f32).sqrt();
        let is_member: Vec<bool> = thetas.iter().map(|&t| t >= theta_max - 0.5 * spacing).collect();
        let azimuth =
            |i: u32| units[i as usize].y.atan2(units[i as usize].x).rem_euclid(std::f32::consts::TAU);
        let mut members: Vec<u32> = (0..units.len() as u32).filter(|&i| is_member[i as usize]).collect();
        members.sort_by(|&a, &b| azimuth(a).total_cmp(&azimuth(b)));
        let azimuths = members.iter().map(|&i| azimuth(i)).collect();
        let fade = 0.25 * spacing;
        Rim { theta_max, fade, band_cos: (theta_max - fade).cos(), members, azimuths, is_member }
    }

    /// The rim members that can be among the 5 nearest rim directions of a query at azimuth
    /// `phi`: the 5 on either side of it by azimuth (all of a small rim).
    fn near(&self, phi: f32) -> impl Iterator<Item = u32> + '_ {
        let n = self.members.len();
        let (start, count) =
            if n <= 10 { (0, n) } else { (self.azimuths.partition_point(|&a| a < phi) + n - 5, 10) };
        (start..start + count).map(move |k| self.members[k % n])
    }

    /// The penalty added to the distance of a non-rim direction for a query at polar angle
    /// `theta`: 0 inside the band, growing to infinity at `theta_max`.
    fn penalty(&self, theta: f32) -> f32 {
        let start = self.theta_max - self.fade;
        if theta <= start || self.fade <= 0.0 {
            return 0.0;
        }
        let s = (theta - start) / self.fade;
        if s >= 1.0 {
            f32::INFINITY
        } else {
            self.fade * s / (1.0 - s)
        }
    }
}

impl DirectionIndex {
    /// Indexes `units` (unit vectors, z up; at least one).
    pub fn new(units: Vec<Vec3>) -> DirectionIndex {
        assert!(!units.is_empty(), "a direction set has at least one direction");
        let (dt, dp) = (cell_theta(), cell_phi());
        let cells = (0..THETA_CELLS * PHI_CELLS)
            .map(|c| {
                let (row, col) = (c / PHI_CELLS, c % PHI_CELLS);
                let theta = (row as f32 + 0.5) * dt;
                let centre = spherical((row as f32 + 0.5) * dt, (col as f32 + 0.5) * dp);
                // Any point of the cell lies within `radius` of its centre (a θ step, then
                // an arc of φ no longer than at the cell's widest row).
                let radius = 0.5 * dt + 0.5 * dp * (theta + 0.5 * dt).min(std::f32::consts::FRAC_PI_2).sin();
                let mut angles: Vec<(f32, u32)> =
                    units.iter().enumerate().map(|(i, u)| (angle(centre, *u), i as u32)).collect();
                angles.sort_by(|a, b| a.0.total_cmp(&b.0));
                let fifth = angles[angles.len().min(5) - 1].0;
                angles
                    .iter()
                    .take_while(|(a, _)| *a <= fifth + 2.0 * radius + 1e-4)
                    .map(|&(_, i)| i)
                    .collect()
            })
            .collect();
        let row_cos = std::array::from_fn(|k| ((k + 1) as f32 * dt).cos());
        let rim = Rim::new(&units);
        DirectionIndex { units, cells, row_cos, rim }
    }

    /// The largest polar angle θ of the set, in radians: where the measured dome ends.
    pub fn theta_max(&self) -> f32 {
        self.rim.theta_max
    }

    /// The directions on the outermost ring (those a query beyond the dome blends), by
    /// azimuth.
    pub fn rim(&self) -> &[u32] {
        &self.rim.members
    }

    /// For a query beyond the dome (θ > [`DirectionIndex::theta_max`]), cos θ / cos θ_max:
    /// how much less light a plane receives from it than from the outermost ring; 1 inside
    /// the dome. Below the horizon, 0.
    pub fn beyond_cosine_ratio(&self, query: Vec3) -> f32 {
        let cos_max = self.rim.theta_max.cos();
        if query.z >= cos_max || cos_max <= 0.0 {
            1.0
        } else {
            (query.z / cos_max).max(0.0)
        }
    }

    /// The nearest direction to `query` (above the horizon): the Voronoi cell it falls in.
    pub fn nearest(&self, query: Vec3) -> u32 {
        let mut best = (f32::NEG_INFINITY, 0u32);
        for &i in &self.cells[self.cell_of(query)] {
            let d = query.dot(self.units[i as usize]);
            if d > best.0 {
                best = (d, i);
            }
        }
        best.1
    }

    /// The indexed directions.
    pub fn units(&self) -> &[Vec3] {
        &self.units
    }

    /// Number of directions.
    pub fn len(&self) -> usize {
        self.units.len()
    }

    /// True if empty (never, by construction).
    pub fn is_empty(&self) -> bool {
        self.units.is_empty()
    }

    /// The 4 nearest directions to `query` (a unit vector; below the horizon it is taken at
    /// the horizon) and their weights; beyond the dome, the rim's (see the module notes).
    pub fn nearest4(&self, query: Vec3) -> Nearest4 {
        let query = above_horizon(query);
        if query.z < self.rim.band_cos && self.rim.fade > 0.0 {
            return self.nearest4_near_rim(query, query.z.clamp(-1.0, 1.0).acos());
        }
        // Rank by dot product (the larger, the nearer); take angles of the five kept only.
        let mut best = [(f32::NEG_INFINITY, 0u32); 5];
        for &i in &self.cells[self.cell_of(query)] {
            let d = query.dot(self.units[i as usize]);
            if d > best[4].0 {
                let mut k = 4;
                while k > 0 && best[k - 1].0 < d {
                    best[k] = best[k - 1];
                    k -= 1;
                }
                best[k] = (d, i);
            }
        }
        let units = &self.units;
        weights(&best.map(|(d, i)| {
            if d.is_finite() {
                (angle(query, units[i as usize]), i)
            } else {
                (f32::INFINITY, i)
            }
        }))
    }

    /// A query in the fade band or beyond the dome: moved onto the outermost θ if beyond,
    /// inner directions penalised, rim directions always considered.
    fn nearest4_near_rim(&self, query: Vec3, theta: f32) -> Nearest4 {
        let q = if theta > self.rim.theta_max {
            let (sin_t, cos_t) = self.rim.theta_max.sin_cos();
            let flat = Vec3::new(query.x, query.y, 0.0).normalize_or(Vec3::X);
            Vec3::new(flat.x * sin_t, flat.y * sin_t, cos_t)
        } else {
            query
        };
        let penalty = self.rim.penalty(theta);
        let mut best = [(f32::INFINITY, 0u32); 5];
        let mut consider = |i: u32| {
            if best.iter().any(|b| b.1 == i && b.0.is_finite()) {
                return;
            }
            let extra = if self.rim.is_member[i as usize] { 0.0 } else { penalty };
            let d = angle(q, self.units[i as usize]) + extra;
            if d < best[4].0 {
                let mut k = 4;
                while k > 0 && best[k - 1].0 > d {
                    best[k] = best[k - 1];
                    k -= 1;
                }
                best[k] = (d, i);
            }
        };
        self.rim.near(q.y.atan2(q.x).rem_euclid(std::f32::consts::TAU)).for_each(&mut consider);
        if penalty.is_finite() {
            self.cells[self.cell_of(q)].iter().for_each(|&i| consider(i));
        }
        weights(&best)
    }

    fn cell_of(&self, q: Vec3) -> usize {
        let row = self.row_cos.partition_point(|&c| q.z < c).min(THETA_CELLS - 1);
        let phi = q.y.atan2(q.x).rem_euclid(std::f32::consts::TAU);
        let col = ((phi / cell_phi()) as usize).min(PHI_CELLS - 1);
        row * PHI_CELLS + col
    }
}

/// Weights from the (up to) five nearest (angle, index) pairs, sorted by angle; missing
/// entries have infinite angle.
fn weights(best: &[(f32, u32); 5]) -> Nearest4 {
    let index = [best[0].1, best[1].1, best[2].1, best[3].1];
    if best[0].0 <= EXACT_RADIANS {
        return Nearest4 { index, weight: [1.0, 0.0, 0.0, 0.0] };
    }
    let floor = if best[4].0.is_finite() { 1.0 / best[4].0 } else { 0.0 };
    let mut weight = [0.0; 4];
    for k in 0..4 {
        if best[k].0.is_finite() {
            weight[k] = (1.0 / best[k].0 - floor).max(0.0);
        }
    }
    let sum: f32 = weight.iter().sum();
    if sum > 0.0 {
        weight.iter_mut().for_each(|w| *w /= sum);
    } else {
        // Five equidistant directions: share equally among the four kept.
        let kept = best[..4].iter().filter(|b| b.0.is_finite()).count() as f32;
        for k in 0..4 {
            weight[k] = if best[k].0.is_finite() { 1.0 / kept } else { 0.0 };
        }
    }
    Nearest4 { index, weight }
}

/// The angle between unit vectors, accurate near 0 and π (unlike `acos` of the dot).
pub fn angle(a: Vec3, b: Vec3) -> f32 {
    2.0 * ((a - b).length() * 0.5).clamp(0.0, 1.0).asin()
}

fn above_horizon(q: Vec3) -> Vec3 {
    if q.z >= 0.0 {
        return q;
    }
    let flat = Vec3::new(q.x, q.y, 0.0);
    if flat.length_squared() > 1e-12 {
        flat.normalize()
    } else {
        Vec3::X
    }
}

fn spherical(theta: f32, phi: f32) -> Vec3 {
    Vec3::new(theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos())
}

fn cell_theta() -> f32 {
    std::f32::consts::FRAC_PI_2 / THETA_CELLS as f32
}

fn cell_phi() -> f32 {
    std::f32::consts::TAU / PHI_CELLS as f32
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::btf::DirectionSet;

    fn dome() -> DirectionIndex {
        let dirs = DirectionSet::Ubo81.directions();
        DirectionIndex::new(dirs.iter().map(|d| d.unit()).collect())
    }

    /// Brute force over all directions, for reference.
    fn brute(index: &DirectionIndex, q: Vec3) -> Nearest4 {
        let mut all: Vec<(f32, u32)> =
            index.units().iter().enumerate().map(|(i, u)| (angle(q, *u), i as u32)).collect();
        all.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut best = [(f32::INFINITY, 0); 5];
        for (k, b) in all.iter().take(5).enumerate() {
            best[k] = *b;
        }
        weights(&best)
    }

    #[test]
    fn grid_lookup_equals_brute_force() {
        let index = dome();
        // Inside the dome, short of the band where inner directions fade out.
        let inside = index.theta_max() - index.rim.fade;
        for k in 0..2000 {
            let theta = crate::seeded::unit(3, k, 0, 0) * inside;
            let phi = crate::seeded::unit(3, k, 1, 0) * std::f32::consts::TAU;
            let q = spherical(theta, phi);
            let (a, b) = (index.nearest4(q), brute(&index, q));
            for j in 0..4 {
                let wa: f32 = (0..4).filter(|&m| a.index[m] == b.index[j]).map(|m| a.weight[m]).sum();
                assert!((wa - b.weight[j]).abs() < 1e-5, "query {q}: {a:?} vs {b:?}");
            }
        }
    }

    #[test]
    fn nearest_is_the_voronoi_cell() {
        let index = dome();
        for k in 0..2000 {
            let theta = crate::seeded::unit(4, k, 0, 0) * std::f32::consts::FRAC_PI_2;
            let phi = crate::seeded::unit(4, k, 1, 0) * std::f32::consts::TAU;
            let q = spherical(theta, phi);
            let best = index.units().iter().map(|u| angle(q, *u)).fold(f32::MAX, f32::min);
            assert!((angle(q, index.units()[index.nearest(q) as usize]) - best).abs() < 1e-6, "{q}");
        }
    }

    #[test]
    fn beyond_the_dome_only_the_outermost_ring_blends() {
        let index = dome();
        let theta_max = index.theta_max();
        assert!((theta_max - 75f32.to_radians()).abs() < 1e-5);
        assert_eq!(index.rim().len(), 24, "the 75° ring");
        for k in 0..500 {
            let theta =
                theta_max + crate::seeded::unit(5, k, 0, 0) * (std::f32::consts::FRAC_PI_2 - theta_max);
            let q = spherical(theta + 1e-4, crate::seeded::unit(5, k, 1, 0) * std::f32::consts::TAU);
            let n = index.nearest4(q);
            for j in 0..4 {
                assert!(n.weight[j] == 0.0 || index.rim().contains(&n.index[j]), "{q}: {n:?}");
            }
            // The same as the 5 nearest rim directions to the query moved onto θ_max.
            let on_rim = spherical(theta_max, q.y.atan2(q.x));
            let mut all: Vec<(f32, u32)> =
                index.rim().iter().map(|&i| (angle(on_rim, index.units()[i as usize]), i)).collect();
            all.sort_by(|a, b| a.0.total_cmp(&b.0));
            let brute = weights(&std::array::from_fn(|k| all[k]));
            for j in 0..4 {
                let w: f32 = (0..4).filter(|&m| n.index[m] == brute.index[j]).map(|m| n.weight[m]).sum();
                assert!((w - brute.weight[j]).abs() < 1e-4, "{q}: {n:?} vs {brute:?}");
            }
            assert!((n.weight.iter().sum::<f32>() - 1.0).abs() < 1e-5);
            let ratio = index.beyond_cosine_ratio(q);
            assert!((ratio - q.z / theta_max.cos()).abs() < 1e-5 && ratio < 1.0);
        }
        assert_eq!(index.beyond_cosine_ratio(spherical(0.3, 1.0)), 1.0);
    }

    #[test]
    fn the_blend_is_continuous_across_the_fade_band_and_the_rim() {
        // Each direction's weight, as a function of θ at a fixed φ between two rim
        // directions: halving the step must halve the largest change (no jumps).
        let index = dome();
        let weights = |theta: f32| {
            let n = index.nearest4(spherical(theta, 0.37));
            let mut w = vec![0.0; index.len()];
            (0..4).for_each(|j| w[n.index[j] as usize] += n.weight[j]);
            w
        };
        let worst_step = |steps: usize| {
            let (a, b) = (60f32.to_radians(), 85f32.to_radians());
            let at = |k: usize| weights(a + (b - a) * k as f32 / steps as f32);
            (1..=steps)
                .map(|k| at(k).iter().zip(at(k - 1)).map(|(x, y)| (x - y).abs()).fold(0.0, f32::max))
                .fold(0.0, f32::max)
        };
        let (coarse, fine) = (worst_step(4000), worst_step(8000));
        assert!(fine < 0.6 * coarse, "largest step {coarse} at 4k steps, {fine} at 8k");
    }

    #[test]
    fn exact_hit_returns_that_direction_alone() {
        let index = dome();
        for (i, u) in index.units().iter().enumerate() {
            let n = index.nearest4(*u);
            assert_eq!((n.index[0], n.weight), (i as u32, [1.0, 0.0, 0.0, 0.0]));
        }
    }

    #[test]
    fn weights_sum_to_one_and_are_non_negative() {
        let index = dome();
        for k in 0..500 {
            let q = spherical(k as f32 * 0.003, k as f32 * 0.7);
            let n = index.nearest4(q);
            assert!((n.weight.iter().sum::<f32>() - 1.0).abs() < 1e-5);
            assert!(n.weight.iter().all(|&w| w >= 0.0));
        }
    }

    #[test]
    fn small_sets_and_below_horizon_queries() {
        let one = DirectionIndex::new(vec![Vec3::Z]);
        assert_eq!(one.nearest4(Vec3::new(0.0, 0.6, -0.8)).weight, [1.0, 0.0, 0.0, 0.0]);
        let two = DirectionIndex::new(vec![Vec3::Z, Vec3::X]);
        let n = two.nearest4(spherical(0.3, 0.0));
        assert!((n.weight[0] + n.weight[1] - 1.0).abs() < 1e-6 && n.weight[0] > n.weight[1]);
    }
}
