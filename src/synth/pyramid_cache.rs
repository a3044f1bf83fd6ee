//! A surface pyramid's costly parts kept between runs ([`crate::cache`]): each level's
//! remeshing and its templates with their links to the coarser level.
//!
//! A remeshing depends on the input mesh and the remeshing's target only (a refined level,
//! on the input, the coarser level it refines and its edge length); templates and
//! links on the level's and the coarser level's meshes, frames and texels and on the
//! template sizes. Their keys hash exactly those, so a run with another analysis of the same
//! size, another preset or another seed finds the remeshing, and one whose frames are the
//! same (the same seed, or an orientation axis or constraints, which no seed moves) finds the
//! templates too. A file's payload is the result's numbers, little-endian.

use super::target::{Neighbourhoods, ParentLink, Shift, Slot, TargetLevel};
use crate::cache::{CacheDir, Fnv1a, Kind, Source};
use crate::mesh::frames::Frames;
use crate::mesh::remesh::{RemeshParams, REFINE_ITERATIONS};
use crate::mesh::Mesh;
use crate::Result;

// Version 2: remeshed vertices come in spatial order (`mesh::layout`).
const REMESH: Kind = Kind { magic: b"BTFREMSH", version: 3, name: "remesh" };
// Version 2: parent templates are narrowed from the coarser level's own patches.
const TEMPLATES: Kind = Kind { magic: b"BTFTMPLT", version: 2, name: "templates" };

/// One level's mesh, frames and texel size: what its templates are flattened from.
#[derive(Clone, Copy)]
pub struct LevelShape<'a> {
    /// The level's remeshed surface.
    pub mesh: &'a Mesh,
    /// Its tangent frames.
    pub frames: &'a Frames,
    /// Its texel size, in model units.
    pub texel: f32,
}

/// The key of `mesh` remeshed to `target`.
pub fn remesh_key(mesh: &Mesh, target: &RemeshParams) -> u64 {
    let mut h = Fnv1a::of_kind(REMESH);
    hash_mesh(&mut h, mesh);
    h.write(&target.target_edge_length.to_le_bytes());
    h.write(&(target.iterations as u64).to_le_bytes());
    h.write(&target.vertex_count.map_or(u64::MAX, |n| n as u64).to_le_bytes());
    h.finish()
}

/// The key of `coarse`, a remeshing of `reference`, refined at edge length `length`
/// ([`crate::mesh::remesh::refine`]).
pub fn refine_key(reference: &Mesh, coarse: &Mesh, length: f32) -> u64 {
    let mut h = Fnv1a::of_kind(REMESH);
    h.write(b"refined");
    hash_mesh(&mut h, reference);
    hash_mesh(&mut h, coarse);
    h.write(&length.to_le_bytes());
    h.write(&(REFINE_ITERATIONS as u64).to_le_bytes());
    h.finish()
}

/// The key of a level's templates (side `template`) and, where it has a coarser level,
/// its links and parent templates (side `parent_template`).
pub fn templates_key(fine: LevelShape, template: usize, coarse: Option<(LevelShape, usize)>) -> u64 {
    let mut h = Fnv1a::of_kind(TEMPLATES);
    hash_shape(&mut h, fine);
    h.write(&(template as u64).to_le_bytes());
    if let Some((coarse, parent_template)) = coarse {
        hash_shape(&mut h, coarse);
        h.write(&(parent_template as u64).to_le_bytes());
    }
    h.finish()
}

fn hash_mesh(h: &mut Fnv1a, mesh: &Mesh) {
    h.write(&(mesh.vertex_count() as u64).to_le_bytes());
    h.write_f32s(mesh.positions().iter().flat_map(|p| p.to_array()));
    h.write(&(mesh.triangles().len() as u64).to_le_bytes());
    h.write_u32s(mesh.triangles().iter().flatten().copied());
}

fn hash_shape(h: &mut Fnv1a, shape: LevelShape) {
    hash_mesh(h, shape.mesh);
    let frames = shape.frames;
    h.write_f32s(frames.s.iter().chain(&frames.t).chain(&frames.n).flat_map(|v| v.to_array()));
    h.write(&shape.texel.to_le_bytes());
}

/// What a remeshing read from the cache must fit: the mesh it remeshes, the edge length it
/// aims for and the vertex count it comes to, where that is known. A file whose checksum and
/// key are right but whose payload is another run's (renamed, or a key shared by accident) is
/// refused unless it is a sound remeshing of this shape at this density: about the same
/// bounding box, no edge of zero length, and within 10% (and 64) of that vertex count, which
/// the remesher meets within 5% from 100 vertices on (a count asked of the cow, dragon,
/// teapot and bunny; a refinement, four times the level above's); without one, between half
/// and twice the count that equilateral triangles of the edge length give (met within 12%).
#[derive(Clone, Copy)]
pub struct MeshFit<'a> {
    /// The mesh remeshed (the input).
    pub reference: &'a Mesh,
    /// The edge length aimed for.
    pub edge: f32,
    /// The vertex count it comes to, where that is known (asked for, or implied).
    pub vertices: Option<usize>,
}

/// What a level's templates read from the cache must fit: its vertex count and template
/// side and, below the coarsest level, the coarser level's vertex count and the parent
/// template side. Every vertex a slot, a shift or a link names must be one of those.
#[derive(Clone, Copy, Debug)]
pub struct LevelFit {
    /// Vertices of the level.
    pub vertices: usize,
    /// Side of its templates.
    pub template: usize,
    /// Vertices of the coarser level and the side of the parent templates, if any.
    pub coarse: Option<(usize, usize)>,
}

/// A remeshing made by `remesh`, whose key ([`remesh_key`], [`refine_key`]) is `key`,
/// through `cache` where one is given; a cached one must `fit`.
pub fn remeshed(
    cache: Option<&CacheDir>,
    (key, fit): (u64, MeshFit),
    remesh: impl FnOnce() -> Result<Mesh>,
) -> Result<(Mesh, Source)> {
    let Some(cache) = cache else { return Ok((remesh()?, Source::Computed)) };
    let decode = |bytes: &[u8]| decode_mesh(bytes).and_then(|mesh| mesh_fits(mesh, fit));
    cache.get_or_compute((REMESH, key), decode, remesh, encode_mesh)
}

/// A level's templates and links built by `build`, through `cache` where one is given; cached
/// ones must `fit`.
pub fn templates(
    cache: Option<&CacheDir>,
    (key, fit): (u64, LevelFit),
    build: impl FnOnce() -> Result<TargetLevel>,
) -> Result<(TargetLevel, Source)> {
    let Some(cache) = cache else { return Ok((build()?, Source::Computed)) };
    let decode = |bytes: &[u8]| decode_level(bytes).and_then(|level| level_fits(level, fit));
    cache.get_or_compute((TEMPLATES, key), decode, build, encode_level)
}

/// `mesh` if it is a sound remeshing of `fit.reference` (see [`MeshFit`]).
fn mesh_fits(mesh: Mesh, fit: MeshFit) -> Res<Mesh> {
    if let Some(i) = mesh.positions().iter().position(|p| !p.is_finite()) {
        return Err(format!("vertex {i} is not finite"));
    }
    for (f, t) in mesh.triangles().iter().enumerate() {
        let [a, b, c] = t.map(|i| mesh.positions()[i as usize]);
        if a == b || b == c || c == a {
            return Err(format!("face {f} has an edge of zero length"));
        }
    }
    let n = mesh.vertex_count() as f64;
    let (low, high) = match fit.vertices {
        Some(asked) => (0.9 * asked as f64 - 64.0, 1.1 * asked as f64 + 64.0),
        None => {
            // Two equilateral triangles of side L per vertex.
            let equilateral =
                2.0 * fit.reference.surface_area() / (3f64.sqrt() * f64::from(fit.edge).powi(2));
            (equilateral / 2.0 - 64.0, 2.0 * equilateral + 64.0)
        }
    };
    if !(low..=high).contains(&n) {
        return Err(format!(
            "it has {n} vertices, where this remeshing has {:.0} to {high:.0}",
            low.max(0.0)
        ));
    }
    let ((lo, hi), (rlo, rhi)) =
        (crate::mesh::bounds_of(mesh.positions()), crate::mesh::bounds_of(fit.reference.positions()));
    // Coarse levels cut thin parts short by a few edges, and finer ones refine those.
    let slack = 2.0 * fit.edge + 0.1 * (rhi - rlo).length();
    if (lo - rlo).abs().max_element() > slack || (hi - rhi).abs().max_element() > slack {
        return Err("it does not cover the input mesh (another mesh's remeshing?)".into());
    }
    Ok(mesh)
}

/// `level` if every part fits `fit` (see [`LevelFit`]).
fn level_fits(level: TargetLevel, fit: LevelFit) -> Res<TargetLevel> {
    let wrong =
        |what: &str| format!("{what} do not fit {} vertices and {}² templates", fit.vertices, fit.template);
    if (level.vertices, level.template) != (fit.vertices, fit.template) {
        return Err(wrong(&format!("{} vertices and {}² templates", level.vertices, level.template)));
    }
    neighbourhoods_fit(&level.neighbourhoods, fit.vertices, fit.template).map_err(wrong)?;
    match (fit.coarse, &level.parent_neighbourhoods) {
        (None, None) if level.parents.is_empty() => {}
        (Some((coarse, side)), Some(parents)) => {
            let linked = level.parent_template == side
                && level.parents.len() == fit.vertices
                && level
                    .parents
                    .iter()
                    .all(|l| (l.vertex as usize) < coarse && l.offset.iter().all(|o| o.is_finite()));
            if !linked {
                return Err(wrong("its links to the coarser level"));
            }
            neighbourhoods_fit(parents, coarse, side).map_err(wrong)?;
        }
        _ => return Err(wrong("its links to a coarser level")),
    }
    Ok(level)
}

/// Whether `n` holds a `template`² square of slots for each of `vertices` vertices, naming
/// only those vertices, with finite weights and offsets; which part does not, if not.
fn neighbourhoods_fit(
    n: &Neighbourhoods,
    vertices: usize,
    template: usize,
) -> std::result::Result<(), &'static str> {
    let Neighbourhoods::Mesh { template: side, slots, shift_start, shifts } = n else {
        return Err("a grid's templates");
    };
    let vertex = |v: u32| (v as usize) < vertices;
    let slot_fits = |s: &Slot| {
        (s.vertices[0] == crate::sentinel::OUTSIDE || s.vertices.iter().all(|&v| vertex(v)))
            && s.weights.iter().all(|w| w.is_finite())
    };
    if *side != template
        || template.checked_mul(template).and_then(|t| t.checked_mul(vertices)) != Some(slots.len())
    {
        return Err("its template slots");
    }
    if !slots.iter().all(slot_fits) {
        return Err("its template slots' vertices");
    }
    if shift_start.len() != vertices + 1
        || !shifts.iter().all(|(v, o)| vertex(*v) && o.iter().all(|x| x.is_finite()))
    {
        return Err("its patches' vertices");
    }
    Ok(())
}

fn encode_mesh(mesh: &Mesh) -> Vec<u8> {
    let mut w = Writer::default();
    w.len(mesh.vertex_count());
    w.f32s(mesh.positions().iter().flat_map(|p| p.to_array()));
    w.len(mesh.triangles().len());
    w.u32s(mesh.triangles().iter().flatten().copied());
    w.0
}

fn decode_mesh(bytes: &[u8]) -> std::result::Result<Mesh, String> {
    let mut r = Reader::new(bytes);
    let n = r.len(12)?;
    let positions =
        (0..n).map(|_| Ok(glam::Vec3::new(r.f32()?, r.f32()?, r.f32()?))).collect::<Res<Vec<_>>>()?;
    let m = r.len(12)?;
    let triangles = (0..m).map(|_| Ok([r.u32()?, r.u32()?, r.u32()?])).collect::<Res<Vec<_>>>()?;
    r.end()?;
    if triangles.iter().flatten().any(|&i| i as usize >= n) {
        return Err("a triangle names a vertex past the mesh's".into());
    }
    Ok(Mesh::from_valid_parts(positions, triangles))
}

fn encode_level(level: &TargetLevel) -> Vec<u8> {
    let mut w = Writer::default();
    w.len(level.vertices);
    w.len(level.template);
    w.neighbourhoods(&level.neighbourhoods);
    w.len(level.parents.len());
    for link in &level.parents {
        w.u32s([link.vertex]);
        w.f32s(link.offset);
    }
    w.len(level.parent_template);
    match &level.parent_neighbourhoods {
        Some(n) => {
            w.len(1);
            w.neighbourhoods(n);
        }
        None => w.len(0),
    }
    w.0
}

fn decode_level(bytes: &[u8]) -> std::result::Result<TargetLevel, String> {
    let mut r = Reader::new(bytes);
    let (vertices, template) = (r.size()?, r.size()?);
    let neighbourhoods = r.neighbourhoods()?;
    let links = r.len(12)?;
    let parents = (0..links)
        .map(|_| Ok(ParentLink { vertex: r.u32()?, offset: [r.f32()?, r.f32()?] }))
        .collect::<Res<Vec<_>>>()?;
    let parent_template = r.size()?;
    let parent_neighbourhoods = if r.size()? == 1 { Some(r.neighbourhoods()?) } else { None };
    r.end()?;
    let level = TargetLevel {
        vertices,
        template,
        neighbourhoods,
        parents,
        parent_template,
        parent_neighbourhoods,
        round: None,
    };
    // Whether its parts fit the run, and so each other, is `level_fits`'s to say.
    Ok(level)
}

type Res<T> = std::result::Result<T, String>;

/// Little-endian numbers into a payload.
#[derive(Default)]
struct Writer(Vec<u8>);

impl Writer {
    fn len(&mut self, n: usize) {
        self.0.extend((n as u64).to_le_bytes());
    }

    fn u32s(&mut self, values: impl IntoIterator<Item = u32>) {
        values.into_iter().for_each(|x| self.0.extend(x.to_le_bytes()));
    }

    fn f32s(&mut self, values: impl IntoIterator<Item = f32>) {
        values.into_iter().for_each(|x| self.0.extend(x.to_le_bytes()));
    }

    fn neighbourhoods(&mut self, n: &Neighbourhoods) {
        let Neighbourhoods::Mesh { template, slots, shift_start, shifts } = n else {
            unreachable!("only mesh levels are cached, and a mesh level's templates are stored");
        };
        self.len(*template);
        self.len(slots.len());
        for slot in slots {
            self.u32s(slot.vertices);
            self.f32s(slot.weights);
        }
        self.len(shift_start.len());
        self.u32s(shift_start.iter().copied());
        self.len(shifts.len());
        for &(vertex, offset) in shifts {
            self.u32s([vertex]);
            self.f32s(offset);
        }
    }
}

/// Little-endian numbers out of a payload, every read checked against its end.
struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl<'a> Reader<'a> {
    fn new(bytes: &'a [u8]) -> Self {
        Reader { bytes, at: 0 }
    }

    fn take<const N: usize>(&mut self) -> Res<[u8; N]> {
        let end = self.at + N;
        let bytes = self.bytes.get(self.at..end).ok_or("the payload ends early")?;
        self.at = end;
        Ok(bytes.try_into().expect("N bytes"))
    }

    fn u32(&mut self) -> Res<u32> {
        self.take().map(u32::from_le_bytes)
    }

    fn f32(&mut self) -> Res<f32> {
        self.take().map(f32::from_le_bytes)
    }

    /// A count of items of `item` bytes each, refused if the rest cannot hold them.
    fn len(&mut self, item: usize) -> Res<usize> {
        let n = u64::from_le_bytes(self.take()?);
        if n.saturating_mul(item as u64) > (self.bytes.len() - self.at) as u64 {
            return Err(format!("a count of {n} that the payload cannot hold"));
        }
        Ok(n as usize)
    }

    /// A size (vertices, a template's side), refused beyond any mesh btfsynth makes.
    fn size(&mut self) -> Res<usize> {
        let n = u64::from_le_bytes(self.take()?);
        usize::try_from(n).ok().filter(|&n| n < 1 << 32).ok_or_else(|| format!("a size of {n}"))
    }

    fn neighbourhoods(&mut self) -> Res<Neighbourhoods> {
        let template = self.size()?;
        let slots = (0..self.len(24)?)
            .map(|_| {
                let vertices = [self.u32()?, self.u32()?, self.u32()?];
                Ok(Slot { vertices, weights: [self.f32()?, self.f32()?, self.f32()?] })
            })
            .collect::<Res<Vec<_>>>()?;
        let shift_start = (0..self.len(4)?).map(|_| self.u32()).collect::<Res<Vec<_>>>()?;
        let shifts = (0..self.len(12)?)
            .map(|_| -> Res<Shift> { Ok((self.u32()?, [self.f32()?, self.f32()?])) })
            .collect::<Res<Vec<_>>>()?;
        let ends_right = shift_start.last().is_none_or(|&e| e as usize == shifts.len())
            && shift_start.windows(2).all(|w| w[0] <= w[1]);
        if !ends_right {
            return Err("the patch lists' offsets do not run through the shifts".into());
        }
        Ok(Neighbourhoods::Mesh { template, slots, shift_start, shifts })
    }

    fn end(&self) -> Res<()> {
        match self.bytes.len() - self.at {
            0 => Ok(()),
            n => Err(format!("{n} bytes past the payload's end")),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::surface::surface_level;
    use crate::synth::surface::tests::bunny;

    /// A level and a remeshing read back equal what was stored, and a damaged payload
    /// is refused, never indexed past its end.
    #[test]
    fn levels_and_meshes_come_back_as_they_were_stored() {
        let (mesh, frames, texel) = bunny();
        let level = surface_level(&mesh, &frames, texel, 5).unwrap();
        let bytes = encode_level(&level);
        let fit = LevelFit { vertices: mesh.vertex_count(), template: 5, coarse: None };
        let decode = |bytes: &[u8]| decode_level(bytes).and_then(|l| level_fits(l, fit));
        assert_eq!(decode(&bytes).unwrap(), level);
        let back = decode_mesh(&encode_mesh(&mesh)).unwrap();
        assert_eq!((back.positions(), back.triangles()), (mesh.positions(), mesh.triangles()));
        for cut in [1, 8, bytes.len() / 3, bytes.len() - 1] {
            assert!(decode(&bytes[..cut]).is_err(), "cut at {cut}");
        }
        let mut huge = bytes.clone();
        huge[16..24].copy_from_slice(&u64::MAX.to_le_bytes());
        assert!(decode(&huge).is_err());
    }

    /// A whole, self-consistent payload of another run (another level, another mesh) is
    /// refused where it does not fit this one, never indexed past the mesh's end.
    #[test]
    fn a_payload_of_other_inputs_is_refused_by_what_the_run_needs() {
        let (mesh, frames, texel) = bunny();
        let level = surface_level(&mesh, &frames, texel, 5).unwrap();
        let bytes = encode_level(&level);
        let n = mesh.vertex_count();
        let fit = LevelFit { vertices: n, template: 5, coarse: None };
        let decode = |fit: LevelFit| decode_level(&bytes).and_then(|l| level_fits(l, fit));
        assert!(decode(fit).is_ok());
        for other in [
            LevelFit { vertices: n - 1, ..fit },
            LevelFit { template: 7, ..fit },
            LevelFit { coarse: Some((n / 4, 3)), ..fit },
        ] {
            assert!(decode(other).is_err(), "{other:?}");
        }
        // The right sizes, but a slot naming a vertex past the mesh's.
        let mut wrong = level.clone();
        if let Neighbourhoods::Mesh { slots, .. } = &mut wrong.neighbourhoods {
            let inside = slots.iter_mut().find(|s| s.vertices[0] != crate::sentinel::OUTSIDE).unwrap();
            inside.vertices[1] = n as u32;
        }
        let e = decode_level(&encode_level(&wrong)).and_then(|l| level_fits(l, fit)).unwrap_err();
        assert!(e.contains("slots' vertices"), "{e}");

        let mesh_fit = MeshFit { reference: &mesh, edge: texel, vertices: None };
        assert!(mesh_fits(mesh.clone(), mesh_fit).is_ok());
        assert!(
            mesh_fits(mesh.clone(), MeshFit { edge: texel * 4.0, ..mesh_fit }).is_err(),
            "another density"
        );
        let asked = |n: usize| MeshFit { vertices: Some(n), ..mesh_fit };
        assert!(mesh_fits(mesh.clone(), asked(n)).is_ok());
        assert!(mesh_fits(mesh.clone(), asked(n * 6 / 5 + 64)).is_err(), "another vertex count");
        let diagonal = {
            let (lo, hi) = crate::mesh::bounds_of(mesh.positions());
            (hi - lo).length()
        };
        let moved = Mesh::from_valid_parts(
            mesh.positions().iter().map(|&p| p + glam::Vec3::X * diagonal).collect(),
            mesh.triangles().to_vec(),
        );
        assert!(mesh_fits(moved, mesh_fit).is_err(), "another mesh");
        let mut pinched = mesh.positions().to_vec();
        let t = mesh.triangles()[0];
        pinched[t[1] as usize] = pinched[t[0] as usize];
        let pinched = Mesh::from_valid_parts(pinched, mesh.triangles().to_vec());
        assert!(mesh_fits(pinched, mesh_fit).unwrap_err().contains("zero length"));
    }

    /// Every input of a level's templates moves its key.
    #[test]
    fn the_templates_key_covers_mesh_frames_texel_and_sizes() {
        let (mesh, frames, texel) = bunny();
        let shape = LevelShape { mesh: &mesh, frames: &frames, texel };
        let key = templates_key(shape, 7, None);
        assert_eq!(templates_key(shape, 7, None), key);
        assert_ne!(templates_key(shape, 5, None), key);
        assert_ne!(templates_key(LevelShape { texel: texel * 1.001, ..shape }, 7, None), key);
        let mut turned = frames.clone();
        turned.s[3] = -turned.s[3];
        assert_ne!(templates_key(LevelShape { frames: &turned, ..shape }, 7, None), key);
        assert_ne!(templates_key(shape, 7, Some((shape, 3))), key);
        let target = RemeshParams::edge_length(0.01);
        assert_ne!(remesh_key(&mesh, &target), remesh_key(&mesh, &RemeshParams::edge_length(0.02)));
        let refined = refine_key(&mesh, &mesh, 0.01);
        assert_ne!(refined, remesh_key(&mesh, &target));
        assert_ne!(refined, refine_key(&mesh, &mesh, 0.02));
        let moved = Mesh::from_valid_parts(
            mesh.positions().iter().map(|&p| p * 1.001).collect(),
            mesh.triangles().to_vec(),
        );
        assert_ne!(refined, refine_key(&mesh, &moved, 0.01));
        assert_ne!(refined, refine_key(&moved, &mesh, 0.01));
    }
}
