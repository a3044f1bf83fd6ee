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
const REMESH: Kind = Kind { magic: b"BTFREMSH", version: 2, name: "remesh" };
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

/// A remeshing made by `remesh`, whose key ([`remesh_key`], [`refine_key`]) is `key`,
/// through `cache` where one is given.
pub fn remeshed(
    cache: Option<&CacheDir>,
    key: u64,
    remesh: impl FnOnce() -> Result<Mesh>,
) -> Result<(Mesh, Source)> {
    let Some(cache) = cache else { return Ok((remesh()?, Source::Computed)) };
    cache.get_or_compute((REMESH, key), decode_mesh, remesh, encode_mesh)
}

/// A level's templates and links built by `build`, through `cache` where one is given.
pub fn templates(
    cache: Option<&CacheDir>,
    key: u64,
    build: impl FnOnce() -> Result<TargetLevel>,
) -> Result<(TargetLevel, Source)> {
    let Some(cache) = cache else { return Ok((build()?, Source::Computed)) };
    cache.get_or_compute((TEMPLATES, key), decode_level, build, encode_level)
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
    check_level(&level)?;
    Ok(level)
}

/// The sizes a level's parts must agree on, so that a file of other inputs that shares a
/// key by accident is refused rather than indexed past its end.
fn check_level(level: &TargetLevel) -> std::result::Result<(), String> {
    let Neighbourhoods::Mesh { template, slots, shift_start, .. } = &level.neighbourhoods else {
        return Err("a grid level is never cached".into());
    };
    let fits = *template == level.template
        && Some(slots.len()) == template.checked_mul(*template).and_then(|t| t.checked_mul(level.vertices))
        && shift_start.len() == level.vertices + 1
        && (level.parents.is_empty() || level.parents.len() == level.vertices);
    if !fits {
        return Err(format!("its parts do not fit {} vertices and {template}² templates", level.vertices));
    }
    Ok(())
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
        assert_eq!(decode_level(&bytes).unwrap(), level);
        let back = decode_mesh(&encode_mesh(&mesh)).unwrap();
        assert_eq!((back.positions(), back.triangles()), (mesh.positions(), mesh.triangles()));
        for cut in [1, 8, bytes.len() / 3, bytes.len() - 1] {
            assert!(decode_level(&bytes[..cut]).is_err(), "cut at {cut}");
        }
        let mut huge = bytes.clone();
        huge[16..24].copy_from_slice(&u64::MAX.to_le_bytes());
        assert!(decode_level(&huge).is_err());
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
