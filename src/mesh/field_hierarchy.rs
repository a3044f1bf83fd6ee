//! The coarse-to-fine vertex hierarchy that direction fields are interpolated over (Turk
//! 2001 §3, used by §4.1's pull/push): level 0 is the mesh itself, and each coarser level
//! keeps about a quarter to a third of the vertices of the level below, so that, as in
//! Turk's point hierarchy and a Gaussian pyramid, every coarse vertex is also a vertex of
//! every finer level.
//!
//! A coarser level is a maximal independent set of the finer level's vertices (no two
//! kept vertices are neighbours, and every dropped vertex has a kept neighbour). Each
//! finer vertex is represented by its nearest kept neighbour (itself, if kept), its
//! *parent*; two coarse vertices are neighbours when some finer edge joins the vertices
//! they represent. This needs no remeshing: the field only needs positions, normals and
//! neighbours on each level, not triangles.

use super::frames::tangent_towards;
use super::topology::VertexRings;
use glam::Vec3;

/// Levels are added until one has at most this many vertices: few enough that relaxing
/// the coarsest level until it converges costs nothing, whatever the mesh's shape.
pub const COARSEST_VERTICES: usize = 100;

/// A coarser level that keeps more than this share of the vertices below it is not
/// worth having (a mesh of many tiny components stops shrinking once each is one vertex).
const MIN_REDUCTION: f32 = 0.8;

/// How far beyond the farthest candidate parent the interpolation kernel reaches, as a
/// multiple of that distance: every candidate keeps some weight, the nearest the most.
const INTERPOLATION_REACH: f32 = 1.5;

/// Anything that lists the neighbours of each vertex.
pub(crate) trait Adjacency {
    /// The neighbours of vertex `v`.
    fn neighbours(&self, v: usize) -> &[u32];
}

impl Adjacency for VertexRings {
    fn neighbours(&self, v: usize) -> &[u32] {
        self.ring(v)
    }
}

/// Neighbour lists in compressed rows, for levels that have no triangles.
#[derive(Clone, Debug)]
pub(crate) struct Graph {
    offsets: Vec<usize>,
    neighbours: Vec<u32>,
}

impl Adjacency for Graph {
    fn neighbours(&self, v: usize) -> &[u32] {
        &self.neighbours[self.offsets[v]..self.offsets[v + 1]]
    }
}

impl Graph {
    /// The graph with the same neighbour lists, in the same order, as `adjacency`.
    fn copy_of(adjacency: &impl Adjacency, vertex_count: usize) -> Graph {
        let mut offsets = Vec::with_capacity(vertex_count + 1);
        let mut neighbours = Vec::new();
        for v in 0..vertex_count {
            offsets.push(neighbours.len());
            neighbours.extend_from_slice(adjacency.neighbours(v));
        }
        offsets.push(neighbours.len());
        Graph { offsets, neighbours }
    }

    /// The graph on `0..vertex_count` with these undirected edges (duplicates and loops
    /// ignored); each vertex's neighbours are sorted.
    fn from_edges(vertex_count: usize, mut edges: Vec<(u32, u32)>) -> Graph {
        edges.retain(|(a, b)| a != b);
        let both_ways: Vec<(u32, u32)> = edges.iter().map(|&(a, b)| (b, a)).collect();
        edges.extend(both_ways);
        edges.sort_unstable();
        edges.dedup();
        let mut offsets = Vec::with_capacity(vertex_count + 1);
        let mut at = 0;
        for v in 0..vertex_count as u32 {
            offsets.push(at);
            at += edges[at..].partition_point(|e| e.0 == v);
        }
        offsets.push(at);
        Graph { offsets, neighbours: edges.into_iter().map(|e| e.1).collect() }
    }
}

/// One level of the hierarchy.
#[derive(Clone, Debug)]
pub(crate) struct Level {
    /// Where each vertex is (a vertex of every finer level too).
    pub positions: Vec<Vec3>,
    /// Unit normal of each vertex: the mesh's on level 0, the normalised sum of the
    /// represented vertices' normals above (a coarse vertex stands for a patch).
    pub normals: Vec<Vec3>,
    /// Who is next to whom on this level.
    pub graph: Graph,
}

impl Level {
    /// Number of vertices.
    pub fn len(&self) -> usize {
        self.positions.len()
    }
}

/// Levels from the mesh (0) to the coarsest, with the links between consecutive levels.
#[derive(Clone, Debug)]
pub(crate) struct Hierarchy {
    levels: Vec<Level>,
    /// `parents[k][v]`: the vertex of level `k + 1` that represents vertex `v` of level `k`.
    parents: Vec<Vec<u32>>,
}

impl Hierarchy {
    /// Coarsens the mesh given by `positions`, `normals` and `rings` until a level has at
    /// most [`COARSEST_VERTICES`] vertices or stops shrinking.
    pub fn build(positions: &[Vec3], normals: &[Vec3], rings: &VertexRings) -> Hierarchy {
        let finest = Level {
            positions: positions.to_vec(),
            normals: normals.to_vec(),
            graph: Graph::copy_of(rings, positions.len()),
        };
        let mut hierarchy = Hierarchy { levels: vec![finest], parents: Vec::new() };
        while let Some(fine) = hierarchy.levels.last().filter(|l| l.len() > COARSEST_VERTICES) {
            let (coarse, parent) = coarsen(fine);
            if coarse.len() as f32 > MIN_REDUCTION * fine.len() as f32 {
                break;
            }
            hierarchy.levels.push(coarse);
            hierarchy.parents.push(parent);
        }
        hierarchy
    }

    /// The levels, finest (the mesh) first.
    pub fn levels(&self) -> &[Level] {
        &self.levels
    }

    /// Turk's pull (downsampling of a sparse field): each vertex of level `k + 1` takes
    /// the mean of the given directions among the level-`k` vertices it represents,
    /// projected onto its tangent plane, or none if none of them has one. Where they
    /// cancel, the first one (in vertex order) is followed.
    pub fn pull(&self, k: usize, fine: &[Option<Vec3>]) -> Vec<Option<Vec3>> {
        let coarse = &self.levels[k + 1];
        let mut sums = vec![Vec3::ZERO; coarse.len()];
        let mut firsts: Vec<Option<Vec3>> = vec![None; coarse.len()];
        for (&p, d) in self.parents[k].iter().zip(fine) {
            if let Some(d) = *d {
                sums[p as usize] += d;
                firsts[p as usize].get_or_insert(d);
            }
        }
        firsts
            .iter()
            .zip(&sums)
            .zip(&coarse.normals)
            .map(|((first, &sum), &n)| {
                first.map(|first| tangent_towards(n, if sum.length_squared() > 1e-12 { sum } else { first }))
            })
            .collect()
    }

    /// Turk's push (upsampling): each vertex of level `k` interpolates the field of level
    /// `k + 1` from its own parent and its neighbours' parents, weighted by Turk's kernel
    /// `w(x) = 2x³ − 3x² + 1` of distance, projected onto its tangent plane and
    /// normalised. A vertex that is also on level `k + 1` keeps its coarse direction, as a
    /// pixel present on two levels of a Gaussian pyramid does.
    pub fn push(&self, k: usize, coarse_field: &[Vec3]) -> Vec<Vec3> {
        let (fine, coarse, parent) = (&self.levels[k], &self.levels[k + 1], &self.parents[k]);
        let mut candidates = Vec::new();
        (0..fine.len())
            .map(|v| {
                let p = fine.positions[v];
                let own = coarse_field[parent[v] as usize];
                // Only a kept vertex sits where its parent is: a mesh has no two vertices
                // at one place (they are welded).
                if coarse.positions[parent[v] as usize] == p {
                    return tangent_towards(fine.normals[v], own);
                }
                candidates.clear();
                candidates.push(parent[v]);
                candidates.extend(fine.graph.neighbours(v).iter().map(|&w| parent[w as usize]));
                candidates.sort_unstable();
                candidates.dedup();
                let distance = |c: u32| coarse.positions[c as usize].distance(p);
                let reach = INTERPOLATION_REACH * candidates.iter().map(|&c| distance(c)).fold(0.0, f32::max);
                let sum: Vec3 = candidates
                    .iter()
                    .map(|&c| coarse_field[c as usize] * turk_kernel(distance(c), reach))
                    .sum();
                tangent_towards(fine.normals[v], if sum.length_squared() > 1e-12 { sum } else { own })
            })
            .collect()
    }
}

/// Turk's interpolation weight (§3.2, Equation 1): 1 at distance 0, falling smoothly to
/// 0 at `reach`.
fn turk_kernel(distance: f32, reach: f32) -> f32 {
    if reach <= 0.0 {
        return 1.0;
    }
    let x = (distance / reach).min(1.0);
    2.0 * x * x * x - 3.0 * x * x + 1.0
}

/// The next coarser level of `fine` and, for each vertex of `fine`, its parent there.
fn coarsen(fine: &Level) -> (Level, Vec<u32>) {
    let kept = maximal_independent_set(&fine.graph, fine.len());
    let mut coarse_index = vec![u32::MAX; fine.len()];
    let mut kept_vertices = Vec::new();
    for v in (0..fine.len()).filter(|&v| kept[v]) {
        coarse_index[v] = kept_vertices.len() as u32;
        kept_vertices.push(v);
    }
    let parent: Vec<u32> = (0..fine.len()).map(|v| coarse_index[nearest_kept(fine, &kept, v)]).collect();
    let mut normal_sums = vec![Vec3::ZERO; kept_vertices.len()];
    for (v, &p) in parent.iter().enumerate() {
        normal_sums[p as usize] += fine.normals[v];
    }
    let normals = normal_sums
        .iter()
        .zip(&kept_vertices)
        .map(|(sum, &v)| sum.try_normalize().unwrap_or(fine.normals[v]))
        .collect();
    let edges = (0..fine.len())
        .flat_map(|v| fine.graph.neighbours(v).iter().map(move |&w| (v, w as usize)))
        .filter(|&(v, w)| v < w)
        .map(|(v, w)| (parent[v], parent[w]))
        .collect();
    let coarse = Level {
        positions: kept_vertices.iter().map(|&v| fine.positions[v]).collect(),
        normals,
        graph: Graph::from_edges(kept_vertices.len(), edges),
    };
    (coarse, parent)
}

/// Greedy in vertex order: a vertex is kept unless a neighbour already is. Every vertex
/// is then kept or next to a kept one, and no two kept vertices are neighbours.
fn maximal_independent_set(graph: &Graph, vertex_count: usize) -> Vec<bool> {
    let mut kept = vec![false; vertex_count];
    for v in 0..vertex_count {
        kept[v] = !graph.neighbours(v).iter().any(|&w| kept[w as usize]);
    }
    kept
}

/// `v` if it is kept, else its nearest kept neighbour (the lowest index among equals).
fn nearest_kept(level: &Level, kept: &[bool], v: usize) -> usize {
    if kept[v] {
        return v;
    }
    let p = level.positions[v];
    let mut best = (usize::MAX, f32::INFINITY);
    for &w in level.graph.neighbours(v) {
        let d = level.positions[w as usize].distance_squared(p);
        if kept[w as usize] && (d < best.1 || (d == best.1 && (w as usize) < best.0)) {
            best = (w as usize, d);
        }
    }
    best.0
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::test_meshes::{bundled, grid};
    use crate::mesh::topology::{connected_components, one_rings};
    use crate::mesh::Mesh;

    fn hierarchy_of(mesh: &Mesh) -> Hierarchy {
        let normals = mesh.normals().expect("normals").to_vec();
        Hierarchy::build(mesh.positions(), &normals, &one_rings(mesh))
    }

    /// Components of a level's graph, as a count (union–find over its edges).
    fn component_count(level: &Level) -> usize {
        let mut sets = crate::mesh::topology::UnionFind::new(level.len());
        for v in 0..level.len() {
            for &w in level.graph.neighbours(v) {
                sets.union(v, w as usize);
            }
        }
        (0..level.len()).filter(|&v| sets.find(v) == v).count()
    }

    #[test]
    fn the_bunny_coarsens_to_a_few_connected_vertices_that_are_finer_vertices_too() {
        let bunny = crate::mesh::load(&bundled("bunny-1k8.obj")).expect("bunny").with_normals();
        let h = hierarchy_of(&bunny);
        let levels = h.levels();
        assert!(levels.len() >= 3, "{} levels", levels.len());
        assert!(levels.last().map(Level::len).unwrap_or(0) <= COARSEST_VERTICES);
        let components = connected_components(&bunny).count;
        for k in 0..levels.len() - 1 {
            let (fine, coarse, parent) = (&levels[k], &levels[k + 1], &h.parents[k]);
            assert!(coarse.len() * 2 <= fine.len(), "level {k}: {} → {}", fine.len(), coarse.len());
            assert_eq!(component_count(coarse), components, "level {}", k + 1);
            for (v, &p) in parent.iter().enumerate() {
                let at = coarse.positions[p as usize];
                // A parent is the vertex itself or one of its neighbours.
                let near = at == fine.positions[v]
                    || fine.graph.neighbours(v).iter().any(|&w| fine.positions[w as usize] == at);
                assert!(near, "level {k} vertex {v}");
            }
            // Every coarse vertex represents itself.
            for c in 0..coarse.len() {
                let v = fine.positions.iter().position(|&q| q == coarse.positions[c]).expect("a fine vertex");
                assert_eq!(parent[v] as usize, c, "level {k}");
            }
            for (c, n) in coarse.normals.iter().enumerate() {
                assert!((n.length() - 1.0).abs() < 1e-5, "level {} vertex {c}", k + 1);
            }
        }
    }

    #[test]
    fn pull_averages_the_represented_directions_and_push_copies_onto_kept_vertices() {
        let g = grid(16).with_normals();
        let h = hierarchy_of(&g);
        assert!(h.levels().len() >= 2);
        let (fine, coarse) = (&h.levels()[0], &h.levels()[1]);
        let mut given = vec![None; fine.len()];
        given[0] = Some(Vec3::X);
        given[fine.len() - 1] = Some(Vec3::Y);
        let pulled = h.pull(0, &given);
        assert_eq!(pulled.iter().filter(|d| d.is_some()).count(), 2);
        assert_eq!(pulled[h.parents[0][0] as usize], Some(Vec3::X));
        assert_eq!(pulled[h.parents[0][fine.len() - 1] as usize], Some(Vec3::Y));
        // A kept vertex keeps its own direction; the others lie between their parents'.
        let turning: Vec<Vec3> = coarse.positions.iter().map(|p| Vec3::new(1.0, p.x, 0.0)).collect();
        let pushed = h.push(0, &turning);
        for (c, p) in coarse.positions.iter().enumerate() {
            let v = fine.positions.iter().position(|q| q == p).expect("a fine vertex");
            assert!((pushed[v] - turning[c].normalize()).length() < 1e-6, "kept vertex {v}");
        }
        for (v, d) in pushed.iter().enumerate() {
            let slope = |d: Vec3| d.y / d.x;
            let nearby = fine.graph.neighbours(v).iter().map(|&w| fine.positions[w as usize].x);
            let (lo, hi) =
                nearby.fold((fine.positions[v].x, fine.positions[v].x), |(lo, hi), x| (lo.min(x), hi.max(x)));
            let margin = 2.0 / 16.0;
            assert!(slope(*d) >= lo - margin && slope(*d) <= hi + margin, "vertex {v}: {d}");
        }
        let uniform = h.push(0, &vec![Vec3::Y; coarse.len()]);
        assert!(uniform.iter().all(|&d| (d - Vec3::Y).length() < 1e-6));
    }
}
