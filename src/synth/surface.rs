//! Targets on a triangle mesh (Tong et al. 2002 §5.1, Fig. 4; §5.2): per vertex, the
//! triangles around it are flattened into its (s, t) plane, the square neighbourhood
//! template is resampled from that patch (each pixel the texton of the nearest corner of
//! the face it falls in, where Tong et al. blend the three: see `nearest_corner`), and the
//! patch vertices inside the template become the forward shifts of the k-coherence
//! candidate set.
//!
//! Conventions are those of [`super::target`]: template pixel (i, j) sits at offset
//! (dx, dy) = (i − r, j − r) texels; x runs along s and y runs *down* t (image rows), so the
//! surface point of offset (dx, dy) is `v + texel·(dx·s − dy·t)`.

use super::flatten::{barycentric, bounds, flatten, Cover, Patch, Topology};
use super::slot::OUTSIDE;
use super::target::{Neighbourhoods, ParentLink, Shift, Slot, TargetLevel};
use crate::mesh::bvh::TriangleBvh;
use crate::mesh::frames::Frames;
use crate::mesh::Mesh;
use crate::{Error, Result};
use glam::{Vec2, Vec3};
use rayon::prelude::*;

/// Offsets within this many texels of the template's edge still count as inside it.
const SQUARE_TOLERANCE: f32 = 1e-3;

/// The level of a mesh whose template pixels are `texel` apart on the surface: per vertex
/// a `template × template` square of slots resampled from its flattened patch, and the
/// patch vertices inside that square with their offsets. Parents are left empty (see
/// [`link_levels`]).
pub fn surface_level(mesh: &Mesh, frames: &Frames, texel: f32, template: usize) -> Result<TargetLevel> {
    check_frames(mesh, frames, "mesh")?;
    if !(texel.is_finite() && texel > 0.0) {
        return Err(Error::invalid(format!("texel size must be positive and finite, got {texel}")));
    }
    if template % 2 == 0 {
        return Err(Error::invalid(format!("template side must be odd, got {template}")));
    }
    let topology = Topology::new(mesh);
    let r = template / 2;
    let cover = square_cover(r, texel);
    // Each vertex's slots go straight to their place in the level's array: a copy from
    // per-vertex vectors had doubled the memory of the finest level's templates.
    let mut slots = vec![Slot::DEFAULT; mesh.vertex_count() * template * template];
    let per_vertex: Vec<Vec<Shift>> = slots
        .par_chunks_mut(template * template)
        .enumerate()
        .map_init(
            || Patch::new(mesh),
            |patch, (v, vertex_slots)| {
                flatten(mesh, frames, &topology, v as u32, cover, patch);
                resample(mesh, patch, v as u32, texel, r, vertex_slots);
                patch_shifts(patch, texel, r)
            },
        )
        .collect();
    let (mut shift_start, mut shifts) = (vec![0u32], Vec::new());
    for vertex_shifts in per_vertex {
        shifts.extend(vertex_shifts);
        shift_start.push(shifts.len() as u32);
    }
    Ok(TargetLevel::new(mesh.vertex_count(), Neighbourhoods::Mesh { template, slots, shift_start, shifts }))
}

fn check_frames(mesh: &Mesh, frames: &Frames, name: &str) -> Result<()> {
    if frames.len() != mesh.vertex_count() {
        return Err(Error::invalid(format!(
            "{name}: {} frames for {} vertices",
            frames.len(),
            mesh.vertex_count()
        )));
    }
    Ok(())
}

/// The template of `v` resampled from its patch into `slots` (all [`Slot::DEFAULT`]): each
/// pixel takes the nearest corner of the first patch face (in breadth-first order, so the
/// least distorted) that contains it, or keeps the default texton.
fn resample(mesh: &Mesh, patch: &Patch, v: u32, texel: f32, r: usize, slots: &mut [Slot]) {
    let side = 2 * r + 1;
    let ri = r as i64;
    // A filled pixel names a vertex of its face; an empty one still names OUTSIDE.
    let empty = |slot: &Slot| slot.vertices[0] == OUTSIDE;
    let mut left = side * side;
    // Beyond this in s or t (a margin above r + 1 texels that covers the rounding of the
    // division below), a corner's offset is at least r + 1 texels: a face with every
    // corner beyond it on one side holds no pixel, and half the patch is such faces.
    let beyond = (r + 1) as f32 * texel * (1.0 + 1e-5);
    for &(f, corners) in &patch.faces {
        let (lo, hi) = bounds(&corners);
        if lo.x > beyond || hi.x < -beyond || lo.y > beyond || hi.y < -beyond {
            continue;
        }
        // Corners in texel offsets: x along s, y down t. Dividing by texel > 0 keeps the
        // order and negating is exact, so their bounds are the corners' bounds divided.
        let offsets = corners.map(|c| Vec2::new(c.x / texel, -c.y / texel));
        let (lo, hi) = (Vec2::new(lo.x / texel, -hi.y / texel), Vec2::new(hi.x / texel, -lo.y / texel));
        let [(x0, x1), (y0, y1)] = lattice_span(&offsets, lo, hi).map(|(a, b)| (a.max(-ri), b.min(ri)));
        for dy in y0..=y1 {
            for dx in x0..=x1 {
                let i = ((dy + ri) as usize) * side + (dx + ri) as usize;
                if !empty(&slots[i]) {
                    continue;
                }
                let q = Vec2::new(dx as f32, dy as f32);
                if let Some(weights) = barycentric(q, &offsets) {
                    slots[i] = nearest_corner(mesh.triangles()[f as usize], weights);
                    left -= 1;
                }
            }
        }
        // Later faces only fill pixels still empty.
        if left == 0 {
            break;
        }
    }
    // v sits at the centre even when no (non-degenerate) face around it does.
    if empty(&slots[r * side + r]) {
        slots[r * side + r] = Slot::at(v);
    }
}

/// The template pixel at barycentric `weights` in `face`: the texton of the corner nearest
/// to it, whole. Tong et al. blend the three corners' textons; on a mesh whose vertices are
/// about a texel apart that blend low-passes every target neighbourhood, so the search
/// prefers the sample's calm places and the result loses contrast and detail (marble on
/// `bunny-1k8`, 184k vertices: the exported texture's detail 0.62 → 0.80 of the sample's,
/// contrast 0.89 → 0.91, smeared windows 4.5% → 4.3%). The nearest corner is at most about
/// half a texel off, as a grid's pixel is on a plane.
fn nearest_corner(face: [u32; 3], weights: [f32; 3]) -> Slot {
    let k = (0..3).fold(0, |best, k| if weights[k] > weights[best] { k } else { best });
    Slot::at(face[k])
}

/// A flattened face at least this round (twice its area over the square of its bounds'
/// larger side) has barycentric weights that are accurate to well within [`LATTICE_MARGIN`].
const WELL_SHAPED: f32 = 1e-2;

/// How far beyond its bounds, in texels per texel of the face's size plus one, a lattice
/// point may lie and still pass the barycentric test of a well-shaped face (its tolerance
/// and the rounding of its weights are both some hundred times less).
const LATTICE_MARGIN: f32 = 1e-3;

/// The columns and rows of the pixels that may lie in the face with `corners` (in texel
/// offsets, bounded by `lo` and `hi`). A well-shaped face's span is the lattice points in
/// its bounds widened by [`LATTICE_MARGIN`]: a quarter of the points the bounds rounded
/// outward give, where each test is a division. A sliver's weights are only as accurate as
/// its area, so it keeps the rounded-out span.
fn lattice_span(corners: &[Vec2; 3], lo: Vec2, hi: Vec2) -> [(i64, i64); 2] {
    let extent = (hi - lo).max_element();
    let area = (corners[1] - corners[0]).perp_dot(corners[2] - corners[0]).abs();
    if area >= WELL_SHAPED * extent * extent {
        let margin = LATTICE_MARGIN * (1.0 + extent);
        let (lo, hi) = (lo - margin, hi + margin);
        [(ceil_to_i64(lo.x), floor_to_i64(hi.x)), (ceil_to_i64(lo.y), floor_to_i64(hi.y))]
    } else {
        [(floor_to_i64(lo.x), ceil_to_i64(hi.x)), (floor_to_i64(lo.y), ceil_to_i64(hi.y))]
    }
}

/// `x.floor() as i64` without a call into libm (the templates call it four times per
/// patch face): the truncation is exact for every f32 that fits, and one lower where it
/// rounded a negative fraction up. NaN gives 0 and the ends saturate, as `as` does.
#[inline]
fn floor_to_i64(x: f32) -> i64 {
    let whole = x as i64;
    whole.saturating_sub((whole as f32 > x) as i64)
}

/// `x.ceil() as i64` without a call into libm, as [`floor_to_i64`].
#[inline]
fn ceil_to_i64(x: f32) -> i64 {
    let whole = x as i64;
    whole.saturating_add(((whole as f32) < x) as i64)
}

/// What a patch must cover for a template of `r` texels each way: its pixels, with room
/// for a pixel that the barycentric test finds inside a face a rounding error beyond them.
fn square_cover(r: usize, texel: f32) -> Cover {
    Cover::Square((r as f32 + 0.05) * texel)
}

/// Whether a patch vertex at `offset` (in texels) lies in a template of `r` texels each way.
fn in_square(offset: [f32; 2], r: usize) -> bool {
    let limit = r as f32 + SQUARE_TOLERANCE;
    offset[0].abs() <= limit && offset[1].abs() <= limit
}

/// The patch vertices inside the template's square with their offsets in texels (the
/// centre first, at offset 0).
fn patch_shifts(patch: &Patch, texel: f32, r: usize) -> Vec<Shift> {
    patch
        .order
        .iter()
        .filter_map(|&u| {
            let c = patch.uv_of(u)?;
            let offset = [c.x / texel, -c.y / texel];
            in_square(offset, r).then_some((u, offset))
        })
        .collect()
}

/// `level`'s mesh templates narrowed to `template` (odd, at most theirs): the centre of
/// each square and the forward shifts inside it. They are what [`surface_level`] resamples
/// from the same patches, since a pixel takes the first patch face that holds it however
/// wide the square is: a finer level's parent templates come from its coarser level's own
/// patches, flattened once.
pub fn narrowed(level: &TargetLevel, template: usize) -> Result<TargetLevel> {
    let Neighbourhoods::Mesh { template: wide, slots, shift_start, shifts } = &level.neighbourhoods else {
        return Err(Error::invalid("only a mesh level's templates are narrowed"));
    };
    let wide = *wide;
    if template % 2 == 0 || template > wide {
        return Err(Error::invalid(format!("cannot narrow {wide}-wide templates to {template}")));
    }
    let margin = (wide - template) / 2;
    let narrow_slots = slots
        .chunks_exact(wide * wide)
        .flat_map(|square| square.chunks_exact(wide).skip(margin).take(template))
        .flat_map(|row| &row[margin..margin + template])
        .copied()
        .collect();
    let (mut narrow_start, mut narrow_shifts) = (vec![0u32], Vec::new());
    for range in shift_start.windows(2) {
        let inside = |s: &&Shift| in_square(s.1, template / 2);
        narrow_shifts.extend(shifts[range[0] as usize..range[1] as usize].iter().filter(inside));
        narrow_start.push(narrow_shifts.len() as u32);
    }
    let neighbourhoods = Neighbourhoods::Mesh {
        template,
        slots: narrow_slots,
        shift_start: narrow_start,
        shifts: narrow_shifts,
    };
    Ok(TargetLevel::new(level.vertices, neighbourhoods))
}

/// Links each vertex of `fine_level` to the coarser level (Tong §5.1, multi-resolution):
/// its parent is a corner of the coarse triangle nearest to it, with the offset from that
/// corner in fine texels, and its parent template is that corner's template in
/// `coarse_parent_templates` (templates of `coarse` at twice `fine_texel`, such as
/// [`narrowed`] from its own; the fine level keeps them).
///
/// Tong casts along the normal; the nearest point is used instead because it always
/// exists (a ray can miss a coarse mesh that lies just inside a convex fine surface, or
/// hit a far sheet first in a thin part), and the two agree where the meshes are close,
/// as successive remeshed levels are.
pub fn link_levels(
    fine: &Mesh,
    fine_frames: &Frames,
    fine_level: &mut TargetLevel,
    coarse: &Mesh,
    coarse_frames: &Frames,
    coarse_parent_templates: TargetLevel,
    fine_texel: f32,
) -> Result<()> {
    check_frames(fine, fine_frames, "fine mesh")?;
    check_frames(coarse, coarse_frames, "coarse mesh")?;
    if fine_level.vertices != fine.vertex_count() || coarse_parent_templates.vertices != coarse.vertex_count()
    {
        return Err(Error::invalid("link_levels: the levels do not belong to the given meshes"));
    }
    if !(fine_texel.is_finite() && fine_texel > 0.0) || coarse.face_count() == 0 {
        return Err(Error::invalid("link_levels: needs a positive texel size and a coarse mesh with faces"));
    }
    let bvh = TriangleBvh::new(coarse);
    let parents: Vec<ParentLink> =
        fine.positions().par_iter().map(|&p| parent_of(p, coarse, coarse_frames, &bvh, fine_texel)).collect();
    fine_level.parent_template = coarse_parent_templates.template;
    fine_level.parent_neighbourhoods = Some(coarse_parent_templates.neighbourhoods);
    fine_level.parents = parents;
    Ok(())
}

/// The parent link of the fine point `p`. A coarse vertex stands for fine texels
/// 2u and 2u + 1 (as on a grid), so corners are compared by the centre of that footprint,
/// half a fine texel along +x and +y; this also settles the exact ties of regular meshes the
/// way grids do.
fn parent_of(p: Vec3, coarse: &Mesh, frames: &Frames, bvh: &TriangleBvh, fine_texel: f32) -> ParentLink {
    let hit = bvh.closest_point(p);
    let corners = coarse.triangles()[hit.triangle as usize];
    let footprint = |c: u32| {
        let (s, t) = (frames.s[c as usize], frames.t[c as usize]);
        coarse.positions()[c as usize] + 0.5 * fine_texel * (s - t)
    };
    let vertex = corners
        .into_iter()
        .min_by(|&a, &b| {
            footprint(a).distance_squared(hit.point).total_cmp(&footprint(b).distance_squared(hit.point))
        })
        .unwrap_or(corners[0]);
    let d = p - coarse.positions()[vertex as usize];
    let (s, t) = (frames.s[vertex as usize], frames.t[vertex as usize]);
    ParentLink { vertex, offset: [d.dot(s) / fine_texel, -d.dot(t) / fine_texel] }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::synth::target::{grid_levels, OUTSIDE};

    /// A w × h grid in z = 0 with `spacing` between vertices; vertex (x, y) is index
    /// y·w + x at (x, −y)·spacing, so rows run down t = +y as image rows do, and its frames
    /// are s = +x, t = +y, n = +z.
    pub(crate) fn flat_grid(w: u32, h: u32, spacing: f32) -> (Mesh, Frames) {
        let at = |x: u32, y: u32| y * w + x;
        let positions = (0..h)
            .flat_map(|y| (0..w).map(move |x| Vec3::new(x as f32, -(y as f32), 0.0) * spacing))
            .collect();
        let mut triangles = Vec::new();
        for y in 0..h - 1 {
            for x in 0..w - 1 {
                // Counter-clockwise seen from +z.
                triangles.push([at(x, y), at(x, y + 1), at(x + 1, y + 1)]);
                triangles.push([at(x, y), at(x + 1, y + 1), at(x + 1, y)]);
            }
        }
        let mesh = Mesh::new(positions, triangles).expect("the grid is valid");
        let n = mesh.vertex_count();
        let frames = Frames::from_directions(&vec![Vec3::Z; n], &vec![Vec3::X; n]);
        (mesh, frames)
    }

    /// The vertex a slot falls on, if it carries (almost) all the weight.
    fn on_vertex(slot: &Slot) -> Option<u32> {
        (0..3).find(|&k| slot.weights[k] > 1.0 - 1e-4).map(|k| slot.vertices[k])
    }

    fn interior(w: u32, h: u32, margin: u32) -> impl Iterator<Item = usize> {
        (margin..h - margin).flat_map(move |y| (margin..w - margin).map(move |x| (y * w + x) as usize))
    }

    /// Where unfolding is exact (a plane with jittered vertices), a template flattened over
    /// its square resamples the same pixels and forward shifts as one flattened over the
    /// disc around the square, from fewer faces.
    #[test]
    fn a_square_cover_resamples_what_the_disc_around_it_does() {
        let (grid, frames) = flat_grid(20, 20, 1.0);
        let jitter =
            |i: usize, k: u32| ((i as u32).wrapping_mul(2_654_435_761).rotate_left(k) % 1000) as f32 / 1000.0;
        let positions = grid
            .positions()
            .iter()
            .enumerate()
            .map(|(i, p)| *p + Vec3::new(jitter(i, 0) - 0.5, jitter(i, 11) - 0.5, 0.0) * 0.4)
            .collect();
        let mesh = Mesh::new(positions, grid.triangles().to_vec()).expect("still valid");
        let (topology, r, texel) = (Topology::new(&mesh), 3, 0.9);
        let (mut square, mut disc) = (Patch::new(&mesh), Patch::new(&mesh));
        let (mut fewer, side) = (0, 2 * r + 1);
        for v in interior(20, 20, 7) {
            let v = v as u32;
            flatten(&mesh, &frames, &topology, v, square_cover(r, texel), &mut square);
            flatten(&mesh, &frames, &topology, v, Cover::Disc(r as f32 * texel * 1.5), &mut disc);
            let slots = |patch: &Patch| {
                let mut slots = vec![Slot::DEFAULT; side * side];
                resample(&mesh, patch, v, texel, r, &mut slots);
                slots
            };
            for (a, b) in slots(&square).iter().zip(&slots(&disc)) {
                assert_eq!(a.vertices, b.vertices, "vertex {v}");
                assert!(a.weights.iter().zip(&b.weights).all(|(x, y)| (x - y).abs() < 1e-5), "vertex {v}");
            }
            let shifts = |patch: &Patch| {
                let mut shifts = patch_shifts(patch, texel, r);
                shifts.sort_by_key(|s| s.0);
                shifts
            };
            assert_eq!(shifts(&square), shifts(&disc), "vertex {v}");
            fewer += usize::from(square.faces.len() < disc.faces.len());
        }
        assert_eq!(fewer, 36, "every vertex's square patch holds fewer faces");
    }

    #[test]
    fn floor_and_ceil_agree_with_libm_everywhere() {
        for x in crate::synth::candidates::tests::awkward_floats(5) {
            assert_eq!(floor_to_i64(x), x.floor() as i64, "floor {x}");
            assert_eq!(ceil_to_i64(x), x.ceil() as i64, "ceil {x}");
        }
    }

    /// The narrow lattice span drops only points that the barycentric test refuses, for
    /// faces of every size and shape: round, long, slivers, tiny and many texels wide, and
    /// with corners a hair from lattice points (where the test's tolerance decides).
    #[test]
    fn a_lattice_span_holds_every_point_a_face_accepts() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let (mut faces, mut narrower) = (0, 0);
        for trial in 0..20_000 {
            let size = [0.05f32, 0.7, 1.5, 6.0][trial % 4];
            let mut random = |a: f32| Vec2::new(rng.random_range(-a..a), rng.random_range(-a..a));
            let centre = random(3.0);
            let mut t = [(); 3].map(|_| centre + random(size));
            if trial % 3 == 0 {
                // Corners a hair from lattice points, on either side of them.
                t = t.map(|c| c.round() + random(3e-6));
            }
            if trial % 5 == 0 {
                // A sliver: the third corner almost on the line through the other two.
                let width = [1e-3, 1e-6][trial % 2];
                t[2] = t[0].lerp(t[1], rng.random_range(-0.5..1.5))
                    + Vec2::splat(rng.random_range(-width..width));
            }
            let (lo, hi) = bounds(&t);
            let wide = [(floor_to_i64(lo.x), ceil_to_i64(hi.x)), (floor_to_i64(lo.y), ceil_to_i64(hi.y))];
            let narrow = lattice_span(&t, lo, hi);
            let inside = |[(x0, x1), (y0, y1)]: [(i64, i64); 2]| {
                let points =
                    (y0..=y1).flat_map(move |y| (x0..=x1).map(move |x| Vec2::new(x as f32, y as f32)));
                points
                    .filter(|&q| barycentric(q, &t).is_some())
                    .map(|q| (q.x as i64, q.y as i64))
                    .collect::<Vec<_>>()
            };
            let all = inside(wide);
            assert_eq!(inside(narrow).len(), all.len(), "face {t:?}");
            faces += usize::from(!all.is_empty());
            narrower += usize::from((narrow[0].1 - narrow[0].0) < (wide[0].1 - wide[0].0));
        }
        assert!(
            faces > 5_000 && narrower > 10_000,
            "{faces} faces held points, {narrower} spans were narrower"
        );
    }

    #[test]
    fn flat_grid_matches_grid_levels() {
        let (w, h, template) = (9, 8, 5);
        let (mesh, frames) = flat_grid(w, h, 0.5);
        let level = surface_level(&mesh, &frames, 0.5, template).expect("valid");
        let grid = &grid_levels(w as usize, h as usize, 1, template, 3)[0];
        let (mut a, mut b, mut c, mut d) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        for v in interior(w, h, 2) {
            let got: Vec<Option<u32>> = level.slots_of(v, &mut a).iter().map(on_vertex).collect();
            let want: Vec<Option<u32>> = grid.slots_of(v, &mut b).iter().map(on_vertex).collect();
            assert_eq!(got, want, "slots of vertex {v}");
            let mut got = level.shifts_of(v, &mut c).to_vec();
            let mut want = grid.shifts_of(v, &mut d).to_vec();
            got.sort_by_key(|s| s.0);
            want.sort_by_key(|s| s.0);
            assert_eq!(got.len(), want.len(), "shifts of vertex {v}");
            for ((gv, go), (wv, wo)) in got.iter().zip(&want) {
                assert_eq!(gv, wv);
                assert!((go[0] - wo[0]).abs() < 1e-4 && (go[1] - wo[1]).abs() < 1e-4, "{go:?} vs {wo:?}");
            }
        }
        // Past the mesh's edge the surface has the default texton.
        assert_eq!(level.slots_of(0, &mut a)[0], Slot::DEFAULT);
    }

    #[test]
    fn off_vertex_pixels_take_the_nearest_corner() {
        // Texel 0.75 of a unit grid: pixel (1, 0) of vertex (2, 2) is at x = 2.75, y = 2,
        // nearer vertex (3, 2); pixel (−1, 0) at x = 1.25, nearer vertex (1, 2).
        let (mesh, frames) = flat_grid(6, 6, 1.0);
        let level = surface_level(&mesh, &frames, 0.75, 3).expect("valid");
        let slots = level.slots_of(14, &mut Vec::new()).to_vec();
        assert_eq!(slots[5], Slot::at(15));
        assert_eq!(slots[3], Slot::at(13));
        assert_eq!(slots[4], Slot::at(14));
    }

    pub(crate) fn bunny() -> (Mesh, Frames, f32) {
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/data/bunny-1k8.obj");
        let mesh = crate::mesh::load(std::path::Path::new(path)).expect("bundled mesh").with_normals();
        let normals = mesh.normals().expect("computed").to_vec();
        let frames = Frames::from_directions(&normals, &vec![Vec3::X; normals.len()]);
        let edges = crate::mesh::topology::edges(&mesh);
        let p = mesh.positions();
        let texel = edges.iter().map(|[a, b]| p[*a as usize].distance(p[*b as usize])).sum::<f32>()
            / edges.len() as f32;
        (mesh, frames, texel)
    }

    /// Narrowed templates are the narrow square resampled from the wide square's patches,
    /// to the bit, slots and shifts alike; and narrowing to the same width keeps a level.
    #[test]
    fn narrowed_templates_resample_the_wide_templates_patches() {
        let (mesh, frames, texel) = bunny();
        let wide = surface_level(&mesh, &frames, texel, 7).expect("valid");
        assert_eq!(narrowed(&wide, 7).expect("no narrower"), wide);
        let narrow = narrowed(&wide, 3).expect("narrower");
        let (topology, mut patch) = (Topology::new(&mesh), Patch::new(&mesh));
        let (mut slot_scratch, mut shift_scratch) = (Vec::new(), Vec::new());
        for v in 0..mesh.vertex_count() {
            flatten(&mesh, &frames, &topology, v as u32, square_cover(3, texel), &mut patch);
            let mut slots = vec![Slot::DEFAULT; 9];
            resample(&mesh, &patch, v as u32, texel, 1, &mut slots);
            assert_eq!(narrow.slots_of(v, &mut slot_scratch), &slots[..], "vertex {v}");
            assert_eq!(
                narrow.neighbourhoods.shifts(v, &mut shift_scratch),
                &patch_shifts(&patch, texel, 1)[..]
            );
        }
        assert!(narrowed(&wide, 9).is_err() && narrowed(&wide, 4).is_err());
    }

    #[test]
    fn same_level_whatever_the_thread_count() {
        let (mesh, frames, texel) = bunny();
        let many = surface_level(&mesh, &frames, texel, 5).expect("valid");
        let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().expect("a pool");
        let one = pool.install(|| surface_level(&mesh, &frames, texel, 5)).expect("valid");
        assert_eq!(many, one);
    }

    #[test]
    fn bunny_slots_are_convex_combinations() {
        let (mesh, frames, texel) = bunny();
        let p = mesh.positions();
        let template = 5;
        let level = surface_level(&mesh, &frames, texel, template).expect("valid");
        let Neighbourhoods::Mesh { slots: all_slots, .. } = &level.neighbourhoods else {
            panic!("a mesh level")
        };
        assert_eq!(all_slots.len(), mesh.vertex_count() * template * template);
        let (mut scratch, mut shift_scratch) = (Vec::new(), Vec::new());
        let limit = (template / 2) as f32 + SQUARE_TOLERANCE;
        let (mut default, mut folded, mut shifted) = (0, 0, 0);
        for v in 0..mesh.vertex_count() {
            for s in level.slots_of(v, &mut scratch) {
                if s.vertices[0] == OUTSIDE {
                    default += 1;
                    continue;
                }
                assert!(s.weights.iter().all(|&w| w >= -1e-4), "{s:?}");
                assert!((s.weights.iter().sum::<f32>() - 1.0).abs() < 1e-4, "{s:?}");
            }
            let centre = level.slots_of(v, &mut scratch)[template * template / 2];
            let on_v: f32 =
                (0..3).filter(|&k| centre.vertices[k] == v as u32).map(|k| centre.weights[k]).sum();
            assert!(on_v >= 0.99, "centre of {v}: {centre:?}");
            let shifts = level.shifts_of(v, &mut shift_scratch);
            assert_eq!(shifts[0], (v as u32, [0.0, 0.0]));
            assert!(shifts.iter().all(|(_, o)| o[0].abs() <= limit && o[1].abs() <= limit));
            // Unfolding lays paths on the surface flat, so nothing should land much nearer
            // than it is in space, as it would on a face folded back over its edge.
            for &(u, o) in &shifts[1..] {
                let chord = p[u as usize].distance(p[v]);
                folded += usize::from(Vec2::from(o).length() * texel < 0.8 * chord);
                shifted += 1;
            }
        }
        // About 1% (sharp cones, where the exponential map stretches angles); a face
        // flattened onto the wrong side of its edge folds nearly 90%.
        assert!(folded * 50 < shifted, "{folded} of {shifted} shifts folded back");
        // The patches cover the templates almost everywhere on a closed-ish mesh.
        assert!(default * 20 < all_slots.len(), "{default} default slots");
    }

    #[test]
    fn link_levels_matches_grid_parents() {
        let (w, h) = (9, 9);
        let (fine, fine_frames) = flat_grid(w, h, 1.0);
        let (coarse, coarse_frames) = flat_grid(w.div_ceil(2), h.div_ceil(2), 2.0);
        let mut level = surface_level(&fine, &fine_frames, 1.0, 5).expect("valid");
        let coarse_templates = surface_level(&coarse, &coarse_frames, 2.0, 3).expect("valid");
        link_levels(&fine, &fine_frames, &mut level, &coarse, &coarse_frames, coarse_templates, 1.0)
            .expect("valid");
        let grid = &grid_levels(w as usize, h as usize, 2, 5, 3)[0];
        assert_eq!(level.parent_template, 3);
        for v in interior(w, h, 1) {
            let (got, want) = (level.parents[v], grid.parents[v]);
            assert_eq!(got.vertex, want.vertex, "parent of {v}");
            assert!((got.offset[0] - want.offset[0]).abs() < 1e-5, "{got:?} vs {want:?}");
            assert!((got.offset[1] - want.offset[1]).abs() < 1e-5, "{got:?} vs {want:?}");
        }
        // Parent templates are the coarse vertices' own (interior ones match the grid's).
        let (mut a, mut b) = (Vec::new(), Vec::new());
        for v in interior(w, h, 3) {
            let got: Vec<Option<u32>> = level.parent_slots_of(v, &mut a).iter().map(on_vertex).collect();
            let want: Vec<Option<u32>> = grid.parent_slots_of(v, &mut b).iter().map(on_vertex).collect();
            assert_eq!(got, want, "parent slots of {v}");
        }
    }

    #[test]
    fn rejects_bad_arguments() {
        let (mesh, frames) = flat_grid(3, 3, 1.0);
        assert!(surface_level(&mesh, &frames, 0.0, 3).is_err());
        assert!(surface_level(&mesh, &frames, 1.0, 4).is_err());
        let (other, other_frames) = flat_grid(2, 2, 1.0);
        assert!(surface_level(&mesh, &other_frames, 1.0, 3).is_err());
        let mut level = surface_level(&mesh, &frames, 1.0, 3).expect("valid");
        let coarse = surface_level(&other, &other_frames, 2.0, 3).expect("valid");
        assert!(link_levels(&mesh, &frames, &mut level, &other, &frames, coarse, 1.0).is_err());
    }
}
