//! The surface as hierarchical pattern mapping sees it: the user's triangles exactly as the
//! file gives them, joined where their corners coincide.
//!
//! Nothing is repaired: corners at the same point (within 10⁻⁶ of the bounding-box
//! diagonal and 1% of their shortest edge, as the loaders weld) are one vertex of the
//! graph, so unwelded patches such as
//! the Utah teapot's join, but the file's own vertices, faces and their order are what the
//! output keeps. A face whose corners weld onto fewer than three points has no area and no
//! place in the graph; it is carried along and gets the coordinates of its neighbours. Faces
//! that disagree with their neighbours' winding are oriented here for the flattening only.
//! An edge shared by more than two faces, a vertex where two fans of faces touch, or a
//! surface that cannot be oriented is refused with one line.

use crate::mesh::topology::{edge_incidences, UnionFind};
use crate::{Error, Result};
use glam::Vec3;
use std::path::Path;

/// No face, no vertex, no cluster.
pub(crate) const NONE: u32 = u32::MAX;

/// The welded, oriented connectivity of a file's triangles.
#[derive(Clone, Debug)]
pub struct SurfaceGraph {
    /// One position per distinct point.
    pub positions: Vec<Vec3>,
    /// Area-weighted unit vertex normals (across the file's seams, since they are welded).
    pub normals: Vec<Vec3>,
    /// Per file vertex, its graph vertex.
    pub weld: Vec<u32>,
    /// Per graph vertex, the first file vertex welded into it (for messages).
    pub file_vertex: Vec<u32>,
    /// Per graph face, the file face it is.
    pub file_face: Vec<u32>,
    /// Per file face, its graph face, or `NONE` for a face without area in the graph.
    pub graph_face: Vec<u32>,
    /// Per graph face, its three vertices counter-clockwise (consistently oriented).
    pub corners: Vec<[u32; 3]>,
    /// Per graph face, which corner of the file's face each of its corners is.
    pub file_corner: Vec<[u8; 3]>,
    /// Per graph face, the face across edge k (corners k → k + 1), or `NONE`.
    pub across: Vec<[u32; 3]>,
    /// Per graph face, its area.
    pub area: Vec<f32>,
    /// Per graph face, its unit normal (zero for a zero-area face).
    pub face_normal: Vec<Vec3>,
    /// Per graph face, its centroid.
    pub centroid: Vec<Vec3>,
    /// Per graph vertex, whether it lies on the surface's boundary.
    pub on_boundary: Vec<bool>,
    face_start: Vec<u32>,
    vertex_faces: Vec<u32>,
}

impl SurfaceGraph {
    /// Joins `triangles` over `positions` (a file's, named `path` in errors).
    pub fn new(positions: &[Vec3], triangles: &[[u32; 3]], path: &Path) -> Result<SurfaceGraph> {
        let refuse = |m: String| {
            Error::format(
                path,
                format!("{m}; pattern mapping (soler2002) takes the mesh as it is and does not repair it"),
            )
        };
        // Coincident corners are one point.
        let (lo, hi) = crate::mesh::bounds_of(positions);
        let (remap, _) = crate::mesh::weld::weld(
            positions,
            triangles,
            crate::mesh::weld::LOCAL_FRACTION,
            1e-6 * (hi - lo).length(),
        );
        let distinct = |c: [u32; 3]| c[0] != c[1] && c[1] != c[2] && c[0] != c[2];
        // The file's own connectivity must be a manifold: at most two faces on an edge, one
        // fan of faces around a vertex. Faces without area once welded are left out: they
        // are carried, not joined, so a sliver between two seam copies pinches nothing.
        let proper: Vec<[u32; 3]> = triangles
            .iter()
            .copied()
            .filter(|t| distinct(*t) && distinct(t.map(|i| remap[i as usize])))
            .collect();
        let incidences = edge_incidences(&proper);
        if let Some(group) = incidences.chunk_by(|a, b| a.key() == b.key()).find(|g| g.len() > 2) {
            return Err(refuse(format!(
                "not a manifold surface: the edge between vertices {} and {} (counting from 0) is shared by {} faces",
                group[0].lo,
                group[0].hi,
                group.len()
            )));
        }
        let file_links = links(&incidences, proper.len());
        if let Some(v) = first_pinched_vertex(&proper, &file_links, positions.len()) {
            return Err(refuse(format!(
                "not a manifold surface: separate fans of faces meet at vertex {v} (counting from 0)"
            )));
        }
        // Join faces across every welded edge that exactly two faces share (a seam the file
        // left open); an edge of three or more sheets stays open.
        let mut graph_face = vec![NONE; triangles.len()];
        let (mut corners, mut file_face) = (Vec::new(), Vec::new());
        for (f, t) in triangles.iter().enumerate() {
            let c = t.map(|i| remap[i as usize]);
            if distinct(c) {
                graph_face[f] = corners.len() as u32;
                corners.push(c);
                file_face.push(f as u32);
            }
        }
        if corners.is_empty() {
            return Err(Error::format(path, "every face has its corners at fewer than three points"));
        }
        // A huge polygon, fan-triangulated: the mapping's time grows with the square of its
        // corners (2,000: 45 s), as the vertex engine's remeshing does.
        crate::mesh::load::check_fans_of(&corners, positions.len(), path)?;
        let incidences = edge_incidences(&corners);
        let joins = links(&incidences, corners.len());
        let flips = orientation(&joins).map_err(|(a, b)| {
            refuse(format!(
                "not an orientable surface: its faces cannot agree on a winding (around the edge between vertices {a} and {b})"
            ))
        })?;
        let mut file_corner = vec![[0u8, 1, 2]; corners.len()];
        for (f, flip) in flips.iter().enumerate() {
            if *flip {
                corners[f].swap(1, 2);
                file_corner[f].swap(1, 2);
            }
        }
        let mut across = vec![[NONE; 3]; corners.len()];
        for (f, list) in joins.iter().enumerate() {
            for &(g, _, (a, b)) in list {
                if let Some(k) = (0..3).find(|&k| {
                    let (x, y) = (corners[f][k], corners[f][(k + 1) % 3]);
                    (x.min(y), x.max(y)) == (a, b)
                }) {
                    across[f][k] = g;
                }
            }
        }
        // One graph vertex per fan of faces around each welded point.
        let (corners, file_vertex, weld) = split_fans(corners, &across, &remap);
        let n = file_vertex.len();
        let mut face_start = vec![0u32; n + 1];
        for c in &corners {
            for &v in c {
                face_start[v as usize + 1] += 1;
            }
        }
        for v in 0..n {
            face_start[v + 1] += face_start[v];
        }
        let mut fill = face_start.clone();
        let mut vertex_faces = vec![0u32; face_start[n] as usize];
        for (f, c) in corners.iter().enumerate() {
            for &v in c {
                vertex_faces[fill[v as usize] as usize] = f as u32;
                fill[v as usize] += 1;
            }
        }
        let mut graph = SurfaceGraph {
            normals: Vec::new(),
            area: Vec::new(),
            face_normal: Vec::new(),
            centroid: Vec::new(),
            on_boundary: vec![false; n],
            positions: file_vertex.iter().map(|&v| positions[v as usize]).collect(),
            weld,
            file_vertex,
            file_face,
            graph_face,
            corners,
            file_corner,
            across,
            face_start,
            vertex_faces,
        };
        graph.measure();
        Ok(graph)
    }

    fn measure(&mut self) {
        let mut normals = vec![Vec3::ZERO; self.positions.len()];
        for (f, c) in self.corners.iter().enumerate() {
            let [a, b, d] = c.map(|v| self.positions[v as usize]);
            let cross = (b - a).cross(d - a);
            self.area.push(0.5 * cross.length());
            self.face_normal.push(cross.normalize_or_zero());
            self.centroid.push((a + b + d) / 3.0);
            for k in 0..3 {
                normals[c[k] as usize] += cross;
                if self.across[f][k] == NONE {
                    self.on_boundary[c[k] as usize] = true;
                    self.on_boundary[c[(k + 1) % 3] as usize] = true;
                }
            }
        }
        self.normals = normals.into_iter().map(|n| n.try_normalize().unwrap_or(Vec3::Z)).collect();
    }

    /// Number of graph vertices.
    pub fn vertex_count(&self) -> usize {
        self.positions.len()
    }

    /// Number of graph faces.
    pub fn face_count(&self) -> usize {
        self.corners.len()
    }

    /// The faces around vertex `v`.
    pub fn faces_of(&self, v: u32) -> &[u32] {
        &self.vertex_faces[self.face_start[v as usize] as usize..self.face_start[v as usize + 1] as usize]
    }

    /// Where `v` sits in face `f`'s corners.
    pub fn corner_of(&self, f: u32, v: u32) -> Option<usize> {
        self.corners[f as usize].iter().position(|&c| c == v)
    }

    /// Total area.
    pub fn total_area(&self) -> f64 {
        self.area.iter().map(|&a| f64::from(a)).sum()
    }

    /// Connected components: a label per face, and the number of labels.
    pub fn components(&self) -> (Vec<u32>, usize) {
        let mut label = vec![NONE; self.face_count()];
        let mut count = 0;
        for seed in 0..self.face_count() {
            if label[seed] != NONE {
                continue;
            }
            let mut stack = vec![seed as u32];
            label[seed] = count;
            while let Some(f) = stack.pop() {
                for &g in &self.across[f as usize] {
                    if g != NONE && label[g as usize] == NONE {
                        label[g as usize] = count;
                        stack.push(g);
                    }
                }
            }
            count += 1;
        }
        (label, count as usize)
    }
}

/// Per face, its neighbours across edges exactly two faces share: (face, whether the two
/// run the edge the same way, the edge).
type Links = Vec<Vec<(u32, bool, (u32, u32))>>;

fn links(incidences: &[crate::mesh::topology::EdgeIncidence], faces: usize) -> Links {
    let mut links: Links = vec![Vec::new(); faces];
    for group in incidences.chunk_by(|a, b| a.key() == b.key()) {
        if let [a, b] = group {
            let same = a.forward == b.forward;
            links[a.face as usize].push((b.face, same, a.key()));
            links[b.face as usize].push((a.face, same, a.key()));
        }
    }
    links
}

/// The first vertex around which the faces form more than one fan, if any.
fn first_pinched_vertex(triangles: &[[u32; 3]], links: &Links, vertices: usize) -> Option<u32> {
    let mut faces_of: Vec<Vec<u32>> = vec![Vec::new(); vertices];
    for (f, t) in triangles.iter().enumerate() {
        for &v in t {
            faces_of[v as usize].push(f as u32);
        }
    }
    (0..vertices as u32).find(|&v| fans(&faces_of[v as usize], links, v).1 > 1)
}

/// The fans of `faces` around vertex `v` (faces joined across an edge at `v` are one):
/// a fan label per face, and their number.
fn fans(faces: &[u32], links: &Links, v: u32) -> (Vec<usize>, usize) {
    let mut sets = UnionFind::new(faces.len());
    for (i, &f) in faces.iter().enumerate() {
        for &(g, _, (a, b)) in &links[f as usize] {
            if a == v || b == v {
                if let Some(j) = faces.iter().position(|&h| h == g) {
                    sets.union(i, j);
                }
            }
        }
    }
    let roots: Vec<usize> = (0..faces.len()).map(|i| sets.find(i)).collect();
    let mut distinct = roots.clone();
    distinct.sort_unstable();
    distinct.dedup();
    let label = roots.iter().map(|r| distinct.binary_search(r).unwrap_or(0)).collect();
    (label, distinct.len())
}

/// Per face, whether to flip it so that faces sharing an edge run along it in opposite
/// directions; the edge of a conflict if there is none.
fn orientation(links: &Links) -> std::result::Result<Vec<bool>, (u32, u32)> {
    let faces = links.len();
    let mut flip = vec![false; faces];
    let mut seen = vec![false; faces];
    for seed in 0..faces {
        if seen[seed] {
            continue;
        }
        seen[seed] = true;
        let mut part = vec![seed];
        let mut next = 0;
        while let Some(&f) = part.get(next) {
            next += 1;
            for &(g, same, edge) in &links[f] {
                let want = flip[f] ^ same;
                if !seen[g as usize] {
                    seen[g as usize] = true;
                    flip[g as usize] = want;
                    part.push(g as usize);
                } else if flip[g as usize] != want {
                    return Err(edge);
                }
            }
        }
        // Keep the winding most of the part's faces already have.
        if 2 * part.iter().filter(|&&f| flip[f]).count() > part.len() {
            for &f in &part {
                flip[f] = !flip[f];
            }
        }
    }
    Ok(flip)
}

/// Renumbers welded corners so that each fan of faces around a welded point is a vertex of
/// its own; returns the corners, per graph vertex its file vertex (the welded one), and per
/// file vertex a graph vertex at its point.
fn split_fans(
    corners: Vec<[u32; 3]>,
    across: &[[u32; 3]],
    remap: &[u32],
) -> (Vec<[u32; 3]>, Vec<u32>, Vec<u32>) {
    let points = remap.len();
    let mut faces_of: Vec<Vec<u32>> = vec![Vec::new(); points];
    for (f, t) in corners.iter().enumerate() {
        for &v in t {
            faces_of[v as usize].push(f as u32);
        }
    }
    let mut out = corners.clone();
    let mut file_vertex = Vec::new();
    let mut first_at = vec![NONE; points];
    for (p, faces) in faces_of.iter().enumerate() {
        if faces.is_empty() {
            continue;
        }
        let mut sets = UnionFind::new(faces.len());
        for (i, &f) in faces.iter().enumerate() {
            let t = corners[f as usize];
            for k in 0..3 {
                let g = across[f as usize][k];
                let touches = t[k] as usize == p || t[(k + 1) % 3] as usize == p;
                if g != NONE && touches {
                    if let Some(j) = faces.iter().position(|&h| h == g) {
                        sets.union(i, j);
                    }
                }
            }
        }
        let mut id_of_root: Vec<(usize, u32)> = Vec::new();
        for (i, &f) in faces.iter().enumerate() {
            let root = sets.find(i);
            let id = match id_of_root.iter().find(|(r, _)| *r == root) {
                Some(&(_, id)) => id,
                None => {
                    let id = file_vertex.len() as u32;
                    file_vertex.push(p as u32);
                    id_of_root.push((root, id));
                    id
                }
            };
            if first_at[p] == NONE {
                first_at[p] = id;
            }
            for k in 0..3 {
                if corners[f as usize][k] as usize == p {
                    out[f as usize][k] = id;
                }
            }
        }
    }
    // Per file vertex: the graph vertex at its welded point (the first fan's).
    let weld = remap.iter().map(|&r| first_at[r as usize]).collect();
    (out, file_vertex, weld)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// An `n`×`n`-quad grid on the unit square (z = 0), as a file would give it.
    pub fn grid(n: u32) -> (Vec<Vec3>, Vec<[u32; 3]>) {
        let mut p = Vec::new();
        for j in 0..=n {
            for i in 0..=n {
                p.push(Vec3::new(i as f32 / n as f32, j as f32 / n as f32, 0.0));
            }
        }
        let at = |i: u32, j: u32| j * (n + 1) + i;
        let mut t = Vec::new();
        for j in 0..n {
            for i in 0..n {
                t.push([at(i, j), at(i + 1, j), at(i + 1, j + 1)]);
                t.push([at(i, j), at(i + 1, j + 1), at(i, j + 1)]);
            }
        }
        (p, t)
    }

    #[test]
    fn a_grid_joins_into_one_oriented_disc() {
        let (p, mut t) = grid(4);
        t[5].swap(1, 2); // one face wound the other way
        let g = SurfaceGraph::new(&p, &t, Path::new("g.obj")).expect("manifold");
        assert_eq!((g.vertex_count(), g.face_count()), (25, 32));
        assert_eq!(g.file_corner[5], [0, 2, 1], "the odd face is oriented for flattening only");
        assert!(g.face_normal.iter().all(|n| n.z > 0.99));
        assert_eq!(g.components().1, 1);
        assert_eq!(g.on_boundary.iter().filter(|&&b| b).count(), 16);
    }

    #[test]
    fn unwelded_patches_join_and_degenerate_faces_are_carried() {
        // Two triangles with duplicated seam vertices, and a sliver whose corners weld.
        let p = vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::X, Vec3::ONE.with_z(0.0), Vec3::Y, Vec3::X];
        let t = vec![[0, 1, 2], [3, 4, 5], [1, 3, 6]];
        let g = SurfaceGraph::new(&p, &t, Path::new("g.obj")).expect("manifold");
        assert_eq!((g.vertex_count(), g.face_count()), (4, 2));
        assert_eq!(g.graph_face, vec![0, 1, NONE]);
        assert_eq!(g.across[0].iter().filter(|&&f| f == 1).count(), 1);
    }

    #[test]
    fn non_manifold_input_is_one_line_naming_the_file() {
        // Three faces on one edge.
        let p = vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::NEG_Y, Vec3::Z];
        let e = SurfaceGraph::new(&p, &[[0, 1, 2], [1, 0, 3], [0, 1, 4]], Path::new("m.obj")).unwrap_err();
        let e = e.to_string();
        assert!(e.starts_with("m.obj: not a manifold surface: the edge between vertices 0 and 1"), "{e}");
        assert_eq!(e.lines().count(), 1);
        // Two fans touching at one vertex (a bow tie).
        let p = vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::NEG_X, Vec3::NEG_Y];
        let e = SurfaceGraph::new(&p, &[[0, 1, 2], [0, 3, 4]], Path::new("m.obj")).unwrap_err().to_string();
        assert!(e.contains("separate fans of faces meet at vertex 0"), "{e}");
    }
}
