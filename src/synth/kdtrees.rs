//! Castellanos and Williams' acceleration (§6): the eigenvector transform of a sample
//! level's isotropic neighbourhoods (§6.2) and a set of dynamic kd-trees over the
//! transformed neighbourhoods, one per use count (§6.4), so that choosy sampling's
//! penalty `base`^(c − c_min) is searched per tree.
//!
//! The transform is orthonormal, so the distance between two neighbourhoods in its first
//! [`EIGEN_DIMS`] components never exceeds their full weighted distance. Each tree is read
//! nearest first; every texel it yields is compared in full (least over the three turns, as
//! the exhaustive search does), and the tree is left once the next lower bound times the
//! tree's penalty, times 1 + [`APPROXIMATION`], cannot beat the best so far: the choice is
//! at most that factor worse than the exhaustive search's (an ε-approximate search). A
//! neighbourhood with points past an edge is fitted from its known points
//! ([`Eigen::partial_query`]): an estimate, not a bound.
//!
//! With the isotropic neighbourhood's three turns each candidate texel contributes three
//! points, one per turn: the sample's neighbourhood read in the order the query's points
//! face under that turn ([`super::isotropic_stencil::turned`]).

use super::isotropic_stencil::{turned, BETA, POINTS, RING_POINTS, TURNS};
use kiddo::float::kdtree::KdTree;
use kiddo::SquaredEuclidean;
use nalgebra::{DMatrix, SymmetricEigen};

/// Components kept by the eigenvector transform (the paper's 20 of 108: its eigenvalues
/// fall 1000-fold by the twentieth).
pub const EIGEN_DIMS: usize = 20;

/// A tree point's coordinates: the kept components, then the length of what they leave
/// out. The two parts' distances add up to at most the full one (orthogonal parts; the
/// residuals' lengths differ by at most the residual of the difference), so the bound stays
/// a bound and is tighter where a neighbourhood's detail lies outside the components.
pub const TREE_DIMS: usize = EIGEN_DIMS + 1;

/// ε of the search: a tree is left once its next texel cannot beat the best by more than
/// a factor 1 + ε. On stone33's 128² level (a 128² plane of that level alone) 0 gives 5.3× the
/// exhaustive search's speed, 0.25 6.8× and 1 7.6×; patch energy 1.02×, 1.02× and 0.96×
/// the exhaustive's, colour χ² 0.98×, 0.97× and 1.09× (docs/castellanos.md).
pub const APPROXIMATION: f32 = 0.25;

/// Points per leaf of the kd-trees (kiddo's default).
const BUCKET: usize = 32;

type Tree = KdTree<f32, u32, TREE_DIMS, BUCKET, u32>;

/// Not a candidate texel.
const NONE: u32 = u32::MAX;

/// One sample level's candidate neighbourhoods under the eigenvector transform.
pub struct Eigen {
    dims: usize,
    mean: Vec<f32>,
    /// [`EIGEN_DIMS`] rows of `POINTS × dims` values: the leading eigenvectors.
    basis: Vec<f32>,
    /// Per candidate (index into `texels`) and turn, the transformed neighbourhood plus
    /// its jitter.
    points: Vec<[f32; TREE_DIMS]>,
    texels: Vec<u32>,
    /// Per texel, its index in `texels`, or [`NONE`].
    slot: Vec<u32>,
    /// The length bound of the jitter that keeps points distinct: kiddo's mutable trees
    /// cannot hold more than a bucket of equal points (flat or periodic samples have many).
    jitter: f32,
    /// The variance along each kept component, then the mean variance per dimension of
    /// what they leave out: the prior and the noise of a partial query's fit.
    variances: [f64; TREE_DIMS],
    /// The fraction of the neighbourhoods' variance the kept components hold.
    pub captured: f64,
}

impl Eigen {
    /// The transform of the neighbourhoods `at(q)` (`POINTS × dims` values, unturned) of
    /// `texels`, among `texel_count` texels.
    pub fn new<'a>(texels: Vec<u32>, texel_count: usize, dims: usize, at: impl Fn(u32) -> &'a [f32]) -> Self {
        let full = POINTS * dims;
        let mut rows = vec![0f32; texels.len() * TURNS * full];
        for (i, &q) in texels.iter().enumerate() {
            for turn in 0..TURNS {
                let row = &mut rows[(i * TURNS + turn) * full..][..full];
                turned_neighbourhood(at(q), dims, turn, row);
            }
        }
        let (mean, basis, variances, captured) = principal_components(&rows, full);
        let mut eigen = Eigen {
            dims,
            mean,
            basis,
            points: Vec::new(),
            texels,
            slot: Vec::new(),
            jitter: 0.0,
            variances,
            captured,
        };
        eigen.points = rows.chunks_exact(full).map(|r| eigen.project(r)).collect();
        eigen.jitter = eigen.add_jitter();
        eigen.slot = vec![NONE; texel_count];
        eigen.texels.iter().enumerate().for_each(|(i, &q)| eigen.slot[q as usize] = i as u32);
        tracing::debug!(
            "eigenvector transform: {} candidates × {TURNS} turns, {EIGEN_DIMS} of {full} components hold {:.2}% of the variance",
            eigen.texels.len(),
            100.0 * eigen.captured
        );
        eigen
    }

    /// `row` (weighted, in the query's point order) transformed, with its residual length.
    fn project(&self, row: &[f32]) -> [f32; TREE_DIMS] {
        let full = self.mean.len();
        // In f64: the residual is a difference of two lengths, which f32 would round by more
        // than a close match's distance.
        let centred: Vec<f64> = row.iter().zip(&self.mean).map(|(x, m)| f64::from(x - m)).collect();
        let components: [f64; EIGEN_DIMS] = std::array::from_fn(|k| {
            let e = self.basis.get(k * full..(k + 1) * full).unwrap_or(&[]);
            e.iter().zip(&centred).map(|(&e, x)| f64::from(e) * x).sum()
        });
        let kept: f64 = components.iter().map(|v| v * v).sum();
        let length: f64 = centred.iter().map(|v| v * v).sum();
        let mut out = [0f32; TREE_DIMS];
        out.iter_mut().zip(&components).for_each(|(o, &c)| *o = c as f32);
        out[EIGEN_DIMS] = (length - kept).max(0.0).sqrt() as f32;
        out
    }

    /// A query: the vertex's neighbourhood `own` (`POINTS × dims`, every point known)
    /// weighted and transformed.
    pub fn query(&self, own: &[f32]) -> [f32; TREE_DIMS] {
        let mut row = own.to_vec();
        weigh(&mut row, self.dims);
        self.project(&row)
    }

    /// A query for a neighbourhood with unknown points (`known[p]` false: past an edge,
    /// wild cards), and the share of the proximity weight its known points hold. The kept
    /// components are fitted to the known values alone (least squares, each component
    /// held to its variance, the left-out variance as the noise: gappy PCA), and the
    /// residual's length is the known part's, scaled up to the whole. The tree distance
    /// to such a query estimates a full distance, it does not bound it: times the share,
    /// it estimates the distance over the known points, which is what is compared.
    pub fn partial_query(&self, own: &[f32], known: &[bool]) -> ([f32; TREE_DIMS], f32) {
        let (full, dims) = (self.mean.len(), self.dims);
        let mut row = own.to_vec();
        weigh(&mut row, dims);
        let rows: Vec<usize> = (0..full).filter(|&i| known[i / dims]).collect();
        let noise = self.variances[EIGEN_DIMS];
        let b = |k: usize, i: usize| f64::from(self.basis[k * full + i]);
        let centred = |i: usize| f64::from(row[i] - self.mean[i]);
        let normal = DMatrix::from_fn(EIGEN_DIMS, EIGEN_DIMS, |k, l| {
            let prior = if k == l { noise / self.variances[k] } else { 0.0 };
            prior + rows.iter().map(|&i| b(k, i) * b(l, i)).sum::<f64>()
        });
        let rhs =
            nalgebra::DVector::from_fn(EIGEN_DIMS, |k, _| rows.iter().map(|&i| b(k, i) * centred(i)).sum());
        let fit =
            normal.cholesky().map(|c| c.solve(&rhs)).unwrap_or_else(|| nalgebra::DVector::zeros(EIGEN_DIMS));
        let residual: f64 = rows
            .iter()
            .map(|&i| centred(i) - (0..EIGEN_DIMS).map(|k| b(k, i) * fit[k]).sum::<f64>())
            .map(|r| r * r)
            .sum();
        let total: f32 = (0..POINTS).map(point_weight).sum();
        let share = (0..POINTS).filter(|&p| known[p]).map(point_weight).sum::<f32>() / total;
        let mut out = [0f32; TREE_DIMS];
        out.iter_mut().zip(fit.iter()).for_each(|(o, &c)| *o = c as f32);
        out[EIGEN_DIMS] = (residual / f64::from(share.max(1e-6))).sqrt() as f32;
        (out, share)
    }

    /// Displaces every point by a deterministic amount far below the data's spread, so no
    /// two coincide; returns the displacement's length bound.
    fn add_jitter(&mut self) -> f32 {
        let spread = self.points.iter().flat_map(|p| p.iter()).fold(0f32, |m, v| m.max(v.abs()));
        let step = 1e-6 * spread.max(1e-12);
        let mut state = 0x2545_F491_4F6C_DD1Du64;
        for p in &mut self.points {
            for v in p.iter_mut() {
                state = state.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1_442_695_040_888_963_407);
                *v += step * ((state >> 40) as f32 / (1u64 << 24) as f32 - 0.5);
            }
        }
        0.5 * step * (TREE_DIMS as f32).sqrt()
    }

    /// A lower bound of candidate `q`'s full distance to `query` (least over its turns), or
    /// 0 for a texel that is no candidate.
    pub fn bound(&self, query: &[f32; TREE_DIMS], q: u32) -> f32 {
        let Some(&slot) = self.slot.get(q as usize).filter(|&&s| s != NONE) else { return 0.0 };
        let points = &self.points[slot as usize * TURNS..][..TURNS];
        let nearest = points
            .iter()
            .map(|p| p.iter().zip(query).map(|(a, b)| (a - b) * (a - b)).sum::<f32>())
            .fold(f32::INFINITY, f32::min);
        (nearest.sqrt() - self.jitter).max(0.0).powi(2)
    }

    /// The candidate texels.
    pub fn texels(&self) -> &[u32] {
        &self.texels
    }
}

/// Scales each point's values by the square root of its ring's proximity weight (Eq. 7), so
/// that squared distances of weighted vectors are the weighted distance (§6.2: the weights
/// are applied before the transform).
fn weigh(row: &mut [f32], dims: usize) {
    for (p, values) in row.chunks_exact_mut(dims).enumerate() {
        let w = point_weight(p).sqrt();
        values.iter_mut().for_each(|v| *v *= w);
    }
}

/// Point `p`'s proximity weight (Eq. 7, its ring's mean).
fn point_weight(p: usize) -> f32 {
    BETA[usize::from(p >= RING_POINTS[0])]
}

/// The sample's neighbourhood `s` as the query meets it turned by `turn`: the query's
/// point p faces the sample's point `turned(p, turn)`; weighted.
fn turned_neighbourhood(s: &[f32], dims: usize, turn: usize, out: &mut [f32]) {
    for p in 0..POINTS {
        let j = turned(p, turn);
        out[p * dims..(p + 1) * dims].copy_from_slice(&s[j * dims..(j + 1) * dims]);
    }
    weigh(out, dims);
}

/// The mean of `rows` (each `full` long), the leading [`EIGEN_DIMS`] eigenvectors of their
/// covariance as rows, and the fraction of the variance they hold.
fn principal_components(rows: &[f32], full: usize) -> (Vec<f32>, Vec<f32>, [f64; TREE_DIMS], f64) {
    let n = (rows.len() / full).max(1);
    let mut mean = vec![0f64; full];
    rows.chunks_exact(full).for_each(|r| mean.iter_mut().zip(r).for_each(|(m, &v)| *m += f64::from(v)));
    mean.iter_mut().for_each(|m| *m /= n as f64);
    let centred = ndarray::Array2::from_shape_fn((n, full), |(i, j)| rows[i * full + j] - mean[j] as f32);
    let gram = centred.t().dot(&centred);
    let covariance = DMatrix::from_fn(full, full, |i, j| f64::from(gram[[i, j]]) / n as f64);
    let eigen = SymmetricEigen::new(covariance);
    let mut order: Vec<usize> = (0..full).collect();
    order.sort_by(|&a, &b| eigen.eigenvalues[b].total_cmp(&eigen.eigenvalues[a]));
    let kept = &order[..EIGEN_DIMS.min(full)];
    let total: f64 = eigen.eigenvalues.iter().map(|v| v.max(0.0)).sum();
    let captured = kept.iter().map(|&k| eigen.eigenvalues[k].max(0.0)).sum::<f64>() / total.max(1e-300);
    let mut basis = vec![0f32; EIGEN_DIMS * full];
    let mut variances = [0f64; TREE_DIMS];
    for (row, &k) in kept.iter().enumerate() {
        (0..full).for_each(|i| basis[row * full + i] = eigen.eigenvectors[(i, k)] as f32);
        variances[row] = eigen.eigenvalues[k].max(1e-12);
    }
    let left = (full - kept.len()).max(1) as f64;
    variances[EIGEN_DIMS] = (total * (1.0 - captured) / left).max(1e-12);
    (mean.iter().map(|&m| m as f32).collect(), basis, variances, captured)
}

/// What the caller does after comparing a texel a tree yielded.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Flow {
    /// Read the tree's next nearest.
    Next,
    /// Nothing further in this tree can win: go to the next tree.
    Leave,
}

/// The set of dynamic kd-trees of one pass (§6.4): tree c holds the candidates chosen c
/// times so far in the pass, each under its three turns. A choice moves its texel's points
/// one tree up.
pub struct UseTrees<'e> {
    eigen: &'e Eigen,
    trees: Vec<Tree>,
    count: Vec<u32>,
}

impl<'e> UseTrees<'e> {
    /// Every candidate of `eigen` in tree 0 (nothing chosen yet).
    pub fn new(eigen: &'e Eigen) -> Self {
        let mut tree = Tree::with_capacity(eigen.points.len());
        eigen.points.iter().enumerate().for_each(|(i, p)| tree.add(p, i as u32));
        UseTrees { eigen, trees: vec![tree], count: vec![0; eigen.texels.len()] }
    }

    /// The transform the trees hold.
    pub fn eigen(&self) -> &'e Eigen {
        self.eigen
    }

    /// Texel `q` was chosen (again): its points move one tree up.
    pub fn chose(&mut self, q: u32) {
        let Some(&slot) = self.eigen.slot.get(q as usize).filter(|&&s| s != NONE) else { return };
        let c = self.count[slot as usize] as usize;
        if self.trees.len() == c + 1 {
            self.trees.push(Tree::new());
        }
        for turn in 0..TURNS {
            let id = slot * TURNS as u32 + turn as u32;
            let point = &self.eigen.points[id as usize];
            self.trees[c].remove(point, id);
            self.trees[c + 1].add(point, id);
        }
        self.count[slot as usize] += 1;
    }

    /// Offers `visit` the candidates of every non-empty tree, least count first, each tree
    /// nearest first to `query`, with a lower bound of the texel's full distance. A texel
    /// comes once per turn; `visit` returns [`Flow::Leave`] once the tree cannot win.
    /// `radius(excess)`, asked as a tree is entered (its count minus the least count), is
    /// the squared transformed distance beyond which none of its texels can win, or
    /// infinite: the tree is then read in growing batches.
    pub fn search(
        &self,
        query: &[f32; TREE_DIMS],
        mut radius: impl FnMut(u32) -> f32,
        mut visit: impl FnMut(u32, f32) -> Flow,
    ) {
        let floor = self.trees.iter().position(|t| t.size() > 0).unwrap_or(0);
        for (c, tree) in self.trees.iter().enumerate().skip(floor).filter(|(_, t)| t.size() > 0) {
            let r = radius((c - floor) as u32);
            let mut offer = |hits: &[kiddo::NearestNeighbour<f32, u32>]| {
                hits.iter().all(|hit| {
                    let bound = (hit.distance.max(0.0).sqrt() - self.eigen.jitter).max(0.0);
                    visit(self.eigen.texels[hit.item as usize / TURNS], bound * bound) == Flow::Next
                })
            };
            // Nearest first in growing batches: a batch stops the walk at its n-th nearest,
            // and the caller leaves most trees within the first.
            let reach =
                if r.is_finite() { (r.max(0.0).sqrt() + self.eigen.jitter).powi(2) } else { f32::INFINITY };
            let (mut n, mut seen) = (16usize, 0usize);
            loop {
                let hits = match std::num::NonZeroUsize::new(n).filter(|_| reach.is_finite()) {
                    Some(most) => tree.nearest_n_within::<SquaredEuclidean>(query, reach, most, true),
                    None => tree.nearest_n::<SquaredEuclidean>(query, n),
                };
                if !offer(&hits[seen.min(hits.len())..]) || hits.len() < n {
                    break;
                }
                (seen, n) = (hits.len(), n * 4);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Random neighbourhoods of 3 values per point.
    fn neighbourhoods(texels: usize) -> Vec<f32> {
        let mut state = 7u64;
        (0..texels * POINTS * 3)
            .map(|i| {
                state = state.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1_442_695_040_888_963_407);
                let smooth = ((i / 3) as f32 * 0.37).sin();
                smooth + 0.2 * ((state >> 40) as f32 / (1u64 << 24) as f32)
            })
            .collect()
    }

    /// The transform is orthonormal: a transformed distance never exceeds the full one, so
    /// it bounds the full distance from below.
    #[test]
    fn transformed_distances_bound_full_distances_from_below() {
        let values = neighbourhoods(200);
        let at = |q: u32| &values[q as usize * POINTS * 3..][..POINTS * 3];
        let eigen = Eigen::new((0..200).collect(), 200, 3, at);
        assert!(eigen.captured > 0.5 && eigen.captured <= 1.0 + 1e-9, "{}", eigen.captured);
        let query = eigen.query(at(3));
        for q in 0..200u32 {
            for turn in 0..TURNS {
                let mut row = vec![0.0; POINTS * 3];
                turned_neighbourhood(at(q), 3, turn, &mut row);
                let mut own = at(3).to_vec();
                weigh(&mut own, 3);
                let full: f32 = own.iter().zip(&row).map(|(a, b)| (a - b) * (a - b)).sum();
                let point = &eigen.points[q as usize * TURNS + turn];
                let reduced: f32 = query.iter().zip(point).map(|(a, b)| (a - b) * (a - b)).sum();
                let bound = (reduced.sqrt() - eigen.jitter).max(0.0).powi(2);
                assert!(bound <= full * (1.0 + 1e-4) + 1e-6, "texel {q}, turn {turn}: {bound} > {full}");
            }
        }
    }

    /// A neighbourhood cut by an edge (its outer ring's first half unknown) is fitted from
    /// its known points: its own texel's unturned point is among the nearest to the fit,
    /// and the share is the known points' part of the weight.
    #[test]
    fn a_partial_query_lies_near_its_own_texel() {
        let values = neighbourhoods(200);
        let at = |q: u32| &values[q as usize * POINTS * 3..][..POINTS * 3];
        let eigen = Eigen::new((0..200).collect(), 200, 3, at);
        let known: Vec<bool> = (0..POINTS).map(|p| p < RING_POINTS[0] + RING_POINTS[1] / 2).collect();
        let (query, share) = eigen.partial_query(at(42), &known);
        let expected = (12.0 * BETA[0] + 12.0 * BETA[1]) / (12.0 * BETA[0] + 24.0 * BETA[1]);
        assert!((share - expected).abs() < 1e-5, "share {share}, expected {expected}");
        let distance =
            |p: &[f32; TREE_DIMS]| p.iter().zip(&query).map(|(a, b)| (a - b) * (a - b)).sum::<f32>();
        let own = distance(&eigen.points[42 * TURNS]);
        let closer = eigen.points.iter().filter(|p| distance(p) < own).count();
        assert!(
            closer < eigen.points.len() / 50,
            "{closer} of {} points nearer than its own",
            eigen.points.len()
        );
    }

    /// A chosen texel moves to the next tree; the search visits the lower tree first and
    /// yields every texel's three turns.
    #[test]
    fn choices_move_texels_up_the_trees() {
        let values = neighbourhoods(50);
        let at = |q: u32| &values[q as usize * POINTS * 3..][..POINTS * 3];
        let eigen = Eigen::new((0..50).collect(), 50, 3, at);
        let mut trees = UseTrees::new(&eigen);
        trees.chose(7);
        trees.chose(7);
        trees.chose(9);
        assert_eq!(trees.trees.iter().map(|t| t.size()).collect::<Vec<_>>(), [144, 3, 3]);
        let mut seen = Vec::new();
        trees.search(
            &eigen.query(at(7)),
            |_| f32::INFINITY,
            |q, _| {
                seen.push(q);
                Flow::Next
            },
        );
        assert_eq!(seen.len(), 150);
        assert_eq!(&seen[147..], &[7, 7, 7], "texel 7 sits in the last tree");
    }
}
