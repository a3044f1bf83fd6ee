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

use rayon::prelude::*;

/// Levels with at most this many pixels (64 × 64) are searched exhaustively.
pub const EXHAUSTIVE_LIMIT: usize = 64 * 64;
/// Coarse candidates per pixel in the two-level search (the paper's m).
pub const COARSE_CANDIDATES: usize = 100;
/// Marks a neighbourhood slot outside a non-tileable sample.
const OUTSIDE: u32 = u32::MAX;

/// A texton label per pixel, row-major.
#[derive(Clone, Debug, PartialEq)]
pub struct TextonMap {
    pub width: usize,
    pub height: usize,
    pub labels: Vec<u16>,
}

/// One pyramid level as the search sees it: the map and the texton distance table
/// (`textons × textons`, row-major, from [`super::gamma::distance_table`]).
#[derive(Clone, Copy)]
pub struct Level<'a> {
    pub map: &'a TextonMap,
    pub distances: &'a [f32],
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
    let fine = Features::new(&[(pyramid[level], params.neighborhood)], params.tileable);
    lists(pyramid, level, &fine, params)
}

/// The k-lists of `pyramid[level]` with two-level neighbourhoods (this level plus the
/// parent's on `level + 1`), `[pixels][k]`. `level + 1` must exist.
pub fn two_level_lists(pyramid: &[Level], level: usize, params: &KnnParams) -> Vec<u32> {
    let parts =
        [(pyramid[level], params.neighborhood), (pyramid[level + 1], parent_size(params.neighborhood))];
    let features = Features::new(&parts, params.tileable);
    lists(pyramid, level, &features, params)
}

fn lists(pyramid: &[Level], level: usize, features: &Features, params: &KnnParams) -> Vec<u32> {
    let map = pyramid[level].map;
    let count = params.k.saturating_sub(1);
    let pixels = map.width * map.height;
    let coarse = (pixels > EXHAUSTIVE_LIMIT && level + 1 < pyramid.len()).then(|| {
        let coarse_features = Features::new(&[(pyramid[level + 1], params.neighborhood)], params.tileable);
        let m = KnnParams { k: COARSE_CANDIDATES + 1, ..*params };
        lists(pyramid, level + 1, &coarse_features, &m)
    });
    let all: Vec<u32> = (0..pixels as u32).filter(|&b| features.eligible[b as usize]).collect();
    (0..pixels)
        .into_par_iter()
        .flat_map_iter(|a| {
            let nearest = match &coarse {
                Some(parent_lists) => {
                    let cands = children_of_parent_candidates(
                        map,
                        pyramid[level + 1].map,
                        parent_lists,
                        a,
                        COARSE_CANDIDATES + 1,
                    );
                    features.nearest(a, cands.into_iter(), count, map, params.tileable)
                }
                None => features.nearest(a, all.iter().copied(), count, map, params.tileable),
            };
            let mut list = Vec::with_capacity(params.k);
            list.push(a as u32);
            list.extend_from_slice(&nearest);
            // Tiny samples may not have k − 1 eligible pixels: repeat the last one found.
            while list.len() < params.k {
                list.push(*list.last().unwrap_or(&(a as u32)));
            }
            list.truncate(params.k.max(1));
            list
        })
        .collect()
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
    for &c in &parent_lists[parent * stride..(parent + 1) * stride] {
        let (cx, cy) = (c as usize % coarse.width, c as usize / coarse.width);
        for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
            let (fx, fy) = (2 * cx + dx, 2 * cy + dy);
            if fx < fine.width && fy < fine.height {
                out.push((fy * fine.width + fx) as u32);
            }
        }
    }
    out.sort_unstable();
    out.dedup();
    out
}

/// Every pixel's neighbourhood as labels in one combined texton index space (each level's
/// textons offset after the previous level's), with one block-diagonal distance table.
struct Features {
    len: usize,
    labels: Vec<u32>,
    eligible: Vec<bool>,
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
        }
        if !eligible.iter().any(|&e| e) {
            // A sample smaller than its neighbourhood: compare the offsets that exist.
            eligible.iter_mut().for_each(|e| *e = true);
        }
        Features { len, labels, eligible, table, textons }
    }

    /// The `count` eligible candidates nearest to `a`, nearest first, ties by index.
    fn nearest(
        &self,
        a: usize,
        candidates: impl Iterator<Item = u32>,
        count: usize,
        map: &TextonMap,
        tileable: bool,
    ) -> Vec<u32> {
        let query = &self.labels[a * self.len..(a + 1) * self.len];
        let rows: Vec<(usize, &[f32])> = query
            .iter()
            .enumerate()
            .filter(|(_, &l)| l != OUTSIDE)
            .map(|(slot, &l)| (slot, &self.table[l as usize * self.textons..(l as usize + 1) * self.textons]))
            .collect();
        let mut scored: Vec<(f32, u32)> = candidates
            .filter(|&b| self.eligible[b as usize] && !adjacent(map, a, b as usize, tileable))
            .map(|b| {
                let cand = &self.labels[b as usize * self.len..(b as usize + 1) * self.len];
                let d: f32 = rows
                    .iter()
                    .map(|(slot, row)| {
                        cand.get(*slot).and_then(|&l| row.get(l as usize)).copied().unwrap_or(0.0)
                    })
                    .sum();
                (d, b)
            })
            .collect();
        let by_distance = |x: &(f32, u32), y: &(f32, u32)| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1));
        if scored.len() > count {
            scored.select_nth_unstable_by(count, by_distance);
            scored.truncate(count);
        }
        scored.sort_by(by_distance);
        scored.into_iter().map(|(_, b)| b).collect()
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

    #[test]
    fn parent_neighbourhood_sizes() {
        assert_eq!(parent_size(5), 3);
        assert_eq!(parent_size(7), 3);
        assert_eq!(parent_size(9), 5);
    }
}
