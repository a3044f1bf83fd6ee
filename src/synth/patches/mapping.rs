//! Coarse-to-fine mapping with a priority queue (Soler et al. §2.2), the masks of §4.1 and
//! the relaxation of §4.4.
//!
//! Round by round, coarse to fine, the clusters that cover what is not yet textured wait in
//! a priority queue: those with the most textured neighbouring regions first (then the
//! coarser, then the flattest). A cluster is flattened ([`super::chart`]); if it is not a
//! disc, folds, or its flattening error is over the limit, its children go to the next
//! round. Otherwise its textured
//! neighbours' faces within a band of the border are unfolded into its frame and drawn with
//! their texture: the mask. The mask's best placement in the sample ([`super::fit`]) maps
//! the cluster, relaxed along its borders, if the remaining difference along the shared
//! edges (the output error of §4.4) is under the threshold; else the children go to the next
//! round. A cluster with no textured neighbour takes a random placement only on a piece of
//! the surface where nothing is textured yet, which is how the mapping starts (at the
//! coarsest level with a flat enough cluster, the flattest first); elsewhere it waits, as it
//! is, for a later round, when the growth around it has reached it. Single faces of the last
//! level are always mapped, with their best placement: the finest scale fills what is left
//! as well as it can.

use super::chart::{unfold, Chart};
use super::fit::{Mask, Placement, Unplaced};
use super::graph::NONE;
pub(super) use super::mapper::Mapper;
pub use super::mapper::Mapping;
use super::LevelReport;
use crate::progress::Progress;
use crate::Result;
use glam::{Affine2, Mat2, Vec2};
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use std::cmp::Ordering;
use std::collections::{BinaryHeap, HashMap, VecDeque};
use std::time::Instant;

/// What became of a cluster.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Outcome {
    Mapped {
        started: bool,
        /// Placed as the exact continuation of a textured neighbour.
        continued: bool,
    },
    NotDisc,
    Distorted,
    TooLarge,
    PoorFit,
    /// No textured neighbour, on a piece of the surface already started elsewhere: the
    /// cluster waits for the next round as it is. The paper queues only the neighbours of
    /// textured clusters; a random start here would make its whole border a seam.
    Unreached,
}

/// A queue entry: more textured neighbours first, then the coarser (a larger patch while
/// one still fits), then the flatter, then the lower id.
#[derive(Clone, Copy, PartialEq)]
struct Key {
    textured: u32,
    level: u32,
    flat: f32,
    cluster: u32,
}

/// What a round of [`Mapper::drain`] reads and writes.
struct Round<'a> {
    charts: &'a HashMap<u32, Option<Chart>>,
    reports: &'a mut [LevelReport],
    /// Per level, the fitting errors of its fits.
    errors: &'a mut [Vec<f32>],
    mapping: &'a mut Mapping,
}

impl Eq for Key {}

impl Ord for Key {
    fn cmp(&self, other: &Self) -> Ordering {
        self.textured
            .cmp(&other.textured)
            .then_with(|| other.level.cmp(&self.level))
            .then_with(|| other.flat.total_cmp(&self.flat))
            .then_with(|| other.cluster.cmp(&self.cluster))
    }
}

impl PartialOrd for Key {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

impl Mapper<'_> {
    /// Maps every face, reporting per level.
    pub fn run(&self, rng: &mut ChaCha8Rng, progress: &dyn Progress) -> Result<(Mapping, Vec<LevelReport>)> {
        let (graph, h) = (self.graph, self.hierarchy);
        let mut mapping = Mapping::new(graph.face_count());
        let mut reports: Vec<LevelReport> = h
            .levels
            .iter()
            .enumerate()
            .map(|(l, level)| LevelReport { level: l, clusters: level.len(), ..LevelReport::default() })
            .collect();
        let mut errors: Vec<Vec<f32>> = vec![Vec::new(); h.levels.len()];
        let mut charts: HashMap<u32, Option<Chart>> = HashMap::new();
        let mut eligible: Vec<u32> = h.levels[0].clone();
        progress.start("mapping patches", graph.face_count() as u64);
        // Each round drains a queue of clusters that together cover every face not yet
        // mapped; refused clusters hand their children to the next round, unreached ones
        // wait there as they are (see [`Outcome::Unreached`]).
        while !eligible.is_empty() {
            let fresh: Vec<u32> = eligible.iter().copied().filter(|c| !charts.contains_key(c)).collect();
            let built: Vec<(u32, Option<Chart>)> =
                fresh.par_iter().map(|&c| (c, self.flattening.chart(graph, h, c))).collect();
            charts.extend(built);
            let mut round =
                Round { charts: &charts, reports: &mut reports, errors: &mut errors, mapping: &mut mapping };
            eligible = self.drain(&eligible, &mut round, rng, progress)?;
        }
        if self.params.matching && self.params.move_borders {
            super::cut::cut_borders(self, &mut mapping);
            super::borders::move_borders(self, &mut mapping);
        }
        for (report, errors) in reports.iter_mut().zip(&mut errors) {
            errors.sort_by(f32::total_cmp);
            report.median_fit_error = errors.get(errors.len() / 2).copied().unwrap_or(f32::NAN);
        }
        progress.finish();
        debug_assert!(mapping.mapped_by.iter().all(|&c| c != NONE));
        Ok((mapping, reports))
    }

    /// One round: the clusters of `eligible` by priority; returns those left for the next.
    fn drain(
        &self,
        eligible: &[u32],
        round: &mut Round,
        rng: &mut ChaCha8Rng,
        progress: &dyn Progress,
    ) -> Result<Vec<u32>> {
        let h = self.hierarchy;
        let charts = round.charts;
        let flat = |c: u32| charts[&c].as_ref().map_or(f32::INFINITY, |ch| ch.flat_error);
        let key = |c: u32, mapping: &Mapping| Key {
            textured: self.textured_neighbours(c, mapping),
            level: h.clusters[c as usize].level,
            flat: flat(c),
            cluster: c,
        };
        let mut pending: HashMap<u32, bool> = eligible.iter().map(|&c| (c, true)).collect();
        let mut heap: BinaryHeap<Key> = eligible.iter().map(|&c| key(c, round.mapping)).collect();
        let mut next = Vec::new();
        while let Some(popped) = heap.pop() {
            let c = popped.cluster;
            if pending.get(&c) != Some(&true) {
                continue;
            }
            let textured = self.textured_neighbours(c, round.mapping);
            if textured != popped.textured {
                heap.push(Key { textured, ..popped });
                continue;
            }
            pending.insert(c, false);
            let started = Instant::now();
            let (outcome, error) = self.process(c, charts[&c].as_ref(), round.mapping, rng)?;
            let cluster = &h.clusters[c as usize];
            let report = &mut round.reports[cluster.level as usize];
            report.seconds += started.elapsed().as_secs_f64();
            round.errors[cluster.level as usize].extend(error);
            report.tried += usize::from(outcome != Outcome::Unreached);
            match outcome {
                Outcome::Mapped { started, continued } => {
                    report.mapped += 1;
                    report.started += usize::from(started);
                    report.continued += usize::from(continued);
                    report.faces += cluster.faces.len();
                    progress.advance(cluster.faces.len() as u64);
                    for &n in &cluster.neighbours {
                        if pending.get(&n) == Some(&true) {
                            heap.push(key(n, round.mapping));
                        }
                    }
                }
                Outcome::Unreached => {
                    report.unreached += 1;
                    next.push(c);
                }
                refused => {
                    match refused {
                        Outcome::NotDisc => report.not_disc += 1,
                        Outcome::Distorted => report.distorted += 1,
                        Outcome::TooLarge => report.too_large += 1,
                        _ => report.poor_fit += 1,
                    }
                    next.extend_from_slice(&cluster.children);
                }
            }
        }
        Ok(next)
    }

    /// How many distinct textured regions border cluster `c`.
    fn textured_neighbours(&self, c: u32, mapping: &Mapping) -> u32 {
        let (graph, h) = (self.graph, self.hierarchy);
        let cluster = &h.clusters[c as usize];
        let owner = &h.owner[cluster.level as usize];
        let mut regions: Vec<u32> = cluster
            .faces
            .iter()
            .flat_map(|&f| graph.across[f as usize])
            .filter(|&g| g != NONE && owner[g as usize] != c)
            .map(|g| mapping.mapped_by[g as usize])
            .filter(|&m| m != NONE)
            .collect();
        regions.sort_unstable();
        regions.dedup();
        regions.len() as u32
    }

    /// Steps 2–4 of §2.2 for cluster `c`.
    /// Returns the outcome and the fitting error (as a fraction of a random placement's) if
    /// the cluster was fitted.
    fn process(
        &self,
        c: u32,
        chart: Option<&Chart>,
        mapping: &mut Mapping,
        rng: &mut ChaCha8Rng,
    ) -> Result<(Outcome, Option<f32>)> {
        let cluster = &self.hierarchy.clusters[c as usize];
        let Some(chart) = chart.filter(|_| cluster.disc) else { return Ok((Outcome::NotDisc, None)) };
        let single = cluster.is_face();
        if !single && (chart.folds > 0 || chart.flat_error > self.params.max_flat_error) {
            return Ok((Outcome::Distorted, None));
        }
        let h = self.hierarchy;
        let piece = h.owner[0][cluster.faces[0] as usize];
        let starting = !mapping.started_pieces.contains(&piece);
        // The user's first face (§5): on its piece, nothing else starts before the cluster
        // that holds it; the others wait (its single face always maps, so it does start).
        if let Some(g) = self.first_face {
            if starting && h.owner[0][g as usize] == piece && h.owner[cluster.level as usize][g as usize] != c
            {
                return Ok((Outcome::Unreached, None));
            }
        }
        // The chart in texels, turned by a random angle so that the fixed rotations of the
        // sample do not include the trivial continuation of a neighbour (§4.2); a start
        // with the user's orientation is turned to it and placed unrotated.
        let oriented = self.params.orientation.filter(|_| starting);
        let angle = match oriented {
            Some(degrees) => self.start_angle(chart, degrees),
            None => rng.random_range(0.0..std::f32::consts::TAU),
        };
        let turn = Mat2::from_angle(angle) * self.params.texels_per_unit;
        let local: Vec<Vec2> = chart.vertices.iter().map(|&(_, p)| turn * p).collect();
        if !single && !self.may_fit(&local) {
            return Ok((Outcome::TooLarge, None));
        }
        let band = if self.params.matching { self.band(c, chart, &local, mapping) } else { Vec::new() };
        let footprint = || local.iter().map(|&p| mirror(p));
        let (lo, hi) = bounds(footprint().chain(band.iter().flat_map(|(_, p)| p.map(mirror))));
        let origin = (lo - Vec2::ONE).floor();
        let mask = (!band.is_empty())
            .then(|| self.mask(&band, (chart, &local), origin, hi, mapping))
            .filter(|m| m.count() > 0);
        // A cluster of the last level cannot wait; neither can one beside a textured face
        // whose band came out empty (it would wait for ever).
        let may_wait = !cluster.children.is_empty() && self.textured_neighbours(c, mapping) == 0;
        if mask.is_none() && may_wait && self.params.matching && mapping.started_pieces.contains(&piece) {
            return Ok((Outcome::Unreached, None));
        }
        // Chart texels → pixels of a frame whose pixel (0, 0) is `origin`.
        let to_frame = |origin: Vec2| {
            Affine2::from_translation(-origin) * Affine2::from_mat2(Mat2::from_diagonal(Vec2::new(1.0, -1.0)))
        };
        // A continuation of a textured neighbour leaves no seam on that side (border windows
        // on such seams score as the interior), where the best fit of a mask drawn from two
        // or more neighbours that do not continue each other leaves one on every side.
        // A single face takes the continuation whose mask error is least (the finest level
        // fills gaps). A larger cluster takes the continuation with the least output error
        // (§4.4, before relaxation) if that is within the threshold; else the mask's best
        // fit, unless a continuation's output error is still lower.
        let (fitted, continued) = match &mask {
            Some(mask) if single => match self.best_continuation(&band, mask, origin, &local, mapping) {
                Some(found) => (Some(Ok(found.0)), true),
                None => (Some(self.fitter.fit(mask)?.map(|p| self.fitter.to_sample(&p))), false),
            },
            Some(mask) => {
                let output = |map: Affine2| {
                    let to_sample = map * to_frame(origin);
                    let uv: Vec<Vec2> = local.iter().map(|&p| to_sample.transform_point2(p)).collect();
                    super::relax::output_error(self, c, chart, &uv, mapping).unwrap_or(f32::INFINITY)
                };
                let continuation = self
                    .continuations(&band, origin, &local, mapping)
                    .into_iter()
                    .map(|map| (output(map), map))
                    .min_by(|a, b| a.0.total_cmp(&b.0));
                match continuation {
                    Some((e, map)) if e <= self.params.max_fit_error => (Some(Ok(map)), true),
                    _ => match self.fitter.fit(mask)? {
                        Ok(p) => {
                            let fit = self.fitter.to_sample(&p);
                            match continuation {
                                Some((e, map)) if e < output(fit) => (Some(Ok(map)), true),
                                _ => (Some(Ok(fit)), false),
                            }
                        }
                        Err(unplaced) => (Some(Err(unplaced)), false),
                    },
                }
            }
            None => (None, false),
        };
        let (mask_to_sample, origin, fitted) = match fitted {
            Some(Ok(map)) => (map, origin, true),
            Some(Err(Unplaced::TooLarge)) if !single => return Ok((Outcome::TooLarge, None)),
            // No textured neighbour (or a single face too large to match): a random placement.
            _ => {
                let (lo, hi) = bounds(footprint());
                let placement = match self.random_placement(lo, hi, oriented.map(|_| 0), rng) {
                    Some(p) => p,
                    None if single => self.forced_placement(lo, hi),
                    None => return Ok((Outcome::TooLarge, None)),
                };
                (self.fitter.to_sample(&placement), lo, false)
            }
        };
        // Chart texels → mask pixels → sample.
        let mut to_sample = mask_to_sample * to_frame(origin);
        let image = &self.fitter.image;
        if image.tileable {
            // Keep coordinates near the sample: whole periods change nothing.
            let centre = local.iter().copied().sum::<Vec2>() / local.len().max(1) as f32;
            let s = to_sample.transform_point2(centre);
            let (w, h) = (image.width as f32, image.height as f32);
            to_sample.translation -= Vec2::new((s.x / w).floor() * w, (s.y / h).floor() * h);
        }
        let mut uv: Vec<Vec2> = local.iter().map(|&p| to_sample.transform_point2(p)).collect();
        if self.params.relax && !band.is_empty() && !single {
            super::relax::relax(self, c, chart, &mut uv, mapping, rng);
        }
        // The paper's test (§2.2 step 4, §4.4): the output error, along the shared edges
        // once relaxed, against the threshold. The mask's own error chose the placement but
        // does not decide: it also counts the band's texels away from the border, which no
        // seam shows (on the bunny at the default scale, deciding on it mapped 29 clusters
        // of level 4, on this 82, for a mean jump at the borders of 0.27 against 0.30).
        let error = if fitted { super::relax::output_error(self, c, chart, &uv, mapping) } else { None };
        if !single && error.is_some_and(|e| e > self.params.max_fit_error) {
            return Ok((Outcome::PoorFit, error));
        }
        let started = !fitted;
        mapping.started_pieces.insert(piece);
        for (&f, corners) in cluster.faces.iter().zip(&chart.corners) {
            mapping.mapped_by[f as usize] = c;
            mapping.face_uv[f as usize] = corners.map(|i| uv[i as usize]);
        }
        Ok((Outcome::Mapped { started, continued: continued && fitted }, error))
    }

    /// The best exact continuation of a textured neighbour for a single face (of
    /// [`Mapper::continuations`], the one of least mask error), scored on the whole mask.
    /// Returns the mask → sample map and its error (as [`Fitter::fit`] measures it).
    ///
    /// [`Fitter::fit`]: super::fit::Fitter::fit
    fn best_continuation(
        &self,
        band: &[(u32, [Vec2; 3])],
        mask: &Mask,
        origin: Vec2,
        local: &[Vec2],
        mapping: &Mapping,
    ) -> Option<(Affine2, f32)> {
        let image = &self.fitter.image;
        self.continuations(band, origin, local, mapping)
            .into_iter()
            .map(|map| (map, mask.error_at(image, map)))
            .min_by(|a, b| a.1.total_cmp(&b.1))
    }

    /// The exact continuations of the textured neighbours in `band`: per neighbouring patch,
    /// the rotation and translation that carry the band's mask positions (chart texels
    /// mirrored, minus `origin`) onto that patch's own sample coordinates (least squares),
    /// as a mask → sample map; only those that keep the footprint (`local`) inside a sample
    /// that does not tile. In the patches' order.
    fn continuations(
        &self,
        band: &[(u32, [Vec2; 3])],
        origin: Vec2,
        local: &[Vec2],
        mapping: &Mapping,
    ) -> Vec<Affine2> {
        let image = &self.fitter.image;
        let mut owners: Vec<u32> = band.iter().map(|(g, _)| mapping.mapped_by[*g as usize]).collect();
        owners.sort_unstable();
        owners.dedup();
        let mut found = Vec::new();
        for owner in owners {
            let pairs: Vec<(Vec2, Vec2)> = band
                .iter()
                .filter(|(g, _)| mapping.mapped_by[*g as usize] == owner)
                .flat_map(|(g, p)| {
                    (0..3).map(move |k| (mirror(p[k]) - origin, mapping.face_uv[*g as usize][k]))
                })
                .collect();
            let n = pairs.len() as f32;
            let (cm, cs) =
                pairs.iter().fold((Vec2::ZERO, Vec2::ZERO), |(a, b), (m, s)| (a + *m / n, b + *s / n));
            let (dot, cross) = pairs.iter().fold((0f32, 0f32), |(d, c), (m, s)| {
                let (m, s) = (*m - cm, *s - cs);
                (d + m.dot(s), c + m.perp_dot(s))
            });
            let rotation = Mat2::from_angle(cross.atan2(dot));
            let map = Affine2::from_mat2_translation(rotation, cs - rotation * cm);
            if local.iter().all(|&p| image.inside(map.transform_point2(mirror(p) - origin))) {
                found.push(map);
            }
        }
        found
    }

    /// Whether a footprint (chart vertices in texels) could lie inside the sample at some
    /// rotation: its shorter side within the sample's longer, its longer within the
    /// diagonal (a tileable sample takes up to its own size).
    fn may_fit(&self, local: &[Vec2]) -> bool {
        let (lo, hi) = bounds(local.iter().copied());
        let size = hi - lo;
        let image = &self.fitter.image;
        let (w, h) = (image.width as f32, image.height as f32);
        let (short, long) = (size.x.min(size.y), size.x.max(size.y));
        short <= w.max(h) && long <= (w * w + h * h).sqrt()
    }

    /// The angle to turn `chart` by so that, placed unrotated in the sample, the sample's
    /// up (decreasing rows, +y of the turned chart before it is mirrored to rows) points
    /// `degrees` counter-clockwise from the model's +Y axis as it lies on the chart (+X
    /// where the chart's plane holds too little of Y).
    fn start_angle(&self, chart: &Chart, degrees: f32) -> f32 {
        let graph = self.graph;
        let n = chart.vertices.len().max(1) as f32;
        let q0 = chart.vertices.iter().map(|&(_, q)| q).sum::<Vec2>() / n;
        let p0 = chart.vertices.iter().map(|&(v, _)| graph.positions[v as usize]).sum::<glam::Vec3>() / n;
        // The linear map A (chart → model) of least squares: A = (Σ P qᵀ)(Σ q qᵀ)⁻¹.
        let (mut pq, mut qq) = ([glam::Vec3::ZERO; 2], Mat2::ZERO);
        for &(v, q) in &chart.vertices {
            let (q, p) = (q - q0, graph.positions[v as usize] - p0);
            pq[0] += p * q.x;
            pq[1] += p * q.y;
            qq += Mat2::from_cols(q * q.x, q * q.y);
        }
        let inverse = if qq.determinant().abs() > 1e-20 { qq.inverse() } else { Mat2::IDENTITY };
        let (ax, ay) = (
            pq[0] * inverse.x_axis.x + pq[1] * inverse.x_axis.y,
            pq[0] * inverse.y_axis.x + pq[1] * inverse.y_axis.y,
        );
        // The chart direction of an axis: Aᵀ axis, good enough for a near-isometric A.
        let along = |axis: glam::Vec3| Vec2::new(ax.dot(axis), ay.dot(axis));
        let scale = ax.length().max(ay.length()).max(f32::MIN_POSITIVE);
        let up = along(glam::Vec3::Y);
        let d = if up.length() > 0.3 * scale { up } else { along(glam::Vec3::X) };
        std::f32::consts::FRAC_PI_2 - (d.to_angle() + degrees.to_radians())
    }

    /// A random placement of a footprint spanning `lo..hi` (mask pixels) with the
    /// footprint inside the sample, at one of the fitter's rotations (`rotation` if given).
    fn random_placement(
        &self,
        lo: Vec2,
        hi: Vec2,
        rotation: Option<usize>,
        rng: &mut ChaCha8Rng,
    ) -> Option<Placement> {
        let size = (hi - lo).ceil() + Vec2::ONE;
        let (mw, mh) = (size.x as usize, size.y as usize);
        let count = self.fitter.rotation_count();
        let first = rng.random_range(0..count);
        let tries = if rotation.is_some() { 1 } else { count };
        for k in (0..tries).map(|i| rotation.unwrap_or((first + i) % count)) {
            let rows = self.fitter.positions(k, mw, mh);
            let total: i64 = rows.iter().map(|&(a, b)| (b - a + 1).max(0)).sum();
            if total <= 0 {
                continue;
            }
            let mut pick = rng.random_range(0..total);
            for (y, &(a, b)) in rows.iter().enumerate() {
                let n = (b - a + 1).max(0);
                if pick < n {
                    return Some(Placement { rotation: k, position: ((a + pick) as usize, y), error: 0.0 });
                }
                pick -= n;
            }
        }
        None
    }

    /// A face larger than the sample allows: at the sample's middle, unturned.
    fn forced_placement(&self, lo: Vec2, hi: Vec2) -> Placement {
        let image = &self.fitter.image;
        let middle = Vec2::new(image.width as f32, image.height as f32) / 2.0 - (hi - lo) / 2.0;
        let fallback = Placement { rotation: 0, position: (0, 0), error: 0.0 };
        let shift = self.fitter.to_sample(&fallback).transform_point2(Vec2::ZERO);
        let at = (middle - shift).max(Vec2::ZERO);
        Placement { rotation: 0, position: (at.x as usize, at.y as usize), error: 0.0 }
    }

    /// Textured faces outside cluster `c` within the band width of its border, unfolded
    /// into its frame (`local`: the chart's vertices in texels): (face, corner positions).
    pub(super) fn band(
        &self,
        c: u32,
        chart: &Chart,
        local: &[Vec2],
        mapping: &Mapping,
    ) -> Vec<(u32, [Vec2; 3])> {
        let (graph, h) = (self.graph, self.hierarchy);
        let cluster = &h.clusters[c as usize];
        let owner = &h.owner[cluster.level as usize];
        let outside = |g: u32| g != NONE && owner[g as usize] != c && mapping.mapped_by[g as usize] != NONE;
        let width = self.params.band / self.params.texels_per_unit;
        // Geodesic distance from the border over textured faces outside (Dijkstra).
        let mut dist: HashMap<u32, f32> = cluster.border.iter().map(|&v| (v, 0.0)).collect();
        let mut heap: BinaryHeap<(std::cmp::Reverse<u32>, u32)> =
            cluster.border.iter().map(|&v| (std::cmp::Reverse(0), v)).collect();
        while let Some((std::cmp::Reverse(bits), v)) = heap.pop() {
            let d = f32::from_bits(bits);
            if d > dist[&v] || d > width {
                continue;
            }
            for &g in graph.faces_of(v) {
                if !outside(g) {
                    continue;
                }
                for &w in &graph.corners[g as usize] {
                    let nd = d + graph.positions[v as usize].distance(graph.positions[w as usize]);
                    if dist.get(&w).is_none_or(|&old| nd < old) {
                        dist.insert(w, nd);
                        heap.push((std::cmp::Reverse(nd.to_bits()), w));
                    }
                }
            }
        }
        let mut placed: HashMap<u32, Vec2> =
            chart.vertices.iter().zip(local).map(|(&(v, _), &p)| (v, p)).collect();
        let mut queue: VecDeque<u32> = VecDeque::new();
        let mut seen: HashMap<u32, ()> = HashMap::new();
        for &f in &cluster.faces {
            for &g in &graph.across[f as usize] {
                if outside(g) && seen.insert(g, ()).is_none() {
                    queue.push_back(g);
                }
            }
        }
        let scale = self.params.texels_per_unit;
        let mut band = Vec::new();
        while let Some(g) = queue.pop_front() {
            let t = graph.corners[g as usize];
            let known: Vec<bool> = t.iter().map(|v| placed.contains_key(v)).collect();
            match known.iter().filter(|&&k| k).count() {
                3 => {}
                2 => {
                    let k = (0..3).find(|&k| known[k] && known[(k + 1) % 3]).unwrap_or(0);
                    let (a, b, apex) = (t[k], t[(k + 1) % 3], t[(k + 2) % 3]);
                    let p = |v: u32| graph.positions[v as usize];
                    let (la, lb) = (p(a).distance(p(apex)) * scale, p(b).distance(p(apex)) * scale);
                    let at = unfold(placed[&a], placed[&b], la, lb);
                    placed.insert(apex, at);
                }
                _ => continue,
            }
            if t.iter().all(|v| dist.get(v).is_none_or(|&d| d > width)) {
                continue;
            }
            band.push((g, t.map(|v| placed[&v])));
            for &n in &graph.across[g as usize] {
                if outside(n) && seen.insert(n, ()).is_none() {
                    queue.push_back(n);
                }
            }
        }
        band
    }

    /// The band drawn in mask pixels (chart texels mirrored to image rows, minus `origin`)
    /// with the neighbours' texture, cut to the pixels within the band's width of the
    /// cluster's own footprint (`chart` at `local`).
    ///
    /// [`Mapper::band`] selects whole faces (any face with a corner within the band), so
    /// where faces are wider than the band, uncut, the mask would reach a whole ring of
    /// faces into the neighbours (about 20 texels per face edge on the bunny at the default
    /// scale, for a 6-texel band) and the fit would match a region of the neighbours rather than their
    /// texture along the border, which the paper's band, cut *within* the triangles
    /// (§4.1: the portion of the triangles whose position value is under the threshold),
    /// does not ask.
    fn mask(
        &self,
        band: &[(u32, [Vec2; 3])],
        (chart, local): (&Chart, &[Vec2]),
        origin: Vec2,
        hi: Vec2,
        mapping: &Mapping,
    ) -> Mask {
        let image = &self.fitter.image;
        let size = (hi - origin).ceil() + Vec2::splat(2.0);
        let (w, h) = (size.x.max(1.0) as usize, size.y.max(1.0) as usize);
        // Distance (texels) of every pixel to the footprint: 0 inside, then a two-pass
        // chamfer transform (steps 1 and √2, within 8% of the Euclidean distance).
        let mut near = vec![f32::INFINITY; w * h];
        for corners in &chart.corners {
            let p = corners.map(|i| mirror(local[i as usize]) - origin);
            raster(&p, w, h, |x, y, _| near[y * w + x] = 0.0);
        }
        chamfer(&mut near, w, h);
        let channels = image.channels;
        let mut values = vec![0f32; channels * w * h];
        let mut support = vec![0f32; w * h];
        let mut value = vec![0f32; channels];
        let width = self.params.band;
        for (g, corners) in band {
            let p = corners.map(|c| mirror(c) - origin);
            let uv = mapping.face_uv[*g as usize];
            raster(&p, w, h, |x, y, b| {
                let o = y * w + x;
                if support[o] > 0.0 || near[o] > width {
                    return;
                }
                support[o] = 1.0;
                image.sample(b[0] * uv[0] + b[1] * uv[1] + b[2] * uv[2], &mut value);
                for ch in 0..channels {
                    values[ch * w * h + o] = value[ch];
                }
            });
        }
        Mask { width: w, height: h, values, support }
    }
}

/// Two-pass chamfer distance transform in place (`d`: 0 at the sources, infinite elsewhere).
fn chamfer(d: &mut [f32], w: usize, h: usize) {
    const DIAGONAL: f32 = std::f32::consts::SQRT_2;
    for y in 0..h {
        for x in 0..w {
            let mut v = d[y * w + x];
            if x > 0 {
                v = v.min(d[y * w + x - 1] + 1.0);
            }
            if y > 0 {
                v = v.min(d[(y - 1) * w + x] + 1.0);
                if x > 0 {
                    v = v.min(d[(y - 1) * w + x - 1] + DIAGONAL);
                }
                if x + 1 < w {
                    v = v.min(d[(y - 1) * w + x + 1] + DIAGONAL);
                }
            }
            d[y * w + x] = v;
        }
    }
    for y in (0..h).rev() {
        for x in (0..w).rev() {
            let mut v = d[y * w + x];
            if x + 1 < w {
                v = v.min(d[y * w + x + 1] + 1.0);
            }
            if y + 1 < h {
                v = v.min(d[(y + 1) * w + x] + 1.0);
                if x + 1 < w {
                    v = v.min(d[(y + 1) * w + x + 1] + DIAGONAL);
                }
                if x > 0 {
                    v = v.min(d[(y + 1) * w + x - 1] + DIAGONAL);
                }
            }
            d[y * w + x] = v;
        }
    }
}

/// Chart texels (counter-clockwise, y up) to image orientation (rows down).
pub(super) fn mirror(p: Vec2) -> Vec2 {
    Vec2::new(p.x, -p.y)
}

fn bounds(points: impl Iterator<Item = Vec2>) -> (Vec2, Vec2) {
    points.fold((Vec2::splat(f32::INFINITY), Vec2::splat(f32::NEG_INFINITY)), |(lo, hi), p| {
        (lo.min(p), hi.max(p))
    })
}

/// Calls `pixel(x, y, barycentric)` for every pixel centre of a `w × h` frame inside
/// triangle `p`.
pub(super) fn raster(p: &[Vec2; 3], w: usize, h: usize, mut pixel: impl FnMut(usize, usize, [f32; 3])) {
    let lo = p[0].min(p[1]).min(p[2]).ceil().max(Vec2::ZERO);
    let hi = p[0].max(p[1]).max(p[2]).floor().min(Vec2::new(w as f32 - 1.0, h as f32 - 1.0));
    let d = (p[1] - p[0]).perp_dot(p[2] - p[0]);
    if d.abs() < 1e-12 || lo.x > hi.x || lo.y > hi.y {
        return;
    }
    for y in lo.y as usize..=hi.y as usize {
        for x in lo.x as usize..=hi.x as usize {
            let q = Vec2::new(x as f32, y as f32);
            let b1 = (q - p[0]).perp_dot(p[2] - p[0]) / d;
            let b2 = (p[1] - p[0]).perp_dot(q - p[0]) / d;
            let b0 = 1.0 - b1 - b2;
            if b0 >= -1e-4 && b1 >= -1e-4 && b2 >= -1e-4 {
                pixel(x, y, [b0, b1, b2]);
            }
        }
    }
}
