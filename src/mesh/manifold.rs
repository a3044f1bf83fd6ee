//! Consistent orientation and manifold splitting of a triangle list (see
//! [`super::prepare`] for why these repairs and not errors).

use super::topology::{edge_incidences, EdgeIncidence, UnionFind};
use glam::Vec3;

/// Flips faces so that faces sharing a two-face edge traverse it in opposite directions.
/// Each connected part keeps the orientation most of its faces already have. Returns the
/// number of faces flipped.
pub(crate) fn orient(triangles: &mut [[u32; 3]]) -> usize {
    let adjacency = two_face_adjacency(triangles);
    let mut flip = vec![false; triangles.len()];
    let mut visited = vec![false; triangles.len()];
    let mut flipped = 0;
    for seed in 0..triangles.len() {
        if visited[seed] {
            continue;
        }
        let part = flood(seed, &adjacency, &mut visited, &mut flip);
        let relative = part.iter().filter(|&&f| flip[f]).count();
        let invert = 2 * relative > part.len();
        for &f in &part {
            flip[f] ^= invert;
            if flip[f] {
                triangles[f].swap(1, 2);
                flipped += 1;
            }
        }
    }
    flipped
}

/// Breadth-first over faces joined by two-face edges, choosing each face's flip so that it
/// agrees with the face it was reached from. Returns the faces reached.
fn flood(seed: usize, adjacency: &Adjacency, visited: &mut [bool], flip: &mut [bool]) -> Vec<usize> {
    let mut part = vec![seed];
    visited[seed] = true;
    let mut next = 0;
    while let Some(&f) = part.get(next) {
        next += 1;
        for &(g, same_direction) in adjacency.of(f) {
            let g = g as usize;
            if !visited[g] {
                visited[g] = true;
                flip[g] = flip[f] ^ same_direction;
                part.push(g);
            }
        }
    }
    part
}

/// For every face, its neighbours across edges shared by exactly two faces, and whether
/// the neighbour runs along that edge in the same direction (disagreeing orientation).
struct Adjacency {
    offsets: Vec<usize>,
    neighbours: Vec<(u32, bool)>,
}

impl Adjacency {
    fn of(&self, f: usize) -> &[(u32, bool)] {
        &self.neighbours[self.offsets[f]..self.offsets[f + 1]]
    }
}

fn two_face_adjacency(triangles: &[[u32; 3]]) -> Adjacency {
    let incidences = edge_incidences(triangles);
    let mut pairs = Vec::new();
    for group in incidences.chunk_by(|a, b| a.key() == b.key()) {
        if let [a, b] = group {
            let same = a.forward == b.forward;
            pairs.push((a.face, b.face, same));
            pairs.push((b.face, a.face, same));
        }
    }
    pairs.sort_unstable();
    let mut offsets = vec![0; triangles.len() + 1];
    for &(f, _, _) in &pairs {
        offsets[f as usize + 1] += 1;
    }
    for f in 0..triangles.len() {
        offsets[f + 1] += offsets[f];
    }
    Adjacency { offsets, neighbours: pairs.into_iter().map(|(_, g, same)| (g, same)).collect() }
}

/// Groups the corners (`3 * face + k`) of every vertex into fans: two corners of the same
/// vertex are joined when their faces share an edge at that vertex, that edge has exactly
/// two faces, and they traverse it in opposite directions.
pub(crate) fn corner_fans(triangles: &[[u32; 3]]) -> UnionFind {
    let mut fans = UnionFind::new(3 * triangles.len());
    let incidences = edge_incidences(triangles);
    for group in incidences.chunk_by(|a, b| a.key() == b.key()) {
        if let [a, b] = group {
            if a.forward != b.forward {
                for v in [a.lo, a.hi] {
                    fans.union(corner_of(triangles, a, v), corner_of(triangles, b, v));
                }
            }
        }
    }
    fans
}

fn corner_of(triangles: &[[u32; 3]], e: &EdgeIncidence, v: u32) -> usize {
    let f = e.face as usize;
    let k = triangles[f].iter().position(|&w| w == v).unwrap_or(0);
    3 * f + k
}

/// Gives every fan of a vertex but the first its own copy of the vertex, so that each
/// edge keeps at most two consistently oriented faces and each vertex one fan. Returns
/// the number of vertices added.
pub(crate) fn split(positions: &mut Vec<Vec3>, triangles: &mut [[u32; 3]]) -> usize {
    let before = positions.len();
    // One pass suffices in all cases analysed; repeat a few times in case a pass exposes
    // another split, rather than trust that analysis blindly.
    for _ in 0..4 {
        if split_once(positions, triangles) == 0 {
            break;
        }
    }
    positions.len() - before
}

fn split_once(positions: &mut Vec<Vec3>, triangles: &mut [[u32; 3]]) -> usize {
    let mut fans = corner_fans(triangles);
    let mut vertex_of_fan = vec![u32::MAX; 3 * triangles.len()];
    let mut vertex_taken = vec![false; positions.len()];
    let before = positions.len();
    for c in 0..3 * triangles.len() {
        let fan = fans.find(c);
        let v = triangles[c / 3][c % 3];
        if vertex_of_fan[fan] == u32::MAX {
            vertex_of_fan[fan] = if vertex_taken[v as usize] {
                positions.push(positions[v as usize]);
                (positions.len() - 1) as u32
            } else {
                vertex_taken[v as usize] = true;
                v
            };
        }
        triangles[c / 3][c % 3] = vertex_of_fan[fan];
    }
    positions.len() - before
}

/// True if every edge has one face or two faces traversing it in opposite directions, and
/// the faces around every vertex form a single fan.
pub(crate) fn is_manifold(triangles: &[[u32; 3]]) -> bool {
    let incidences = edge_incidences(triangles);
    let edges_ok = incidences
        .chunk_by(|a, b| a.key() == b.key())
        .all(|g| g.len() == 1 || (g.len() == 2 && g[0].forward != g[1].forward));
    if !edges_ok {
        return false;
    }
    let mut fans = corner_fans(triangles);
    let vertices = triangles.iter().flatten().map(|&v| v as usize + 1).max().unwrap_or(0);
    let mut fan_of_vertex = vec![usize::MAX; vertices];
    for c in 0..3 * triangles.len() {
        let fan = fans.find(c);
        let slot = &mut fan_of_vertex[triangles[c / 3][c % 3] as usize];
        if *slot == usize::MAX {
            *slot = fan;
        } else if *slot != fan {
            return false;
        }
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn orientation_follows_the_majority() {
        let mut t = [[0, 1, 2], [0, 3, 2], [2, 3, 4]];
        // Faces 1 and 2 agree with each other and disagree with face 0.
        assert_eq!(orient(&mut t), 1);
        assert_eq!(t, [[0, 2, 1], [0, 3, 2], [2, 3, 4]]);
        assert!(is_manifold(&t));
    }

    #[test]
    fn three_sheets_on_one_edge_are_split_apart() {
        // Three triangles hinge on the edge 0–1.
        let mut p = vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z, Vec3::NEG_Y];
        let mut t = [[0, 1, 2], [1, 0, 3], [0, 1, 4]];
        assert!(!is_manifold(&t));
        let added = split(&mut p, &mut t);
        assert!(is_manifold(&t), "{t:?}");
        assert_eq!(added, 4, "two of the three sheets get their own copy of 0 and 1");
        assert_eq!(p.len(), 9);
    }

    #[test]
    fn bowtie_vertex_is_split() {
        // Two triangles touching only at vertex 0.
        let mut p = vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::NEG_X, Vec3::NEG_Y];
        let mut t = [[0, 1, 2], [0, 3, 4]];
        assert!(!is_manifold(&t));
        assert_eq!(split(&mut p, &mut t), 1);
        assert_eq!(t, [[0, 1, 2], [5, 3, 4]]);
        assert!(is_manifold(&t));
    }

    #[test]
    fn manifold_input_is_untouched() {
        let mut p = vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::ONE];
        let mut t = [[0, 1, 2], [2, 1, 3]];
        assert_eq!(split(&mut p, &mut t), 0);
        assert_eq!(t, [[0, 1, 2], [2, 1, 3]]);
    }
}
