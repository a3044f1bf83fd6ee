//! Per-vertex direction fields that orient the texture (Tong §5.1, Turk §4.1): a field
//! of unit tangents `s`, which with the normal `n` gives each vertex a frame (s, t = n × s, n).
//!
//! Three ways to ask for a field ([`Orientation`]):
//! - [`Orientation::Smooth`] (the default): a smooth field with no preferred direction,
//!   the projection of a seeded random axis relaxed over the vertex hierarchy below;
//! - [`Orientation::Axis`]: one 3D direction projected onto every tangent plane;
//! - [`Orientation::Constraints`]: directions given at a few places, interpolated by
//!   Turk's pull/push over a vertex hierarchy of the mesh (Turk 2001 §4.1): pulled down to
//!   a coarsest level of about a hundred vertices, filled in and relaxed there, and pushed
//!   back up level by level, each level smoothed a few sweeps.
//!
//! ```no_run
//! use btfsynth::mesh::{self, field::{self, Orientation}};
//!
//! let bunny = mesh::load(std::path::Path::new("bunny.obj"))?;
//! let frames = field::frames(&bunny, &Orientation::parse("axis:0,1,0")?, 7)?;
//! assert_eq!(frames.len(), bunny.vertex_count());
//! # Ok::<(), btfsynth::Error>(())
//! ```

use super::field_hierarchy::{Adjacency, Hierarchy, Level};
use super::frames::{tangent_towards, Frames};
use super::topology::{one_rings, VertexRings};
use super::Mesh;
use crate::{Error, Result};
use glam::Vec3;
use std::borrow::Cow;
use std::path::Path;

/// Relaxation sweeps on each level of the hierarchy after the coarser field is pushed onto
/// it ([`Orientation::Constraints`]): the coarser level already holds the field's shape, so
/// only the few rings between coarse vertices, and around constraints, need smoothing.
pub const PUSH_SWEEPS: usize = 4;

/// At most this many sweeps relax the coarsest level (of at most about a hundred
/// vertices); they stop earlier once no direction moves by more than [`SETTLED`].
const COARSEST_SWEEPS: usize = 10_000;

/// A direction that moves less than this in a sweep has settled.
const SETTLED: f32 = 1e-5;

/// How the texture's "right" direction `s` is chosen at each vertex.
#[derive(Clone, Debug, Default, PartialEq)]
pub enum Orientation {
    /// A smooth field with no preferred direction (default). The seed picks the random
    /// axis it starts from, so the same seed gives the same field.
    #[default]
    Smooth,
    /// This direction, projected onto each tangent plane. Where it is parallel to the
    /// normal, any tangent is used (the field has a singularity there).
    Axis(Vec3),
    /// Directions fixed at a few vertices, interpolated everywhere else.
    Constraints(Vec<Constraint>),
}

/// A user direction at one place on the surface: at a vertex index, or at a 3D point
/// (snapped to its nearest vertex). Exactly one of `vertex` and `point` is set.
#[derive(Clone, Debug, PartialEq)]
pub struct Constraint {
    /// The vertex index the direction applies to.
    pub vertex: Option<usize>,
    /// A point in the mesh's coordinates; the nearest vertex takes the direction.
    pub point: Option<Vec3>,
    /// The desired direction (any non-zero length; projected onto the tangent plane).
    pub direction: Vec3,
}

/// The JSON form of a constraints file, as documented on [`Orientation::parse`].
#[derive(serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct ConstraintsFile {
    constraints: Vec<ConstraintJson>,
}

#[derive(serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct ConstraintJson {
    vertex: Option<usize>,
    point: Option<[f32; 3]>,
    direction: [f32; 3],
}

impl Orientation {
    /// Parses a command-line value: `smooth`, `axis:x,y,z` (a non-zero direction), or the
    /// path of a JSON file such as
    /// `{"constraints": [{"vertex": 12, "direction": [1,0,0]}, {"point": [0.1,0.2,0.3], "direction": [0,1,0]}]}`.
    /// Vertex indices are checked against the mesh later, by [`frames`].
    pub fn parse(arg: &str) -> Result<Orientation> {
        if arg == "smooth" {
            return Ok(Orientation::Smooth);
        }
        if let Some(rest) = arg.strip_prefix("axis:") {
            return parse_axis(rest).map(Orientation::Axis);
        }
        let path = Path::new(arg);
        if !path.exists() {
            return Err(Error::out_of_range(
                crate::Param::FrameOrientation,
                format!("{arg:?}"),
                "expected `smooth`, `axis:x,y,z` or the path of a JSON constraints file",
            ));
        }
        load_constraints(path).map(Orientation::Constraints)
    }
}

/// Parses `x,y,z` into a finite, non-zero vector.
fn parse_axis(text: &str) -> Result<Vec3> {
    let refuse =
        |why: &str| Error::out_of_range(crate::Param::FrameOrientation, format!("axis {text:?}"), why);
    let bad = || refuse("expected three numbers `x,y,z`");
    let parts: Vec<f32> =
        text.split(',').map(|p| p.trim().parse::<f32>().map_err(|_| bad())).collect::<Result<_>>()?;
    let [x, y, z] = parts[..] else { return Err(bad()) };
    check_direction(Vec3::new(x, y, z)).map_err(|why| refuse(&why))
}

/// Why `d` cannot be a direction, if it cannot.
fn check_direction(d: Vec3) -> std::result::Result<Vec3, String> {
    if !d.is_finite() {
        Err("the direction must be finite".into())
    } else if d.length_squared() < 1e-20 {
        Err("the direction must not be zero".into())
    } else {
        Ok(d)
    }
}

/// Reads and validates a constraints file; every error names the file.
fn load_constraints(path: &Path) -> Result<Vec<Constraint>> {
    let text = crate::fsutil::read_input_text(path)?;
    let file: ConstraintsFile =
        serde_json::from_str(&text).map_err(|e| Error::format(path, format!("bad constraints JSON: {e}")))?;
    if file.constraints.is_empty() {
        return Err(Error::format(path, "the constraints list is empty; use `smooth` for no constraints"));
    }
    file.constraints
        .into_iter()
        .enumerate()
        .map(|(i, c)| constraint_from_json(i, c))
        .collect::<Result<_, String>>()
        .map_err(|why| Error::format(path, why))
}

/// Validates constraint number `i` of a file.
fn constraint_from_json(i: usize, c: ConstraintJson) -> std::result::Result<Constraint, String> {
    let direction =
        check_direction(Vec3::from(c.direction)).map_err(|why| format!("constraint {i}: {why}"))?;
    let point = c.point.map(Vec3::from);
    match (c.vertex, point) {
        (Some(_), Some(_)) | (None, None) => {
            Err(format!("constraint {i}: give exactly one of \"vertex\" and \"point\""))
        }
        (_, Some(p)) if !p.is_finite() => Err(format!("constraint {i}: the point must be finite")),
        (vertex, point) => Ok(Constraint { vertex, point, direction }),
    }
}

/// Orthonormal, right-handed frames for every vertex of `mesh`, oriented as asked; `n` is
/// the area-weighted vertex normal. `seed` only matters for [`Orientation::Smooth`] and for
/// parts of the mesh that no constraint reaches. Fails if a constraint names a vertex the
/// mesh does not have.
pub fn frames(mesh: &Mesh, orientation: &Orientation, seed: u64) -> Result<Frames> {
    let normals = area_weighted_normals(mesh);
    let directions = match orientation {
        Orientation::Axis(d) => {
            let d = check_direction(*d).map_err(|why| Error::invalid(format!("orientation axis: {why}")))?;
            vec![d; mesh.vertex_count()]
        }
        Orientation::Smooth => smooth_field(mesh.positions(), &normals, &one_rings(mesh), seed),
        Orientation::Constraints(constraints) => {
            let fixed = snap_constraints(mesh, constraints)?;
            constrained_field(mesh.positions(), &normals, &one_rings(mesh), &fixed, seed)
        }
    };
    Ok(Frames::from_directions(&normals, &directions))
}

/// The mesh's normals, computed if it has none (loaders always compute them).
fn area_weighted_normals(mesh: &Mesh) -> Cow<'_, [Vec3]> {
    match mesh.normals() {
        Some(n) => Cow::Borrowed(n),
        None => Cow::Owned(mesh.clone().with_normals().normals().unwrap_or_default().to_vec()),
    }
}

/// A unit axis drawn uniformly from the sphere, a pure function of `seed`.
fn random_axis(seed: u64) -> Vec3 {
    let v = Vec3::new(
        crate::seeded::normal(seed, 0, 0),
        crate::seeded::normal(seed, 1, 0),
        crate::seeded::normal(seed, 2, 0),
    );
    v.try_normalize().unwrap_or(Vec3::X)
}

/// A projected random axis, relaxed over the vertex hierarchy as constraints are
/// ([`constrained_field`] with none): until it settles on the coarsest level, then a few
/// sweeps per level on the way up. Relaxed on the level itself (40 sweeps, until 7
/// December) the field kept the projected axis' turns at every scale beyond 40 rings, and
/// the start's patches, summed step by step in each vertex's frame, sheared where it
/// turned: 14% of an exported texture's windows showed a magnified copy, which carried
/// the smears in excess of the sample's own (docs/surfaces.md, "A smooth field").
fn smooth_field(positions: &[Vec3], normals: &[Vec3], rings: &VertexRings, seed: u64) -> Vec<Vec3> {
    constrained_field(positions, normals, rings, &vec![None; normals.len()], seed)
}

/// `sweeps` Gauss–Seidel sweeps: each free vertex takes the normalised tangential part
/// of the sum of its neighbours' directions (projection is the cheapest transport between
/// nearby tangent planes). A vertex whose neighbours cancel keeps its direction. Returns
/// the largest change of a direction in the last sweep.
fn relax(field: &mut [Vec3], normals: &[Vec3], graph: &impl Adjacency, fixed: &[bool], sweeps: usize) -> f32 {
    let mut largest = 0.0;
    for _ in 0..sweeps {
        largest = 0.0f32;
        for v in 0..field.len() {
            if fixed[v] {
                continue;
            }
            let sum: Vec3 = graph.neighbours(v).iter().map(|&w| field[w as usize]).sum();
            let n = normals[v];
            let tangential = sum - n * n.dot(sum);
            if let Some(d) = tangential.try_normalize() {
                largest = largest.max(d.distance(field[v]));
                field[v] = d;
            }
        }
    }
    largest
}

/// Resolves each constraint to a vertex and its direction; later constraints on the same
/// vertex override earlier ones.
fn snap_constraints(mesh: &Mesh, constraints: &[Constraint]) -> Result<Vec<Option<Vec3>>> {
    let mut fixed = vec![None; mesh.vertex_count()];
    for (i, c) in constraints.iter().enumerate() {
        let direction =
            check_direction(c.direction).map_err(|why| Error::invalid(format!("constraint {i}: {why}")))?;
        let v = constraint_vertex(mesh, i, c)?;
        fixed[v] = Some(direction);
    }
    Ok(fixed)
}

/// The vertex a constraint applies to, checked against the mesh.
fn constraint_vertex(mesh: &Mesh, i: usize, c: &Constraint) -> Result<usize> {
    let count = mesh.vertex_count();
    match (c.vertex, c.point) {
        (Some(v), None) if v < count => Ok(v),
        (Some(v), None) => Err(Error::invalid(format!(
            "constraint {i}: vertex {v} is out of range (the mesh has {count} vertices)"
        ))),
        (None, Some(p)) if p.is_finite() => Ok(nearest_vertex(mesh.positions(), p)),
        _ => Err(Error::invalid(format!("constraint {i}: give exactly one finite \"vertex\" or \"point\""))),
    }
}

/// Index of the position nearest `p` (a linear scan: constraints are few).
fn nearest_vertex(positions: &[Vec3], p: Vec3) -> usize {
    let mut best = (0, f32::INFINITY);
    for (i, q) in positions.iter().enumerate() {
        let d = q.distance_squared(p);
        if d < best.1 {
            best = (i, d);
        }
    }
    best.0
}

/// Turk §4.1: the constraints are pulled down the vertex hierarchy to its coarsest level,
/// filled in there (a diffusion front, then relaxation until nothing moves, which is cheap
/// on a hundred vertices), and pushed back up: each finer level interpolates the coarser
/// field, holds its own (pulled) constraints and is relaxed a few sweeps, which is all the
/// detail between coarse vertices needs. Far from every constraint the field is as
/// smooth as the coarsest level makes it, which relaxing the finest level alone would take
/// thousands of sweeps to reach.
fn constrained_field(
    positions: &[Vec3],
    normals: &[Vec3],
    rings: &VertexRings,
    fixed: &[Option<Vec3>],
    seed: u64,
) -> Vec<Vec3> {
    let hierarchy = Hierarchy::build(positions, normals, rings);
    let levels = hierarchy.levels();
    let mut constraints: Vec<Vec<Option<Vec3>>> =
        vec![fixed.iter().zip(normals).map(|(d, &n)| d.map(|d| tangent_towards(n, d))).collect()];
    for k in 0..levels.len() - 1 {
        let pulled = hierarchy.pull(k, &constraints[k]);
        constraints.push(pulled);
    }
    let coarsest = levels.len() - 1;
    let mut field = filled_coarsest(&levels[coarsest], &constraints[coarsest], seed);
    for k in (0..coarsest).rev() {
        field = hierarchy.push(k, &field);
        let is_fixed = hold(&mut field, &constraints[k]);
        relax(&mut field, &levels[k].normals, &levels[k].graph, &is_fixed, PUSH_SWEEPS);
    }
    // The raw directions make each constrained frame exactly `tangent_towards(n, d)`, with
    // no rounding from projecting twice.
    for (d, f) in field.iter_mut().zip(fixed) {
        if let Some(f) = f {
            *d = *f;
        }
    }
    field
}

/// The field on the coarsest level: its constraints, spread by a diffusion front, then
/// relaxed until it settles. Components with no constraint start from the smooth field's
/// projected random axis.
fn filled_coarsest(level: &Level, constraints: &[Option<Vec3>], seed: u64) -> Vec<Vec3> {
    let mut field: Vec<Vec3> = constraints.iter().map(|d| d.unwrap_or(Vec3::ZERO)).collect();
    fill_by_diffusion(&mut field, &level.normals, &level.graph);
    let axis = random_axis(seed);
    for (d, &n) in field.iter_mut().zip(&level.normals) {
        if *d == Vec3::ZERO {
            *d = tangent_towards(n, axis);
        }
    }
    let is_fixed: Vec<bool> = constraints.iter().map(Option::is_some).collect();
    for _ in 0..COARSEST_SWEEPS {
        if relax(&mut field, &level.normals, &level.graph, &is_fixed, 1) < SETTLED {
            break;
        }
    }
    field
}

/// Sets the constrained entries of `field` and says which they are.
fn hold(field: &mut [Vec3], constraints: &[Option<Vec3>]) -> Vec<bool> {
    field
        .iter_mut()
        .zip(constraints)
        .map(|(d, c)| {
            if let Some(c) = c {
                *d = *c;
            }
            c.is_some()
        })
        .collect()
}

/// Grows the set of vertices with a direction one ring per sweep: an unassigned vertex
/// takes the projected mean of its neighbours assigned in earlier sweeps (so the result
/// does not depend on vertex order within a sweep). Zero marks "unassigned".
fn fill_by_diffusion(field: &mut [Vec3], normals: &[Vec3], graph: &impl Adjacency) {
    loop {
        let mut updates = Vec::new();
        for v in (0..field.len()).filter(|&v| field[v] == Vec3::ZERO) {
            let assigned: Vec<Vec3> =
                graph.neighbours(v).iter().map(|&w| field[w as usize]).filter(|d| *d != Vec3::ZERO).collect();
            if let Some(&first) = assigned.first() {
                // Opposed neighbours can cancel; then follow any one of them.
                let sum: Vec3 = assigned.iter().sum();
                let d = tangent_towards(normals[v], sum);
                let d = if sum.length_squared() > 1e-12 { d } else { tangent_towards(normals[v], first) };
                updates.push((v, d));
            }
        }
        if updates.is_empty() {
            return;
        }
        for (v, d) in updates {
            field[v] = d;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::test_meshes::grid;

    fn bunny() -> Mesh {
        crate::mesh::load(Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/data/bunny-1k8.obj")))
            .expect("bunny")
    }

    /// Mean angle in degrees between the `s` of neighbouring vertices, over all edges.
    fn mean_neighbour_angle(mesh: &Mesh, s: &[Vec3]) -> f32 {
        let rings = one_rings(mesh);
        let angles: Vec<f32> = (0..mesh.vertex_count())
            .flat_map(|v| rings.ring(v).iter().map(move |&w| (v, w as usize)))
            .map(|(v, w)| s[v].dot(s[w]).clamp(-1.0, 1.0).acos().to_degrees())
            .collect();
        angles.iter().sum::<f32>() / angles.len() as f32
    }

    fn assert_orthonormal(f: &Frames) {
        for i in 0..f.len() {
            let (s, t, n) = (f.s[i], f.t[i], f.n[i]);
            assert!((s.length() - 1.0).abs() < 1e-5 && (t.length() - 1.0).abs() < 1e-5, "vertex {i}");
            assert!(s.dot(n).abs() < 1e-5 && t.dot(n).abs() < 1e-5 && s.dot(t).abs() < 1e-5, "vertex {i}");
            assert!((s.cross(t) - n).length() < 1e-5, "vertex {i} is not right-handed");
        }
    }

    fn write_temp(text: &str) -> (tempfile::TempDir, String) {
        let dir = tempfile::tempdir().expect("temp dir");
        let path = dir.path().join("constraints.json");
        std::fs::write(&path, text).expect("write");
        let arg = path.to_str().expect("utf-8 temp path").to_owned();
        (dir, arg)
    }

    #[test]
    fn every_orientation_gives_orthonormal_frames_on_the_bunny() {
        let bunny = bunny();
        let normals = bunny.normals().expect("loaded meshes have normals").to_vec();
        let constraint = Constraint { vertex: Some(3), point: None, direction: Vec3::Y };
        for o in [Orientation::Smooth, Orientation::Axis(Vec3::X), Orientation::Constraints(vec![constraint])]
        {
            let f = frames(&bunny, &o, 1).expect("frames");
            assert_eq!(f.n, normals, "{o:?}: n is the area-weighted normal");
            assert_orthonormal(&f);
        }
    }

    #[test]
    fn an_axis_in_the_plane_of_a_flat_grid_is_s_exactly() {
        let axis = Vec3::new(1.0, 2.0, 0.0);
        let f = frames(&grid(6), &Orientation::Axis(axis), 0).expect("frames");
        assert!(f.s.iter().all(|&s| s == axis.normalize()));
        // The grid's normals are +Z up to rounding in normalisation, which keeps s exact.
        assert!(f.n.iter().all(|&n| (n - Vec3::Z).length() < 1e-6));
    }

    #[test]
    fn an_axis_is_followed_on_the_bunny_away_from_its_poles() {
        let bunny = bunny();
        let axis = Vec3::new(0.3, 1.0, -0.2).normalize();
        let f = frames(&bunny, &Orientation::Axis(axis), 0).expect("frames");
        for i in (0..f.len()).filter(|&i| f.n[i].dot(axis).abs() < 0.99) {
            assert!(f.s[i].dot(axis) >= 0.0, "vertex {i}");
            assert!((f.s[i] - tangent_towards(f.n[i], axis)).length() < 1e-5, "vertex {i}");
        }
    }

    #[test]
    fn smooth_is_smoother_than_random_and_deterministic() {
        let bunny = bunny();
        let f = frames(&bunny, &Orientation::Smooth, 42).expect("frames");
        let random: Vec<Vec3> = (0..bunny.vertex_count() as i64)
            .map(|v| Vec3::from_array([0, 1, 2].map(|k| crate::seeded::normal(9, v, k))))
            .zip(&f.n)
            .map(|(d, &n)| tangent_towards(n, d))
            .collect();
        let (smooth, rough) = (mean_neighbour_angle(&bunny, &f.s), mean_neighbour_angle(&bunny, &random));
        assert!(smooth < 20.0 && rough > 3.0 * smooth, "smooth {smooth}°, random {rough}°");
        assert_eq!(f, frames(&bunny, &Orientation::Smooth, 42).expect("frames"));
        assert_ne!(f.s, frames(&bunny, &Orientation::Smooth, 43).expect("frames").s);
    }

    /// On a dense mesh the hierarchy carries the relaxation to every scale: the field turns
    /// less between neighbours than the projected axis relaxed 40 sweeps on the level itself
    /// (the smooth field until 7 December), whose turns beyond 40 rings stayed where the
    /// axis put them: 0.84–0.87 of its mean angle on a 30k-vertex bunny, seeds 1–3.
    #[test]
    fn the_smooth_field_turns_less_than_one_relaxed_on_its_level_alone() {
        let bunny = bunny();
        let target = crate::mesh::remesh::RemeshParams::vertex_count(&bunny, 30_000);
        let dense = crate::mesh::remesh::remesh(&bunny, &target, &crate::progress::Silent).expect("remesh");
        let dense = dense.with_normals();
        let normals = dense.normals().expect("normals").to_vec();
        for seed in 1..=3 {
            let axis = random_axis(seed);
            let mut local: Vec<Vec3> = normals.iter().map(|&n| tangent_towards(n, axis)).collect();
            relax(&mut local, &normals, &one_rings(&dense), &vec![false; normals.len()], 40);
            let smooth = frames(&dense, &Orientation::Smooth, seed).expect("frames");
            let hierarchy = mean_neighbour_angle(&dense, &smooth.s);
            let level_alone = mean_neighbour_angle(&dense, &local);
            assert!(
                hierarchy < 0.9 * level_alone,
                "seed {seed}: hierarchy {hierarchy}°, level alone {level_alone}°"
            );
        }
    }

    #[test]
    fn constraints_hold_exactly_and_the_field_is_smooth_between_them() {
        let bunny = bunny();
        let (lo, hi) = bunny.bounds();
        let cs = vec![
            Constraint { vertex: Some(10), point: None, direction: Vec3::X },
            Constraint { vertex: None, point: Some(hi), direction: Vec3::new(0.0, 1.0, 1.0) },
            Constraint { vertex: None, point: Some(lo), direction: Vec3::new(-1.0, 0.0, 1.0) },
        ];
        let f = frames(&bunny, &Orientation::Constraints(cs.clone()), 0).expect("frames");
        for c in &cs {
            let v = c.vertex.unwrap_or_else(|| nearest_vertex(bunny.positions(), c.point.expect("point")));
            assert_eq!(f.s[v], tangent_towards(f.n[v], c.direction), "constraint at vertex {v}");
        }
        let angle = mean_neighbour_angle(&bunny, &f.s);
        assert!(angle < 20.0, "mean neighbour angle {angle}°");
        assert_orthonormal(&f);
    }

    #[test]
    fn a_constrained_field_reaches_every_vertex_of_the_bunny_whatever_the_seed() {
        let bunny = bunny();
        let c = |v, direction| Constraint { vertex: Some(v), point: None, direction };
        let cs = Orientation::Constraints(vec![c(100, Vec3::X), c(1500, Vec3::new(0.0, 1.0, 1.0))]);
        let f = frames(&bunny, &cs, 0).expect("frames");
        assert!(f.s.iter().all(|s| s.is_finite() && (s.length() - 1.0).abs() < 1e-5));
        // Only vertices that no constraint reaches depend on the seed (the bunny is one piece).
        assert_eq!(f, frames(&bunny, &cs, 99).expect("frames"));
        // This coarse bunny's curvature alone costs ~10°: the unconstrained smooth field
        // measures 10.0° and finest-level diffusion from these two constraints 11.3°.
        let angle = mean_neighbour_angle(&bunny, &f.s);
        assert!(angle < 12.0, "mean neighbour angle {angle}°");
    }

    #[test]
    fn one_constraint_on_a_flat_grid_is_followed_everywhere() {
        let g = grid(32);
        let normals = area_weighted_normals(&g);
        assert!(Hierarchy::build(g.positions(), &normals, &one_rings(&g)).levels().len() >= 3);
        let c = Constraint { vertex: None, point: Some(Vec3::new(0.49, 0.51, 0.3)), direction: Vec3::Y };
        let f = frames(&g, &Orientation::Constraints(vec![c]), 0).expect("frames");
        assert!(f.s.iter().all(|s| (*s - Vec3::Y).length() < 1e-4), "{:?}", f.s);
    }

    /// A `length` × `width` grid of unit squares in the z = 0 plane.
    fn strip(length: u32, width: u32) -> Mesh {
        let at = |i: u32, j: u32| j * (length + 1) + i;
        let p =
            (0..=width).flat_map(|j| (0..=length).map(move |i| Vec3::new(i as f32, j as f32, 0.0))).collect();
        let t = (0..width)
            .flat_map(|j| (0..length).map(move |i| (i, j)))
            .flat_map(|(i, j)| {
                [[at(i, j), at(i + 1, j), at(i + 1, j + 1)], [at(i, j), at(i + 1, j + 1), at(i, j + 1)]]
            })
            .collect();
        Mesh::new(p, t).expect("the strip is valid")
    }

    #[test]
    fn between_two_constraints_on_a_long_strip_the_field_turns_evenly() {
        // Finest-level diffusion and relaxation leaves two halves that meet at a seam:
        // relaxation would take ~length² sweeps to even the turn out; the hierarchy's
        // coarsest level does it on a hundred vertices.
        let (length, width) = (240, 4);
        let s = strip(length, width);
        let mid_row = |i: u32| Some((width / 2 * (length + 1) + i) as usize);
        let cs = vec![
            Constraint { vertex: mid_row(0), point: None, direction: Vec3::X },
            Constraint { vertex: mid_row(length), point: None, direction: Vec3::Y },
        ];
        let f = frames(&s, &Orientation::Constraints(cs), 0).expect("frames");
        for quarter in 1..4 {
            let i = quarter * length / 4;
            let angles: Vec<f32> = (0..=width)
                .map(|j| f.s[(j * (length + 1) + i) as usize])
                .map(|d| d.y.atan2(d.x).to_degrees())
                .collect();
            let expected = 90.0 * i as f32 / length as f32;
            assert!(
                angles.iter().all(|a| (a - expected).abs() < 6.0),
                "at x = {i}: {angles:?}°, not {expected}°"
            );
        }
    }

    #[test]
    fn parses_smooth_axis_and_constraint_files() {
        assert_eq!(Orientation::parse("smooth").expect("smooth"), Orientation::Smooth);
        assert_eq!(
            Orientation::parse("axis:1, 0,2").expect("axis"),
            Orientation::Axis(Vec3::new(1.0, 0.0, 2.0))
        );
        let (_dir, path) = write_temp(
            r#"{"constraints": [{"vertex": 12, "direction": [1,0,0]}, {"point": [0.1, 0.2, 0.3], "direction": [0,1,0]}]}"#,
        );
        let expected = vec![
            Constraint { vertex: Some(12), point: None, direction: Vec3::X },
            Constraint { vertex: None, point: Some(Vec3::new(0.1, 0.2, 0.3)), direction: Vec3::Y },
        ];
        assert_eq!(Orientation::parse(&path).expect("file"), Orientation::Constraints(expected));
    }

    #[test]
    fn rejects_bad_axis_strings() {
        for arg in
            ["axis:", "axis:1,2", "axis:1,2,3,4", "axis:a,b,c", "axis:0,0,0", "axis:NaN,0,1", "axis:inf,0,0"]
        {
            let e = Orientation::parse(arg).expect_err(arg);
            assert!(matches!(e, Error::OutOfRange { param: crate::Param::FrameOrientation, .. }), "{e:?}");
            let e = e.to_string();
            assert!(e.starts_with("frame orientation axis") && !e.contains('\n'), "{arg}: {e}");
        }
        assert!(Orientation::parse("no-such-file.json").is_err());
    }

    #[test]
    fn rejects_bad_constraint_files_naming_the_file() {
        let cases = [
            ("{\"constraints\": [", "bad constraints JSON"),
            (r#"{"constraints": [{"vertex": 1, "direction": [0,0,0]}]}"#, "must not be zero"),
            (r#"{"constraints": [{"vertex": 1, "direction": [1e39,0,0]}]}"#, "must be finite"),
            (r#"{"constraints": [{"direction": [1,0,0]}]}"#, "exactly one"),
            (r#"{"constraints": [{"vertex": 1, "point": [0,0,0], "direction": [1,0,0]}]}"#, "exactly one"),
            (r#"{"constraints": [{"vertex": -1, "direction": [1,0,0]}]}"#, "bad constraints JSON"),
            (r#"{"constraints": []}"#, "empty"),
        ];
        for (text, why) in cases {
            let (_dir, path) = write_temp(text);
            let e = Orientation::parse(&path).expect_err(text).to_string();
            assert!(e.contains(&path) && e.contains(why) && !e.contains('\n'), "{text}: {e}");
        }
    }

    #[test]
    fn rejects_out_of_range_vertices_and_zero_directions_at_frames() {
        let g = grid(2);
        let far =
            Orientation::Constraints(vec![Constraint { vertex: Some(9), point: None, direction: Vec3::X }]);
        let e = frames(&g, &far, 0).expect_err("vertex 9 of 9").to_string();
        assert!(e.contains("vertex 9 is out of range"), "{e}");
        let zero = Orientation::Constraints(vec![Constraint {
            vertex: Some(0),
            point: None,
            direction: Vec3::ZERO,
        }]);
        assert!(frames(&g, &zero, 0).is_err());
        assert!(frames(&g, &Orientation::Axis(Vec3::NAN), 0).is_err());
    }
}
