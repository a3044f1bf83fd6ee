//! One step of midpoint subdivision: the start of a remeshing at half a coarser
//! remeshing's edge length ([`super::refine`]).

use crate::mesh::topology::edge_incidences;
use crate::mesh::Mesh;
use glam::Vec3;

/// `mesh` with every triangle split into four at its edges' midpoints: the old vertices
/// keep their numbers, each edge's midpoint follows them (in edge order), and face f's
/// four children are faces 4f to 4f + 3, each counter-clockwise as f is. An edge of an
/// isotropic mesh becomes two of half its length and each face gains three more, so an
/// even mesh stays even at half the length.
pub(super) fn midpoints(mesh: &Mesh) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let (p, triangles) = (mesh.positions(), mesh.triangles());
    let mut positions = p.to_vec();
    // Per face, the midpoint of edge k (corners k → k + 1).
    let mut middle = vec![[0u32; 3]; triangles.len()];
    for edge in edge_incidences(triangles).chunk_by(|a, b| a.key() == b.key()) {
        let (lo, hi) = edge[0].key();
        let m = positions.len() as u32;
        positions.push((p[lo as usize] + p[hi as usize]) * 0.5);
        for incidence in edge {
            let t = triangles[incidence.face as usize];
            if let Some(k) =
                (0..3).find(|&k| t[k].min(t[(k + 1) % 3]) == lo && t[k].max(t[(k + 1) % 3]) == hi)
            {
                middle[incidence.face as usize][k] = m;
            }
        }
    }
    let children = triangles
        .iter()
        .zip(&middle)
        .flat_map(|(&[a, b, c], &[ab, bc, ca])| [[a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca]])
        .collect();
    (positions, children)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::remesh::edge_length_stats;
    use crate::mesh::test_meshes::cube;
    use crate::mesh::topology;

    #[test]
    fn four_faces_per_face_and_one_vertex_per_edge() {
        let c = cube();
        let (positions, triangles) = midpoints(&c);
        let edges = topology::edges(&c).len();
        assert_eq!(positions.len(), c.vertex_count() + edges);
        assert_eq!(triangles.len(), 4 * c.face_count());
        let fine = Mesh::new(positions, triangles).expect("a valid mesh");
        let (before, after) = (topology::summary(&c), topology::summary(&fine));
        assert_eq!(before.euler_characteristic, after.euler_characteristic, "{before} → {after}");
        assert!(crate::mesh::manifold::is_manifold(fine.triangles()));
        // Every child lies in its parent's plane, with half the edges.
        assert!((fine.surface_area() - c.surface_area()).abs() < 1e-5 * c.surface_area());
        let (s, f) = (edge_length_stats(&c), edge_length_stats(&fine));
        assert!((f.max - s.max / 2.0).abs() < 1e-6 && (f.min - s.min / 2.0).abs() < 1e-6, "{s} → {f}");
    }
}
