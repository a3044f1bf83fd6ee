//! Isotropic remeshing: a new triangulation of the same surface whose edges all have
//! about one length, so that synthesis gets evenly spaced samples.
//!
//! Botsch and Kobbelt, *A Remeshing Approach to Multiresolution Modeling*, SGP 2004, §3:
//! each iteration splits edges longer than 4/3 L, collapses edges shorter than 4/5 L,
//! flips edges towards valence 6 (4 on a boundary), relaxes vertices tangentially and
//! projects them onto the nearest point of the input surface.
//!
//! Boundaries are preserved: boundary vertices never move, boundary edges are split at
//! their midpoints, and a boundary vertex is collapsed away only along a straight stretch
//! of boundary. Collapses keep the link condition, so the result has the input's
//! connected components, boundary loops and genus. Everything is deterministic.

mod halfedge;
mod passes;
mod stats;
mod subdivide;

pub use stats::{edge_length_stats, EdgeLengthStats};

use crate::mesh::bvh::TriangleBvh;
use crate::mesh::layout;
use crate::mesh::Mesh;
use crate::progress::{Progress, Silent};
use crate::{Error, Param, Result};
use halfedge::Halfedges;
use rayon::prelude::*;

/// How to remesh.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RemeshParams {
    /// The edge length L to aim for (no default: see [`RemeshParams::edge_length`] and
    /// [`RemeshParams::vertex_count`]).
    pub target_edge_length: f32,
    /// Split–collapse–flip–relax iterations (default 10; Botsch and Kobbelt find 5–10
    /// enough; more cost time and change little). A target reached through a coarser
    /// remeshing ([`remesh`]) runs them at the coarser length, then the refinement's
    /// [`REFINE_ITERATIONS`].
    pub iterations: usize,
    /// If set, L is rescaled midway so that the result has about this many vertices
    /// (default: unset; [`RemeshParams::vertex_count`] sets it).
    pub vertex_count: Option<usize>,
}

impl RemeshParams {
    /// Aim for edges of length `length`.
    pub fn edge_length(length: f32) -> RemeshParams {
        RemeshParams { target_edge_length: length, iterations: 10, vertex_count: None }
    }

    /// Aim for about `n` vertices on `mesh`. Equilateral triangles of side L have area
    /// (√3/4)L² and there are about two per vertex, so L = √(2A / (√3 n)) for area A.
    pub fn vertex_count(mesh: &Mesh, n: usize) -> RemeshParams {
        let l = (2.0 * mesh.surface_area() / (3f64.sqrt() * n.max(1) as f64)).sqrt();
        RemeshParams { vertex_count: Some(n), ..RemeshParams::edge_length(l as f32) }
    }
}

/// Remeshes `mesh` towards edges of length `length` (10 iterations).
pub fn remesh_to_edge_length(mesh: &Mesh, length: f32) -> Result<Mesh> {
    remesh(mesh, &RemeshParams::edge_length(length), &Silent)
}

/// Remeshes `mesh` to about `n` vertices (10 iterations).
pub fn remesh_to_vertex_count(mesh: &Mesh, n: usize) -> Result<Mesh> {
    if n < 4 {
        return Err(Error::out_of_range(Param::Vertices, n, "at least 4 are needed to remesh"));
    }
    remesh(mesh, &RemeshParams::vertex_count(mesh, n), &Silent)
}

/// The largest output the remesher agrees to make, so a typo in L fails at once instead
/// of exhausting memory.
const MAX_VERTICES: f64 = 50e6;

/// Remeshes `mesh` as `params` say, reporting one unit of progress per iteration.
///
/// A target of at least four times the input's vertices is reached through a remeshing at
/// twice the edge, refined once ([`refine`]): the iterations from the input split nearly
/// every edge one at a time and then settle several times the input's vertices, most of a
/// surface synthesis' serial time, while a refinement's start is already even. On
/// `bunny-37k` to 250k vertices: 4.1 s → 2.1 s, the edges' spread 0.104 → 0.093 of their
/// mean.
pub fn remesh(mesh: &Mesh, params: &RemeshParams, progress: &dyn Progress) -> Result<Mesh> {
    check_length(mesh, params.target_edge_length)?;
    let steps = coarser_steps(mesh, params.target_edge_length);
    let scale = (1u32 << steps) as f32;
    let coarse = RemeshParams {
        target_edge_length: params.target_edge_length * scale,
        vertex_count: params.vertex_count.map(|n| (n >> (2 * steps)).max(4)),
        ..*params
    };
    let reference = TriangleBvh::new(mesh);
    let he = Halfedges::from_mesh(mesh)
        .ok_or_else(|| Error::invalid("cannot remesh: the mesh is not manifold"))?;
    progress.start("remeshing", (params.iterations + steps * REFINE_ITERATIONS) as u64);
    let (mut result, mut length) = iterate(he, &reference, &coarse, progress);
    for _ in 0..steps {
        length /= 2.0;
        result = refined(&result, &reference, length, progress)?;
    }
    progress.finish();
    Ok(result)
}

/// How many times a remeshing at edge `length` is better reached by refining a remeshing
/// at twice the length: as long as that coarser remeshing still has at least the input's
/// vertex count, so it follows the input's shape as closely as the input can be followed.
/// At most [`MOST_COARSER_STEPS`].
fn coarser_steps(mesh: &Mesh, length: f32) -> usize {
    let vertices_at = |l: f64| 2.0 * mesh.surface_area() / (3f64.sqrt() * l * l);
    let mut steps = 0;
    while steps < MOST_COARSER_STEPS
        && vertices_at(f64::from(length) * f64::from(2u32 << steps)) >= mesh.vertex_count() as f64
    {
        steps += 1;
    }
    steps
}

/// Each refinement's coarser start rounds the input's sharp features at twice the edge
/// length, so a remeshing goes through at most one: it takes most of the time there is to
/// gain (a second saves the first's ten iterations at a quarter of the vertices).
const MOST_COARSER_STEPS: usize = 1;

/// Iterations [`refine`] runs (`RemeshParams::iterations` is ten from the input): its start
/// is already even, so they only settle the new vertices on the surface and the valences.
pub const REFINE_ITERATIONS: usize = 3;

/// `coarse`, a remeshing of `reference` at about twice `length`, remeshed at `length`:
/// every triangle split into four at its edges' midpoints, the midpoints projected onto
/// `reference`, then [`REFINE_ITERATIONS`] of the remeshing's iterations. Nested levels of a
/// synthesis pyramid come out so at a fraction of a remeshing from the input, whose first
/// iteration splits nearly every edge of the finest level one at a time.
pub fn refine(coarse: &Mesh, reference: &Mesh, length: f32, progress: &dyn Progress) -> Result<Mesh> {
    check_length(reference, length)?;
    progress.start("remeshing", REFINE_ITERATIONS as u64);
    let result = refined(coarse, &TriangleBvh::new(reference), length, progress);
    progress.finish();
    result
}

fn refined(coarse: &Mesh, reference: &TriangleBvh, length: f32, progress: &dyn Progress) -> Result<Mesh> {
    let (positions, triangles) = subdivide::midpoints(coarse);
    let nearest: Vec<_> = positions.par_iter().map(|&p| reference.closest_point(p)).collect();
    let (positions, hints) = nearest.iter().map(|c| (c.point, c.triangle)).unzip();
    let he = Halfedges::new(positions, &triangles, hints)
        .ok_or_else(|| Error::invalid("cannot refine: the coarse mesh is not manifold"))?;
    let params = RemeshParams { iterations: REFINE_ITERATIONS, ..RemeshParams::edge_length(length) };
    Ok(iterate(he, reference, &params, progress).0)
}

/// The remeshing's iterations on `he` (the surface `reference` holds), then its vertices
/// and faces in spatial order, and the edge length the last iteration aimed for (the
/// target's, or as corrected towards a vertex count).
fn iterate(
    mut he: Halfedges,
    reference: &TriangleBvh,
    params: &RemeshParams,
    progress: &dyn Progress,
) -> (Mesh, f32) {
    let mut length = params.target_edge_length;
    let mut scratch = passes::Scratch::default();
    for i in 0..params.iterations {
        if let (Some(n), true) = (params.vertex_count, is_calibration(i, params.iterations)) {
            length = rescale_for_count(&he, length, n);
        }
        let (low, high) = (0.8 * length, 4.0 / 3.0 * length);
        let clock = std::time::Instant::now();
        let splits = passes::split_long_edges(&mut he, high);
        if splits > he.pos.len() / 2 {
            // Most vertices are new and scattered (see `mesh::layout`); the later passes
            // walk rings, so they run much faster on a spatially ordered structure.
            he = he.in_spatial_order();
        }
        let t_split = clock.elapsed();
        let collapses = passes::collapse_short_edges(&mut he, low, high, &mut scratch);
        let t_collapse = clock.elapsed();
        let flips = passes::equalize_valences(&mut he, &mut scratch);
        let t_flip = clock.elapsed();
        passes::relax_and_project(&mut he, reference);
        tracing::debug!(
            "remesh iteration {i}: {splits} splits, {collapses} collapses, {flips} flips; \
             cumulative times {t_split:.2?} {t_collapse:.2?} {t_flip:.2?} {:.2?}",
            clock.elapsed()
        );
        progress.advance(1);
    }
    let (positions, triangles, _) = he.extract();
    let (order, triangles) = layout::spatial_order(&positions, &triangles);
    let positions = layout::permuted(&positions, &order);
    let result = Mesh::from_valid_parts(positions, triangles).with_normals();
    tracing::info!("remeshed to {}", edge_length_stats(&result));
    (result, length)
}

fn check_length(mesh: &Mesh, length: f32) -> Result<()> {
    if !(length.is_finite() && length > 0.0) {
        return Err(Error::out_of_range(Param::EdgeLength, length, "must be positive"));
    }
    let estimate = 2.0 * mesh.surface_area() / (3f64.sqrt() * f64::from(length).powi(2));
    if estimate > MAX_VERTICES {
        return Err(Error::out_of_range(
            Param::EdgeLength,
            length,
            format!("would make about {estimate:.3e} vertices (more than {MAX_VERTICES:.0e}); choose a longer one"),
        ));
    }
    Ok(())
}

/// Whether iteration `i` of `iterations` starts by correcting L towards the vertex count:
/// half-way and three quarters through, once the mesh has settled near L and before the
/// last iterations, which then settle near the corrected L.
fn is_calibration(i: usize, iterations: usize) -> bool {
    i > 0 && (i == iterations / 2 || i == 3 * iterations / 4)
}

/// The vertex count scales as 1/L², so L·√(V/n) corrects it for the next iterations.
fn rescale_for_count(he: &Halfedges, length: f32, n: usize) -> f32 {
    let alive = he.vertex_alive.iter().filter(|&&a| a).count();
    length * (alive as f32 / n as f32).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::test_meshes::{bundled, cube, grid};
    use crate::mesh::{load, topology};

    fn assert_same_topology(a: &Mesh, b: &Mesh) {
        let (sa, sb) = (topology::summary(a), topology::summary(b));
        assert_eq!(sa.components, sb.components, "{sa} vs {sb}");
        assert_eq!(sa.euler_characteristic, sb.euler_characteristic, "{sa} vs {sb}");
        assert!(crate::mesh::manifold::is_manifold(b.triangles()));
    }

    #[test]
    fn cube_refines_evenly_and_stays_a_sphere() {
        let c = cube();
        let fine = remesh_to_edge_length(&c, 0.1).expect("remeshes");
        assert_same_topology(&c, &fine);
        let s = edge_length_stats(&fine);
        assert!((s.mean - 0.1).abs() < 0.02 && s.coefficient_of_variation < 0.35, "{s}");
        // Every vertex stays on the cube's surface.
        for p in fine.positions() {
            let d = (*p - glam::Vec3::splat(0.5)).abs().max_element();
            assert!((d - 0.5).abs() < 1e-4, "{p}");
        }
    }

    #[test]
    fn boundary_of_an_open_grid_stays_in_place() {
        let g = grid(4);
        let fine = remesh_to_edge_length(&g, 0.05).expect("remeshes");
        assert_same_topology(&g, &fine);
        let boundary = topology::boundary_vertices(&fine);
        for (p, on) in fine.positions().iter().zip(boundary) {
            let on_square =
                p.x.abs() < 1e-6 || p.y.abs() < 1e-6 || (p.x - 1.0).abs() < 1e-6 || (p.y - 1.0).abs() < 1e-6;
            assert_eq!(on, on_square, "{p}");
            assert!(p.z.abs() < 1e-6);
        }
        let coarse = remesh_to_edge_length(&fine, 0.2).expect("coarsens");
        assert_same_topology(&g, &coarse);
        assert!(coarse.vertex_count() < fine.vertex_count() / 4);
    }

    #[test]
    fn same_input_gives_the_same_output() {
        let a = remesh_to_edge_length(&cube(), 0.15).expect("remeshes");
        let b = remesh_to_edge_length(&cube(), 0.15).expect("remeshes");
        assert_eq!(a.positions(), b.positions());
        assert_eq!(a.triangles(), b.triangles());
    }

    #[test]
    fn tiny_meshes_survive_coarse_and_fine_targets() {
        let triangle =
            Mesh::new(vec![glam::Vec3::ZERO, glam::Vec3::X, glam::Vec3::Y], vec![[0, 1, 2]]).expect("valid");
        let tetrahedron = Mesh::new(
            vec![glam::Vec3::ZERO, glam::Vec3::X, glam::Vec3::Y, glam::Vec3::Z],
            vec![[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]],
        )
        .expect("valid");
        for mesh in [triangle, tetrahedron, cube()] {
            for length in [0.07, 0.5, 3.0] {
                let out = remesh_to_edge_length(&mesh, length).expect("remeshes");
                assert_same_topology(&mesh, &out);
            }
        }
    }

    #[test]
    fn absurd_targets_are_refused() {
        assert!(remesh_to_edge_length(&cube(), 0.0).is_err());
        assert!(remesh_to_edge_length(&cube(), f32::NAN).is_err());
        assert!(remesh_to_edge_length(&cube(), 1e-6).is_err());
        assert!(remesh_to_vertex_count(&cube(), 2).is_err());
    }

    #[test]
    fn bunny_to_50k_vertices_is_uniform_and_keeps_its_genus() {
        let bunny = load(&bundled("bunny-1k8.obj")).expect("loads");
        let start = std::time::Instant::now();
        let fine = remesh_to_vertex_count(&bunny, 50_000).expect("remeshes");
        let elapsed = start.elapsed();
        let s = edge_length_stats(&fine);
        eprintln!("bunny-1k8 → {} vertices in {elapsed:?}: {s}", fine.vertex_count());
        let n = fine.vertex_count() as f64;
        assert!((n - 50_000.0).abs() < 0.15 * 50_000.0, "{n} vertices");
        assert!(s.coefficient_of_variation < 0.35, "{s}");
        assert_same_topology(&bunny, &fine);
    }

    /// A target of four times the input's vertices or more goes through one coarser
    /// remeshing, a smaller one does not, and the vertex count is met either way.
    #[test]
    fn a_dense_target_is_reached_through_a_coarser_remeshing() {
        let bunny = load(&bundled("bunny-1k8.obj")).expect("loads");
        let inputs = bunny.vertex_count();
        for (n, steps) in [(2 * inputs, 0), (5 * inputs, 1), (30_000, 1)] {
            let params = RemeshParams::vertex_count(&bunny, n);
            assert_eq!(coarser_steps(&bunny, params.target_edge_length), steps, "{n} vertices");
            let fine = remesh(&bunny, &params, &Silent).expect("remeshes");
            let (got, s) = (fine.vertex_count() as f64, edge_length_stats(&fine));
            assert!((got / n as f64 - 1.0).abs() < 0.05, "{got} vertices for {n}");
            assert!(s.coefficient_of_variation < 0.15, "{n}: {s}");
            assert_same_topology(&bunny, &fine);
        }
    }

    /// A refined level has four times the coarse one's vertices, even edges at the length
    /// asked for, the input's topology and boundaries, and every vertex on the input.
    #[test]
    fn refining_a_remeshing_quadruples_it_evenly_on_the_input() {
        for (name, vertices) in [("bunny-1k8.obj", 4_000), ("teapot.obj", 3_000)] {
            let input = load(&bundled(name)).expect("loads");
            let coarse = remesh_to_vertex_count(&input, vertices).expect("remeshes");
            let length = (edge_length_stats(&coarse).mean / 2.0) as f32;
            let fine = refine(&coarse, &input, length, &Silent).expect("refines");
            assert_same_topology(&input, &fine);
            let ratio = fine.vertex_count() as f64 / coarse.vertex_count() as f64;
            assert!((3.6..4.4).contains(&ratio), "{name}: {ratio}× the vertices");
            let s = edge_length_stats(&fine);
            let relative = (s.mean / f64::from(length) - 1.0).abs();
            assert!(relative < 0.1 && s.coefficient_of_variation < 0.2, "{name}: {s}");
            let (before, after) = (topology::summary(&coarse), topology::summary(&fine));
            assert!(after.boundary_edges >= 2 * before.boundary_edges, "{name}: {before} → {after}");
            let surface = TriangleBvh::new(&input);
            for p in fine.positions() {
                let off = surface.closest_point(*p).distance_squared.sqrt();
                assert!(off < 1e-3 * length, "{name}: {p} lies {off} off the input");
            }
        }
    }

    #[test]
    fn teapot_remeshes_with_its_boundaries() {
        let teapot = load(&bundled("teapot.obj")).expect("loads");
        let fine = remesh_to_vertex_count(&teapot, 5_000).expect("remeshes");
        assert_same_topology(&teapot, &fine);
        let (before, after) = (topology::summary(&teapot), topology::summary(&fine));
        assert!(after.boundary_edges >= before.boundary_edges, "{before} → {after}");
    }
}
