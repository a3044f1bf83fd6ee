//! From a triangle soup, as a file parser reads it, to a valid [`Mesh`].
//!
//! Problems that lose information are errors, one line naming the file: no faces, a
//! non-finite coordinate, an index out of range. Problems with an obvious repair are
//! repaired with a `tracing` warning:
//!
//! 1. coincident vertices are welded (exactly equal, or closer than both
//!    [`LoadOptions::weld_tolerance`] times the bounding-box diagonal and 1% of the
//!    shortest edge at either vertex, so that a stray far-away triangle cannot make the
//!    tolerance swallow the model);
//! 2. degenerate faces (a repeated vertex, or zero area at `f32` precision) and duplicate
//!    faces (the same three vertices) are dropped; a mesh of which more than half the faces
//!    are degenerate is refused as damaged;
//! 3. vertices no face uses are dropped;
//! 4. faces are flipped to agree with the majority of their connected neighbours;
//! 5. **non-manifold edges and vertices are split**: faces stay joined across an edge only
//!    if exactly two faces share it with opposite orientations, and each vertex is
//!    duplicated once per fan of faces joined that way around it. An edge shared by three
//!    sheets becomes boundary edges of separate sheets, so everything downstream (the
//!    remesher, one-rings, flattening) can rely on a manifold surface with boundaries.

use super::{bounds_of, manifold, weld, LoadOptions, Mesh};
use crate::{Error, Result};
use glam::Vec3;
use std::collections::HashSet;
use std::path::Path;

/// What a parser produces: positions in the file's precision and fan-triangulated faces
/// with 0-based indices as written (possibly negative or out of range; checked here).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Soup {
    /// Vertex positions.
    pub positions: Vec<[f64; 3]>,
    /// Triangles as indices into `positions`.
    pub triangles: Vec<[i64; 3]>,
}

impl Soup {
    /// Appends polygon `p₀ p₁ … pₙ₋₁` as the triangles `(p₀, pₖ, pₖ₊₁)`; fewer than three
    /// corners append nothing.
    pub fn fan_triangulate(polygon: &[i64], out: &mut Vec<[i64; 3]>) {
        if let Some((&first, rest)) = polygon.split_first() {
            out.extend(rest.windows(2).map(|w| [first, w[0], w[1]]));
        }
    }
}

/// Validates and repairs `soup` read from `path` (see the module documentation).
pub fn prepare(soup: Soup, path: &Path, options: &LoadOptions) -> Result<Mesh> {
    if soup.triangles.is_empty() {
        return Err(Error::format(path, "the file has no faces (is it a mesh?)"));
    }
    let positions = checked_positions(&soup.positions, path)?;
    let mut triangles = checked_triangles(&soup.triangles, positions.len(), path)?;
    let diagonal = {
        let (lo, hi) = bounds_of(&positions);
        (hi - lo).length()
    };
    let (remap, merged) =
        weld::weld(&positions, &triangles, weld::LOCAL_FRACTION, options.weld_tolerance * diagonal);
    if merged > 0 {
        tracing::info!("{}: welded {merged} coincident vertices", path.display());
    }
    for t in &mut triangles {
        *t = t.map(|i| remap[i as usize]);
    }
    let faces = triangles.len();
    let (triangles, degenerate, duplicate) = drop_bad_faces(&positions, triangles);
    if triangles.is_empty() {
        return Err(Error::format(path, "every face is degenerate (zero area)"));
    }
    // A few slivers are repaired; a mesh that is mostly slivers is damaged, and what
    // would remain of it is not the model.
    if 2 * degenerate > faces {
        return Err(Error::format(
            path,
            format!("{degenerate} of {faces} faces are degenerate (zero area, or a corner repeated): the mesh is damaged"),
        ));
    }
    if degenerate > 0 || duplicate > 0 {
        tracing::warn!(
            "{}: dropped {degenerate} degenerate and {duplicate} duplicate faces of {faces}",
            path.display()
        );
    }
    let (positions, mut triangles, dropped) = drop_unused_vertices(positions, triangles);
    // Welded duplicates are unused by now; only report vertices the file left unused.
    if dropped > merged {
        tracing::info!("{}: dropped {} vertices that no face uses", path.display(), dropped - merged);
    }
    let flipped = manifold::orient(&mut triangles);
    if flipped > 0 {
        tracing::warn!(
            "{}: flipped {flipped} faces to agree with their neighbours' orientation",
            path.display()
        );
    }
    let (positions, triangles) = split_non_manifold(positions, triangles, path)?;
    Ok(Mesh::from_valid_parts(positions, triangles).with_normals())
}

/// Positions as `f32`, or the first one that is not finite.
fn checked_positions(positions: &[[f64; 3]], path: &Path) -> Result<Vec<Vec3>> {
    let converted: Vec<Vec3> =
        positions.iter().map(|p| Vec3::new(p[0] as f32, p[1] as f32, p[2] as f32)).collect();
    let bad = converted.iter().filter(|p| !p.is_finite()).count();
    if let Some(i) = converted.iter().position(|p| !p.is_finite()) {
        let [x, y, z] = positions[i];
        return Err(Error::format(
            path,
            format!(
                "vertex {i} has a non-finite coordinate ({x} {y} {z}); \
                 {bad} of {} vertices are affected",
                positions.len()
            ),
        ));
    }
    Ok(converted)
}

/// Triangles as `u32`, or the first index that is out of range.
fn checked_triangles(triangles: &[[i64; 3]], vertices: usize, path: &Path) -> Result<Vec<[u32; 3]>> {
    let in_range = |i: i64| usize::try_from(i).is_ok_and(|i| i < vertices);
    for (f, t) in triangles.iter().enumerate() {
        if let Some(&i) = t.iter().find(|&&i| !in_range(i)) {
            return Err(Error::format(
                path,
                format!(
                    "face {f} refers to vertex {i} (counting from 0), \
                     but the file has {vertices} vertices"
                ),
            ));
        }
    }
    if vertices > u32::MAX as usize {
        return Err(Error::format(path, format!("{vertices} vertices are more than 2³² − 1")));
    }
    Ok(triangles.iter().map(|t| t.map(|i| i as u32)).collect())
}

/// Drops degenerate faces (repeated vertex, zero area) and repeats of an earlier face;
/// returns the rest and how many of each kind were dropped.
fn drop_bad_faces(positions: &[Vec3], triangles: Vec<[u32; 3]>) -> (Vec<[u32; 3]>, usize, usize) {
    let mut seen = HashSet::with_capacity(triangles.len());
    let (mut degenerate, mut duplicate) = (0usize, 0usize);
    let kept: Vec<[u32; 3]> = triangles
        .into_iter()
        .filter(|t| {
            if is_degenerate(positions, t) {
                degenerate += 1;
                return false;
            }
            let mut key = *t;
            key.sort_unstable();
            if !seen.insert(key) {
                duplicate += 1;
                return false;
            }
            true
        })
        .collect();
    (kept, degenerate, duplicate)
}

/// True for a repeated vertex, or an area below `f32` resolution of its longest edge:
/// such faces have no defined normal and break every later angle computation.
fn is_degenerate(positions: &[Vec3], t: &[u32; 3]) -> bool {
    if t[0] == t[1] || t[1] == t[2] || t[0] == t[2] {
        return true;
    }
    let [a, b, c] = t.map(|i| positions[i as usize]);
    let longest = (b - a).length_squared().max((c - b).length_squared()).max((a - c).length_squared());
    (b - a).cross(c - a).length() <= 1e-7 * longest
}

/// Drops vertices no face uses, renumbering in the original order; returns how many.
fn drop_unused_vertices(
    positions: Vec<Vec3>,
    mut triangles: Vec<[u32; 3]>,
) -> (Vec<Vec3>, Vec<[u32; 3]>, usize) {
    let mut new_index = vec![u32::MAX; positions.len()];
    for t in &triangles {
        for &i in t {
            new_index[i as usize] = 0;
        }
    }
    let mut kept = Vec::with_capacity(positions.len());
    for (i, p) in positions.iter().enumerate() {
        if new_index[i] == 0 {
            new_index[i] = kept.len() as u32;
            kept.push(*p);
        }
    }
    for t in &mut triangles {
        *t = t.map(|i| new_index[i as usize]);
    }
    let dropped = positions.len() - kept.len();
    (kept, triangles, dropped)
}

/// Splits non-manifold edges and vertices (see the module documentation).
fn split_non_manifold(
    mut positions: Vec<Vec3>,
    mut triangles: Vec<[u32; 3]>,
    path: &Path,
) -> Result<(Vec<Vec3>, Vec<[u32; 3]>)> {
    let added = manifold::split(&mut positions, &mut triangles);
    if added > 0 {
        tracing::warn!("{}: split non-manifold edges or vertices, adding {added} vertices", path.display());
    }
    if !manifold::is_manifold(&triangles) {
        return Err(Error::format(path, "the surface could not be made manifold"));
    }
    Ok((positions, triangles))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn soup(positions: &[[f64; 3]], triangles: &[[i64; 3]]) -> Soup {
        Soup { positions: positions.to_vec(), triangles: triangles.to_vec() }
    }

    fn prep(s: Soup) -> Result<Mesh> {
        prepare(s, Path::new("m.ply"), &LoadOptions::default())
    }

    const QUAD: [[f64; 3]; 4] = [[0., 0., 0.], [1., 0., 0.], [1., 1., 0.], [0., 1., 0.]];

    #[test]
    fn nan_vertex_is_one_error_naming_the_file() {
        let mut p = QUAD.to_vec();
        p[2][1] = f64::NAN;
        let e = prep(soup(&p, &[[0, 1, 2], [0, 2, 3]])).unwrap_err().to_string();
        assert!(e.starts_with("m.ply: vertex 2 has a non-finite coordinate"), "{e}");
        assert!(!e.contains('\n'));
    }

    #[test]
    fn coordinate_beyond_f32_is_non_finite() {
        let mut p = QUAD.to_vec();
        p[0][0] = 1e300;
        assert!(prep(soup(&p, &[[0, 1, 2]])).is_err());
    }

    #[test]
    fn out_of_range_and_negative_indices_are_errors() {
        let e = prep(soup(&QUAD, &[[0, 1, 4]])).unwrap_err().to_string();
        assert!(e.contains("m.ply: face 0 refers to vertex 4") && e.contains("4 vertices"), "{e}");
        assert!(prep(soup(&QUAD, &[[0, -1, 2]])).is_err());
    }

    #[test]
    fn no_faces_is_an_error() {
        let e = prep(soup(&QUAD, &[])).unwrap_err().to_string();
        assert!(e.contains("no faces"), "{e}");
    }

    #[test]
    fn degenerate_and_duplicate_faces_are_dropped() {
        let mut p = QUAD.to_vec();
        p.push([0.5, 0.0, 0.0]); // on the edge 0–1: the face (0, 4, 1) has zero area
        let m = prep(soup(&p, &[[0, 1, 2], [0, 2, 3], [0, 0, 1], [0, 4, 1], [2, 0, 1]])).unwrap();
        assert_eq!(m.triangles(), &[[0, 1, 2], [0, 2, 3]]);
        assert_eq!(m.vertex_count(), 4, "the vertex only a dropped face used is gone");
        assert!(prep(soup(&p, &[[0, 4, 1]])).is_err(), "only degenerate faces");
    }

    #[test]
    fn coincident_vertices_are_welded() {
        let p = [QUAD[0], QUAD[1], QUAD[2], QUAD[0], QUAD[2], QUAD[3]];
        let m = prep(soup(&p, &[[0, 1, 2], [3, 4, 5]])).unwrap();
        assert_eq!(m.vertex_count(), 4);
        assert_eq!(crate::mesh::topology::edges(&m).len(), 5);
    }

    #[test]
    fn a_flipped_face_is_turned_to_match_the_majority() {
        let p = [QUAD[0], QUAD[1], QUAD[2], QUAD[3], [2., 0., 0.], [2., 1., 0.]];
        let m = prep(soup(&p, &[[0, 1, 2], [0, 3, 2], [1, 4, 5], [1, 5, 2]])).unwrap();
        assert_eq!(m.triangles()[1], [0, 2, 3]);
    }
}
