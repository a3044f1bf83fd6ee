//! k-nearest-neighbour lists for k-coherence search (Tong et al. §5.2).
//!
//! For every pixel of a texton map, the k − 1 pixels whose neighbourhoods are closest in
//! texton space, Σ over a square neighbourhood of ‖t_a − t_b‖² (through Γ), after the pixel
//! itself, which is always the first entry: `k = 1` is Ashikhmin's coherence search.
//!
//! Rules:
//! - The pixel and its 8 immediate neighbours are never among its neighbours (they would
//!   only echo the coherence candidate itself).
//! - Non-tileable samples: neighbourhoods never read across the border. A candidate must
//!   have its whole neighbourhood inside the sample; for a query pixel near the border only
//!   the offsets that fall inside are compared (the same offsets for every candidate, so
//!   the comparison stays fair). Tileable samples wrap around.
//! - Levels up to [`EXHAUSTIVE_LIMIT`] pixels are searched exhaustively; larger levels use
//!   the paper's two-level scheme: the `m` best candidates of the parent pixel on the next
//!   coarser level, each expanded to its four children.
//! - Two-level neighbourhoods (for the second synthesis pass) append the parent pixel's
//!   neighbourhood on the coarser level, of size [`parent_size`].

use crate::sentinel::OUTSIDE;
use rayon::prelude::*;
use std::collections::BinaryHeap;

/// Levels with at most this many pixels (64 × 64) are searched exhaustively.
pub const EXHAUSTIVE_LIMIT: usize = 64 * 64;
/// Coarse candidates per pixel in the two-level search (the paper's m).
pub const COARSE_CANDIDATES: usize = 100;

/// A texton label per pixel, row-major.
#[derive(Clone, Debug, PartialEq)]
pub struct TextonMap {
    /// Columns of the map.
    pub width: usize,
    /// Rows of the map.
    pub height: usize,
    /// `width × height` labels, row `y` at `y * width`; a label is a texton index.
    pub labels: Vec<u16>,
}

/// One pyramid level as the search sees it: the map and the texton distance table
/// (`textons × textons`, row-major, from [`super::gamma::distance_table`]).
#[derive(Clone, Copy)]
pub struct Level<'a> {
    /// The level's texton map.
    pub map: &'a TextonMap,
    /// `textons × textons` squared texton distances ‖tᵢ − tⱼ‖², row-major.
    pub distances: &'a [f32],
    /// Number of rows (and columns) of `distances`.
    pub textons: usize,
}

/// What the lists are built with.
#[derive(Clone, Copy, Debug)]
pub struct KnnParams {
    /// List length including the pixel itself (default 11, the paper's).
    pub k: usize,
    /// Side of the square neighbourhood in pixels, odd (default 5).
    pub neighborhood: usize,
    /// Whether the sample wraps around (default false).
    pub tileable: bool,
}

impl Default for KnnParams {
    fn default() -> Self {
        KnnParams { k: 11, neighborhood: 5, tileable: false }
    }
}

/// Side of the parent-level part of a two-level neighbourhood: about half the fine side, odd,
/// at least 3 (5 → 3, 7 → 3, 9 → 5), as in Wei and Levoy's two-level neighbourhoods.
pub fn parent_size(neighborhood: usize) -> usize {
    (neighborhood / 2).max(3) | 1
}

/// The k-lists of `pyramid[level]` with single-level neighbourhoods, `[pixels][k]`.
pub fn single_level_lists(pyramid: &[Level], level: usize, params: &KnnParams) -> Vec<u32> {
    PyramidSearch::new(pyramid, *params).single_level(level)
}

/// The k-lists of `pyramid[level]` with two-level neighbourhoods (this level plus the
/// parent's on `level + 1`), `[pixels][k]`. `level + 1` must exist.
pub fn two_level_lists(pyramid: &[Level], level: usize, params: &KnnParams) -> Vec<u32> {
    PyramidSearch::new(pyramid, *params).two_level(level)
}

/// The lists of every level of one pyramid. A large level's candidates are its parent's
/// [`COARSE_CANDIDATES`]-lists on the next coarser level, which the single- and two-level
/// lists of that level and of its own parent all read: kept here, each is searched once
/// (at 512² the coarsest level's exhaustive search was otherwise run five times).
pub struct PyramidSearch<'a> {
    pyramid: &'a [Level<'a>],
    params: KnnParams,
    /// Per level, its single-level lists of `COARSE_CANDIDATES + 1` entries, once made.
    candidate_lists: Vec<Option<Vec<u32>>>,
}

impl<'a> PyramidSearch<'a> {
    /// A search over `pyramid` (finest level first) with `params`; lists are made on demand.
    pub fn new(pyramid: &'a [Level<'a>], params: KnnParams) -> Self {
        PyramidSearch { pyramid, params, candidate_lists: vec![None; pyramid.len()] }
    }

    /// The k-lists of `level` with single-level neighbourhoods, `[pixels][k]`.
    pub fn single_level(&mut self, level: usize) -> Vec<u32> {
        let k = self.params.k;
        if self.supplies_candidates(level) && k <= COARSE_CANDIDATES + 1 {
            // The nearest k of a list ordered by (distance, index) are its first k.
            return self
                .candidates(level)
                .chunks(COARSE_CANDIDATES + 1)
                .flat_map(|l| &l[..k])
                .copied()
                .collect();
        }
        let features =
            Features::new(&[(self.pyramid[level], self.params.neighborhood)], self.params.tileable);
        self.lists(level, &features, k)
    }

    /// The k-lists of `level` with two-level neighbourhoods (this level plus the parent's on
    /// `level + 1`), `[pixels][k]`. `level + 1` must exist.
    pub fn two_level(&mut self, level: usize) -> Vec<u32> {
        let n = self.params.neighborhood;
        let parts = [(self.pyramid[level], n), (self.pyramid[level + 1], parent_size(n))];
        let features = Features::new(&parts, self.params.tileable);
        self.lists(level, &features, self.params.k)
    }

    /// `(single_level(level), two_level(level))`, in one pass over the candidates where both
    /// come from the parent's lists. `level + 1` must exist.
    pub fn single_and_two_level(&mut self, level: usize) -> (Vec<u32>, Vec<u32>) {
        if !self.searched_through_parent(level) || self.supplies_candidates(level) {
            return (self.single_level(level), self.two_level(level));
        }
        let (map, parent) = (self.pyramid[level].map, self.pyramid[level + 1].map);
        let (k, tileable, n) = (self.params.k, self.params.tileable, self.params.neighborhood);
        let parts = [(self.pyramid[level], n), (self.pyramid[level + 1], parent_size(n))];
        let features = Features::new(&parts, tileable);
        let parent_lists = self.candidates(level + 1);
        let (single, two): (Vec<Vec<u32>>, Vec<Vec<u32>>) = (0..map.width * map.height)
            .into_par_iter()
            .map(|a| {
                let cands =
                    children_of_parent_candidates(map, parent, parent_lists, a, COARSE_CANDIDATES + 1);
                let (single, two) =
                    features.nearest_among_both(a, &cands, k.saturating_sub(1), map, tileable);
                (padded(a, &single, k), padded(a, &two, k))
            })
            .unzip();
        (single.concat(), two.concat())
    }

    /// Whether the next finer level takes its candidates from this one's lists.
    fn supplies_candidates(&self, level: usize) -> bool {
        level > 0 && self.searched_through_parent(level - 1)
    }

    fn searched_through_parent(&self, level: usize) -> bool {
        let map = self.pyramid[level].map;
        map.width * map.height > EXHAUSTIVE_LIMIT && level + 1 < self.pyramid.len()
    }

    /// `level`'s single-level lists of `COARSE_CANDIDATES + 1` entries, searched on first use.
    fn candidates(&mut self, level: usize) -> &[u32] {
        if self.candidate_lists[level].is_none() {
            let features =
                Features::new(&[(self.pyramid[level], self.params.neighborhood)], self.params.tileable);
            let lists = self.lists(level, &features, COARSE_CANDIDATES + 1);
            self.candidate_lists[level] = Some(lists);
        }
        self.candidate_lists[level].as_deref().unwrap_or_default()
    }

    fn lists(&mut self, level: usize, features: &Features, k: usize) -> Vec<u32> {
        let map = self.pyramid[level].map;
        let count = k.saturating_sub(1);
        let pixels = map.width * map.height;
        let tileable = self.params.tileable;
        let through_parent = self.searched_through_parent(level);
        if through_parent {
            self.candidates(level + 1);
        }
        let parent = self.pyramid.get(level + 1).map(|l| l.map);
        let parent_lists =
            self.candidate_lists.get(level + 1).and_then(Option::as_deref).filter(|_| through_parent);
        let every_pixel = match parent_lists {
            Some(_) => AllPixels::SlotMajor(Vec::new()),
            None => AllPixels::new(features, self.pyramid[level], self.params.neighborhood, tileable),
        };
        (0..pixels)
            .into_par_iter()
            .map_init(Vec::new, |distances, a| {
                let nearest = match (parent_lists, parent) {
                    (Some(lists), Some(parent)) => {
                        let cands =
                            children_of_parent_candidates(map, parent, lists, a, COARSE_CANDIDATES + 1);
                        features.nearest_among(a, &cands, count, map, tileable)
                    }
                    _ => features.nearest_of_all(a, &every_pixel, distances, count, map, tileable),
                };
                padded(a, &nearest, k)
            })
            .flatten_iter()
            .collect()
    }
}

/// A pixel's list: itself, then its nearest, `k` entries in all.
fn padded(a: usize, nearest: &[u32], k: usize) -> Vec<u32> {
    let mut list = Vec::with_capacity(k);
    list.push(a as u32);
    list.extend_from_slice(nearest);
    // Tiny samples may not have k − 1 eligible pixels: repeat the last one found.
    while list.len() < k {
        list.push(*list.last().unwrap_or(&(a as u32)));
    }
    list.truncate(k.max(1));
    list
}

/// The four children of each coarse candidate of `a`'s parent.
fn children_of_parent_candidates(
    fine: &TextonMap,
    coarse: &TextonMap,
    parent_lists: &[u32],
    a: usize,
    stride: usize,
) -> Vec<u32> {
    let (x, y) = (a % fine.width, a / fine.width);
    let parent = (y / 2).min(coarse.height - 1) * coarse.width + (x / 2).min(coarse.width - 1);
    let mut out = Vec::with_capacity(4 * stride);
    let list = &parent_lists[parent * stride..(parent + 1) * stride];
    // A list repeats only its last entry (a tiny sample's padding), and distinct parents
    // have distinct children; the order does not matter to `nearest_among`.
    for (_, &c) in list.iter().enumerate().filter(|&(i, &c)| i == 0 || list[i - 1] != c) {
        let (cx, cy) = (c as usize % coarse.width, c as usize / coarse.width);
        for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
            let (fx, fy) = (2 * cx + dx, 2 * cy + dy);
            if fx < fine.width && fy < fine.height {
                out.push((fy * fine.width + fx) as u32);
            }
        }
    }
    out
}

/// Every pixel's neighbourhood as labels in one combined texton index space (each level's
/// textons offset after the previous level's), with one block-diagonal distance table.
struct Features {
    len: usize,
    labels: Vec<u32>,
    eligible: Vec<bool>,
    /// Slots of the first part (this level's own neighbourhood), and the pixels eligible by
    /// it alone: what the single-level search of the same level sees.
    fine_len: usize,
    fine_eligible: Vec<bool>,
    table: Vec<f32>,
    textons: usize,
}

impl Features {
    fn new(parts: &[(Level, usize)], tileable: bool) -> Self {
        let fine = parts[0].0.map;
        let pixels = fine.width * fine.height;
        let len: usize = parts.iter().map(|(_, s)| s * s).sum();
        let textons: usize = parts.iter().map(|(l, _)| l.textons).sum();
        let mut labels = vec![OUTSIDE; pixels * len];
        let mut eligible = vec![true; pixels];
        let mut fine_eligible = Vec::new();
        let mut table = vec![0.0; textons * textons];
        let (mut slot, mut base) = (0, 0);
        for (level, size) in parts {
            let scale = fine.width.div_ceil(level.map.width).max(1);
            for p in 0..pixels {
                let (x, y) = ((p % fine.width) / scale, (p / fine.width) / scale);
                let inside =
                    write_patch(level.map, x, y, *size, tileable, base, &mut labels[p * len + slot..]);
                eligible[p] &= inside;
            }
            for i in 0..level.textons {
                let row = &level.distances[i * level.textons..(i + 1) * level.textons];
                table[(base + i) * textons + base..(base + i) * textons + base + level.textons]
                    .copy_from_slice(row);
            }
            slot += size * size;
            base += level.textons;
            if fine_eligible.is_empty() {
                fine_eligible = anywhere_if_nowhere(eligible.clone());
            }
        }
        let fine_len = parts[0].1 * parts[0].1;
        Features {
            len,
            labels,
            eligible: anywhere_if_nowhere(eligible),
            fine_len,
            fine_eligible,
            table,
            textons,
        }
    }

    /// The table row of each slot of `a`'s neighbourhood that lies inside the sample (the
    /// others compare nothing).
    fn query_rows(&self, a: usize) -> Vec<(usize, &[f32])> {
        let query = &self.labels[a * self.len..(a + 1) * self.len];
        query
            .iter()
            .enumerate()
            .filter(|(_, &l)| l != OUTSIDE)
            .map(|(slot, &l)| (slot, &self.table[l as usize * self.textons..(l as usize + 1) * self.textons]))
            .collect()
    }

    /// The `count` eligible `candidates` nearest to `a`, nearest first, ties by index.
    fn nearest_among(
        &self,
        a: usize,
        candidates: &[u32],
        count: usize,
        map: &TextonMap,
        tileable: bool,
    ) -> Vec<u32> {
        let rows = self.query_rows(a);
        let mut best = Best::new(count);
        let eligible: Vec<u32> = candidates.iter().copied().filter(|&b| self.eligible[b as usize]).collect();
        for batch in eligible.chunks(LANES) {
            let bound = best.bound();
            let distances = self.batch_within(&rows, batch, |_| bound);
            for (&b, d) in batch.iter().zip(distances) {
                if let Some(d) = d.filter(|_| !adjacent(map, a, b as usize, tileable)) {
                    best.offer(Scored(d, b));
                }
            }
        }
        best.into_sorted()
    }

    /// The distances of up to [`LANES`] candidates from their first slot, each against the
    /// bound `bound` gives it: see [`sums_within`].
    fn batch_within(
        &self,
        rows: &[(usize, &[f32])],
        batch: &[u32],
        bound: impl Fn(u32) -> f32,
    ) -> [Option<f32>; LANES] {
        let mut cands = [&[][..]; LANES];
        let mut bounds = [f32::NEG_INFINITY; LANES];
        for (lane, &b) in batch.iter().enumerate() {
            cands[lane] = &self.labels[b as usize * self.len..(b as usize + 1) * self.len];
            bounds[lane] = bound(b);
        }
        sums_within(rows, cands, bounds)
    }

    /// [`Self::nearest_among`] for the two-level neighbourhoods these features hold and, in
    /// the same pass, for the single-level ones of their first part: the single-level
    /// distance is the two-level sum's prefix (the same terms in the same order), so each
    /// candidate's labels are read once for both lists.
    fn nearest_among_both(
        &self,
        a: usize,
        candidates: &[u32],
        count: usize,
        map: &TextonMap,
        tileable: bool,
    ) -> (Vec<u32>, Vec<u32>) {
        let rows = self.query_rows(a);
        let (fine_rows, parent_rows) = rows.split_at(rows.partition_point(|(slot, _)| *slot < self.fine_len));
        let (mut single, mut two) = (Best::new(count), Best::new(count));
        let bound = |eligible: bool, best: &Best| if eligible { best.bound() } else { f32::NEG_INFINITY };
        for batch in candidates.chunks(LANES) {
            let fine_bound = |b: u32| {
                bound(self.fine_eligible[b as usize], &single).max(bound(self.eligible[b as usize], &two))
            };
            let fines = self.batch_within(fine_rows, batch, fine_bound);
            for (&b, fine) in batch.iter().zip(fines) {
                let Some(fine) = fine.filter(|_| !adjacent(map, a, b as usize, tileable)) else {
                    continue;
                };
                if fine <= bound(self.fine_eligible[b as usize], &single) {
                    single.offer(Scored(fine, b));
                }
                let two_bound = bound(self.eligible[b as usize], &two);
                if fine <= two_bound {
                    let cand = &self.labels[b as usize * self.len..(b as usize + 1) * self.len];
                    if let Some(d) = continue_within(parent_rows, cand, two_bound, fine) {
                        two.offer(Scored(d, b));
                    }
                }
            }
        }
        (single.into_sorted(), two.into_sorted())
    }

    /// [`Self::nearest_among`] every pixel, the distances summed slot by slot (see
    /// [`AllPixels`]): streaming a slot's values for every pixel costs a fraction of
    /// gathering each candidate's neighbourhood, which matters where the search is
    /// exhaustive over a coarsest level of 128² pixels. The terms are added in the order
    /// [`continue_within`] adds them, so the lists are the same.
    fn nearest_of_all(
        &self,
        a: usize,
        every_pixel: &AllPixels,
        distances: &mut Vec<f32>,
        count: usize,
        map: &TextonMap,
        tileable: bool,
    ) -> Vec<u32> {
        let pixels = self.eligible.len();
        distances.clear();
        distances.resize(pixels, -0.0);
        match every_pixel {
            AllPixels::Planes(planes) => {
                for (slot, &q) in self.labels[a * self.len..(a + 1) * self.len].iter().enumerate() {
                    if q != OUTSIDE {
                        planes.add(q as usize, slot, distances);
                    }
                }
            }
            AllPixels::SlotMajor(by_slot) => {
                // The query's row with a zero after it, where the slot-major labels put OUTSIDE.
                let mut row = vec![0.0f32; self.textons + 1];
                for (slot, query_row) in self.query_rows(a) {
                    row[..self.textons].copy_from_slice(query_row);
                    for (d, &l) in distances.iter_mut().zip(&by_slot[slot * pixels..(slot + 1) * pixels]) {
                        *d += row[l as usize];
                    }
                }
            }
        }
        let mut best = Best::new(count);
        for (b, &d) in distances.iter().enumerate() {
            if d <= best.bound() && self.eligible[b] && !adjacent(map, a, b, tileable) {
                best.offer(Scored(d, b as u32));
            }
        }
        best.into_sorted()
    }

    /// The labels slot by slot, `[slot][pixel]`, a slot outside the sample as `textons`.
    fn slot_major(&self) -> Vec<u32> {
        let pixels = self.eligible.len();
        let mut by_slot = vec![0u32; self.len * pixels];
        for (p, labels) in self.labels.chunks_exact(self.len).enumerate() {
            for (slot, &l) in labels.iter().enumerate() {
                by_slot[slot * pixels + p] = if l == OUTSIDE { self.textons as u32 } else { l };
            }
        }
        by_slot
    }
}

/// A sample smaller than its neighbourhood has no pixel wholly inside: then every pixel is
/// a candidate, compared on the offsets that exist.
fn anywhere_if_nowhere(mut eligible: Vec<bool>) -> Vec<bool> {
    if !eligible.iter().any(|&e| e) {
        eligible.iter_mut().for_each(|e| *e = true);
    }
    eligible
}

/// How an exhaustive search sums every pixel's distance to a query.
enum AllPixels {
    /// Single-level neighbourhoods: see [`Planes`].
    Planes(Planes),
    /// Any neighbourhood: the labels slot by slot, `[slot][pixel]` (see [`Features::slot_major`]).
    SlotMajor(Vec<u32>),
}

impl AllPixels {
    fn new(features: &Features, level: Level, size: usize, tileable: bool) -> Self {
        match Planes::new(features, level, size, tileable) {
            Some(planes) => AllPixels::Planes(planes),
            None => AllPixels::SlotMajor(features.slot_major()),
        }
    }
}

/// Every texton's distance to every label of the map padded by the neighbourhood's radius
/// (wrapped, or a zero outside a sample that does not tile): a query slot of texton t
/// then adds plane t shifted by the slot's offset, a contiguous run per row that the
/// compiler vectorises.
struct Planes {
    width: usize,
    height: usize,
    size: usize,
    padded_width: usize,
    padded_pixels: usize,
    values: Vec<f32>,
}

impl Planes {
    /// Most values the planes may hold (256 MiB); a larger search sums slot-major labels.
    const MAX_VALUES: usize = 1 << 26;

    /// Planes for `features` when they are `level`'s own single-level neighbourhoods.
    fn new(features: &Features, level: Level, size: usize, tileable: bool) -> Option<Self> {
        let map = level.map;
        let r = size / 2;
        let (pw, ph) = (map.width + 2 * r, map.height + 2 * r);
        let single_level = features.len == size * size && features.textons == level.textons;
        if !single_level || level.textons * pw * ph > Self::MAX_VALUES {
            return None;
        }
        let padded: Vec<Option<u16>> = (0..pw * ph)
            .map(|i| {
                let (mut x, mut y) = ((i % pw) as isize - r as isize, (i / pw) as isize - r as isize);
                if tileable {
                    x = x.rem_euclid(map.width as isize);
                    y = y.rem_euclid(map.height as isize);
                }
                let inside = (0..map.width as isize).contains(&x) && (0..map.height as isize).contains(&y);
                inside.then(|| map.labels[y as usize * map.width + x as usize])
            })
            .collect();
        let values = (0..level.textons)
            .flat_map(|t| {
                let row = &level.distances[t * level.textons..(t + 1) * level.textons];
                padded.iter().map(move |l| l.map_or(0.0, |l| row.get(l as usize).copied().unwrap_or(0.0)))
            })
            .collect();
        Some(Planes {
            width: map.width,
            height: map.height,
            size,
            padded_width: pw,
            padded_pixels: pw * ph,
            values,
        })
    }

    /// Adds, for every pixel, the distance of texton `t` to the label at neighbourhood `slot`.
    fn add(&self, t: usize, slot: usize, distances: &mut [f32]) {
        let (dy, dx) = (slot / self.size, slot % self.size);
        let plane = &self.values[t * self.padded_pixels..(t + 1) * self.padded_pixels];
        for (y, out) in distances.chunks_exact_mut(self.width).take(self.height).enumerate() {
            let start = (y + dy) * self.padded_width + dx;
            for (d, &v) in out.iter_mut().zip(&plane[start..start + self.width]) {
                *d += v;
            }
        }
    }
}

/// The `count` best candidates offered so far, by (distance, index).
struct Best {
    count: usize,
    heap: BinaryHeap<Scored>,
}

impl Best {
    fn new(count: usize) -> Self {
        Best { count, heap: BinaryHeap::with_capacity(count + 1) }
    }

    /// A candidate farther than this cannot enter.
    fn bound(&self) -> f32 {
        match self.heap.peek() {
            Some(worst) if self.heap.len() == self.count => worst.0,
            _ if self.count == 0 => f32::NEG_INFINITY,
            _ => f32::INFINITY,
        }
    }

    fn offer(&mut self, scored: Scored) {
        if self.heap.len() < self.count {
            self.heap.push(scored);
        } else if let Some(mut worst) = self.heap.peek_mut() {
            if scored < *worst {
                *worst = scored;
            }
        }
    }

    fn into_sorted(self) -> Vec<u32> {
        self.heap.into_sorted_vec().into_iter().map(|s| s.1).collect()
    }
}

/// Table rows are checked against the bound once per this many slots (a 5×5 row).
const PRUNE_EVERY: usize = 5;

/// The distance of a candidate's neighbourhood to the query's `rows`, added on to the partial
/// sum `start` of the slots before them (−0.0 for none), or `None` once it is past `bound`.
/// Exact: every term is ≥ 0, so a partial sum never exceeds the whole, and the terms are
/// added in slot order from −0.0, as `Iterator::sum` adds them, so the distances (and the
/// lists' order of ties) are those of summing every slot.
fn continue_within(rows: &[(usize, &[f32])], cand: &[u32], bound: f32, start: f32) -> Option<f32> {
    let mut d = start;
    for chunk in rows.chunks(PRUNE_EVERY) {
        for (slot, row) in chunk {
            d += cand.get(*slot).and_then(|&l| row.get(l as usize)).copied().unwrap_or(0.0);
        }
        if d > bound {
            return None;
        }
    }
    Some(d)
}

/// Candidates whose distances [`sums_within`] adds up side by side.
const LANES: usize = 4;

/// [`continue_within`] from −0.0 for several candidates at once (a lane with no labels is
/// `None`): each lane's terms are added in the same order, so each distance is
/// the same bits as alone, and a lane is `None` once past its own bound. Side by side
/// because one candidate's sum is a chain of dependent additions that leaves the CPU
/// waiting on each; the lanes' chains are independent. A batch's bounds are those before
/// any of its candidates is offered, looser than one at a time would give; that prunes
/// less but chooses the same, since a candidate past a looser bound could not enter, and
/// the `count` best by (distance, index) do not depend on the order they are offered in.
fn sums_within(
    rows: &[(usize, &[f32])],
    cands: [&[u32]; LANES],
    bounds: [f32; LANES],
) -> [Option<f32>; LANES] {
    let mut sums = [-0.0f32; LANES];
    let mut alive = cands.map(|c| !c.is_empty());
    let term = |cand: &[u32], slot: usize, row: &[f32]| {
        cand.get(slot).and_then(|&l| row.get(l as usize)).copied().unwrap_or(0.0)
    };
    for chunk in rows.chunks(PRUNE_EVERY) {
        for (slot, row) in chunk {
            for lane in 0..LANES {
                sums[lane] += term(cands[lane], *slot, row);
            }
        }
        for lane in 0..LANES {
            alive[lane] &= sums[lane] <= bounds[lane];
        }
        if !alive.contains(&true) {
            break;
        }
    }
    std::array::from_fn(|lane| alive[lane].then_some(sums[lane]))
}

/// A candidate's distance and index, ordered by distance, then index (the lists' order).
#[derive(Clone, Copy, Debug)]
struct Scored(f32, u32);

impl PartialEq for Scored {
    fn eq(&self, other: &Self) -> bool {
        self.cmp(other).is_eq()
    }
}
impl Eq for Scored {}
impl PartialOrd for Scored {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}
impl Ord for Scored {
    fn cmp(&self, other: &Self) -> std::cmp::Ordering {
        self.0.total_cmp(&other.0).then(self.1.cmp(&other.1))
    }
}

/// Writes the `size × size` neighbourhood of (x, y) into `out`, labels offset by `base`;
/// returns whether it lies wholly inside the map.
fn write_patch(
    map: &TextonMap,
    x: usize,
    y: usize,
    size: usize,
    tileable: bool,
    base: usize,
    out: &mut [u32],
) -> bool {
    let r = (size / 2) as isize;
    let (w, h) = (map.width as isize, map.height as isize);
    let mut inside = true;
    let mut k = 0;
    for dy in -r..=r {
        for dx in -r..=r {
            let (mut sx, mut sy) = (x as isize + dx, y as isize + dy);
            if tileable {
                sx = sx.rem_euclid(w);
                sy = sy.rem_euclid(h);
            }
            if (0..w).contains(&sx) && (0..h).contains(&sy) {
                out[k] = base as u32 + map.labels[(sy * w + sx) as usize] as u32;
            } else {
                inside = false;
            }
            k += 1;
        }
    }
    inside
}

/// True if b is a or one of its 8 neighbours (wrapping when tileable).
fn adjacent(map: &TextonMap, a: usize, b: usize, tileable: bool) -> bool {
    let d = |p: usize, q: usize, n: usize| {
        let d = p.abs_diff(q);
        if tileable {
            d.min(n - d)
        } else {
            d
        }
    };
    d(a % map.width, b % map.width, map.width) <= 1 && d(a / map.width, b / map.width, map.height) <= 1
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Distinct textons 0..n at unit distance from each other.
    fn unit_table(n: usize) -> Vec<f32> {
        (0..n * n).map(|i| if i / n == i % n { 0.0 } else { 1.0 }).collect()
    }

    /// A pattern with period (px, py) built from pseudo-random labels.
    fn periodic(w: usize, h: usize, px: usize, py: usize, textons: usize) -> TextonMap {
        let labels = (0..w * h)
            .map(|p| {
                let (x, y) = (p % w % px, p / w % py);
                ((x * 7 + y * 13 + (x * y) % 5) % textons) as u16
            })
            .collect();
        TextonMap { width: w, height: h, labels }
    }

    #[test]
    fn periodic_texture_lists_hold_the_translated_copies() {
        let (w, h, px, py, n) = (24, 24, 6, 8, 9);
        let map = periodic(w, h, px, py, n);
        let table = unit_table(n);
        let level = Level { map: &map, distances: &table, textons: n };
        let params = KnnParams { k: 4, neighborhood: 5, tileable: true };
        let lists = single_level_lists(&[level], 0, &params);
        for p in 0..w * h {
            let list = &lists[p * 4..p * 4 + 4];
            assert_eq!(list[0] as usize, p, "the pixel itself comes first");
            for &q in &list[1..] {
                let (q, p) = (q as usize, p);
                assert_eq!(((q % w) + w - (p % w)) % px, 0, "pixel {p}: {q} is not a translated copy");
                assert_eq!(((q / w) + h - (p / w)) % py, 0, "pixel {p}: {q} is not a translated copy");
            }
        }
    }

    #[test]
    fn non_tileable_candidates_keep_their_neighbourhood_inside() {
        let map = periodic(16, 12, 4, 4, 5);
        let table = unit_table(5);
        let level = Level { map: &map, distances: &table, textons: 5 };
        let lists = single_level_lists(&[level], 0, &KnnParams { k: 6, neighborhood: 5, tileable: false });
        for p in 0..16 * 12 {
            for &q in &lists[p * 6 + 1..p * 6 + 6] {
                let (x, y) = (q as usize % 16, q as usize / 16);
                assert!(
                    (2..14).contains(&x) && (2..10).contains(&y),
                    "pixel {p}: candidate {q} touches the border"
                );
                assert!(!adjacent(&map, p, q as usize, false));
            }
        }
    }

    #[test]
    fn two_level_search_of_a_large_level_finds_the_copies_too() {
        // 72 × 72 > the exhaustive limit: candidates come through the coarser level.
        let (w, px) = (72, 8);
        let fine = periodic(w, w, px, px, 7);
        let coarse = periodic(w / 2, w / 2, px / 2, px / 2, 7);
        let table = unit_table(7);
        let pyramid = [
            Level { map: &fine, distances: &table, textons: 7 },
            Level { map: &coarse, distances: &table, textons: 7 },
        ];
        let params = KnnParams { k: 3, neighborhood: 5, tileable: true };
        for lists in [single_level_lists(&pyramid, 0, &params), two_level_lists(&pyramid, 0, &params)] {
            let wrong = (0..w * w)
                .filter(|&p| {
                    lists[p * 3 + 1..p * 3 + 3].iter().any(|&q| {
                        (q as usize % w + w - p % w) % px != 0 || (q as usize / w + w - p / w) % px != 0
                    })
                })
                .count();
            assert_eq!(wrong, 0);
        }
    }

    /// Pseudo-random labels (a fixed LCG) and a random symmetric table with a zero diagonal.
    fn random_level(w: usize, h: usize, textons: usize, seed: u64) -> (TextonMap, Vec<f32>) {
        let mut x = seed;
        let mut next = || {
            x = x.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (x >> 33) as usize
        };
        let labels = (0..w * h).map(|_| (next() % textons) as u16).collect();
        let mut table = vec![0.0; textons * textons];
        for i in 0..textons {
            for j in 0..i {
                let d = (next() % 1000) as f32 / 250.0;
                table[i * textons + j] = d;
                table[j * textons + i] = d;
            }
        }
        (TextonMap { width: w, height: h, labels }, table)
    }

    /// The lists as the search is defined, without pruning, planes or shared candidates:
    /// every distance summed in slot order, sorted by (distance, index).
    fn naive_lists(
        pyramid: &[Level],
        level: usize,
        parts: &[(Level, usize)],
        k: usize,
        tileable: bool,
    ) -> Vec<u32> {
        let features = Features::new(parts, tileable);
        let map = pyramid[level].map;
        let pixels = map.width * map.height;
        let n = parts[0].1;
        let parent = (pixels > EXHAUSTIVE_LIMIT && level + 1 < pyramid.len()).then(|| {
            naive_lists(pyramid, level + 1, &[(pyramid[level + 1], n)], COARSE_CANDIDATES + 1, tileable)
        });
        (0..pixels)
            .flat_map(|a| {
                let candidates: Vec<u32> = match &parent {
                    Some(lists) => {
                        let mut c = children_of_parent_candidates(
                            map,
                            pyramid[level + 1].map,
                            lists,
                            a,
                            COARSE_CANDIDATES + 1,
                        );
                        c.sort_unstable();
                        c.dedup();
                        c
                    }
                    None => (0..pixels as u32).collect(),
                };
                let rows = features.query_rows(a);
                let mut scored: Vec<(f32, u32)> = candidates
                    .into_iter()
                    .filter(|&b| features.eligible[b as usize] && !adjacent(map, a, b as usize, tileable))
                    .map(|b| {
                        let cand = &features.labels[b as usize * features.len..][..features.len];
                        let d: f32 = rows
                            .iter()
                            .map(|(slot, row)| row.get(cand[*slot] as usize).copied().unwrap_or(0.0))
                            .sum();
                        (d, b)
                    })
                    .collect();
                scored.sort_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)));
                let mut list = vec![a as u32];
                list.extend(scored.iter().take(k - 1).map(|s| s.1));
                while list.len() < k {
                    list.push(*list.last().unwrap());
                }
                list
            })
            .collect()
    }

    #[test]
    fn the_fast_search_gives_the_lists_of_the_naive_search() {
        // Three levels, the finest above the exhaustive limit, the coarsest small: every
        // path (shared candidates, pruning, planes, slot-major sums) is taken.
        let sizes = [(70, 66, 9), (35, 33, 7), (18, 17, 5)];
        let made: Vec<(TextonMap, Vec<f32>)> =
            sizes.iter().enumerate().map(|(i, &(w, h, t))| random_level(w, h, t, i as u64 + 7)).collect();
        let pyramid: Vec<Level> =
            made.iter().zip(&sizes).map(|((m, t), s)| Level { map: m, distances: t, textons: s.2 }).collect();
        for tileable in [false, true] {
            let params = KnnParams { k: 4, neighborhood: 5, tileable };
            let mut search = PyramidSearch::new(&pyramid, params);
            for level in 0..pyramid.len() {
                let single = naive_lists(&pyramid, level, &[(pyramid[level], 5)], 4, tileable);
                assert_eq!(
                    search.single_level(level),
                    single,
                    "single-level lists of level {level}, tileable {tileable}"
                );
                if level + 1 < pyramid.len() {
                    let parts = [(pyramid[level], 5), (pyramid[level + 1], parent_size(5))];
                    let two = naive_lists(&pyramid, level, &parts, 4, tileable);
                    assert_eq!(
                        search.two_level(level),
                        two,
                        "two-level lists of level {level}, tileable {tileable}"
                    );
                    let both = search.single_and_two_level(level);
                    assert_eq!(
                        both,
                        (single.clone(), two),
                        "both lists of level {level}, tileable {tileable}"
                    );
                }
            }
        }
    }

    #[test]
    fn parent_neighbourhood_sizes() {
        assert_eq!(parent_size(5), 3);
        assert_eq!(parent_size(7), 3);
        assert_eq!(parent_size(9), 5);
    }
}
