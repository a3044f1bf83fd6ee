//! Round neighbourhoods (Chen and Dong 2008 §4, §5.3): sample points on concentric circles
//! of radius r, 2r, 3r … around a vertex (r one texel of the level), each circle sampled at
//! equal arc-length steps and every point recorded as (circle, arc fraction).
//!
//! On a surface the paper marches along the intersection of the surface with co-axial
//! cylinders around the normal. Here the vertex's flattened patch (the one its square
//! templates come from, [`super::surface`]) stands in for that marching: each circle is cut
//! into arcs where it crosses the patch's edges, and each arc remembers the face it runs
//! through. That is done once per vertex in a reference frame that ignores the texture
//! direction ([`SurfaceMarching::new`]); a direction only rotates the start point, so a new
//! direction costs one angle per vertex and one barycentric evaluation per point
//! ([`SurfaceMarching::slots`]), never a new marching.
//!
//! Circle c holds `8c` points, so every circle's arc-length step is the same (π r / 4) and a
//! rotation by the angular step of the first circle (45°) moves circle c's points by c
//! places: rotating the start point by a multiple of that step permutes the samples exactly.
//!
//! The same round resampling of the sample, per texel of a level, is [`RoundSample`].

pub mod cache;

pub use cache::{MarchingCache, MarchingOrigin, MarchingSource};

use super::flatten::{barycentric, flatten, slot, Cover, Patch, Topology};
use super::sample::AppearanceMap;
use super::slot::{Slot, OUTSIDE};
use crate::mesh::frames::Frames;
use crate::mesh::Mesh;
use crate::{Error, Result};
use glam::{Vec2, Vec3};
use rayon::prelude::*;
use std::f32::consts::TAU;

/// The most circles a round neighbourhood may have: Chen and Dong use 3; 7 was the most
/// the appearance maps' first border of 8 texels held, and wider round neighbourhoods have
/// not been measured since. The round resampling reads one texel beyond the outer circle
/// (bilinear), so `circles + 1` must fit in the maps' border of [`AppearanceMap::PAD`].
pub const MAX_CIRCLES: usize = 7;
const _: () = assert!(MAX_CIRCLES < AppearanceMap::PAD);

/// Points on the first circle; circle c holds `c` times as many.
pub const POINTS_PER_CIRCLE: usize = 8;

/// The shape of a round neighbourhood: the centre and `circles` concentric circles.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub struct RoundStencil {
    /// Number of circles (radius 1, 2, … `circles` texels).
    pub circles: usize,
}

impl RoundStencil {
    /// Number of sample points: the centre, then circle 1's, circle 2's …
    pub fn points(&self) -> usize {
        Self::circle_start(self.circles + 1)
    }

    /// Points on circle `c` (c ≥ 1).
    pub fn circle_len(c: usize) -> usize {
        POINTS_PER_CIRCLE * c
    }

    /// Index of circle `c`'s first point (the centre is point 0).
    pub fn circle_start(c: usize) -> usize {
        1 + POINTS_PER_CIRCLE * c * (c.saturating_sub(1)) / 2
    }

    /// The points within circle `c` (the centre and circles 1 ..= c): the neighbourhood of
    /// size c, as the adaptive metric grows it.
    pub fn points_within(c: usize) -> usize {
        Self::circle_start(c + 1)
    }

    /// Every point as (circle, arc fraction from the start point), the centre as (0, 0).
    pub fn layout(&self) -> Vec<(usize, f32)> {
        std::iter::once((0, 0.0))
            .chain((1..=self.circles).flat_map(|c| {
                let n = Self::circle_len(c);
                (0..n).map(move |k| (c, k as f32 / n as f32))
            }))
            .collect()
    }
}

/// Where a round neighbourhood starts on its circles: `step` whole angular steps (45°,
/// [`POINTS_PER_CIRCLE`] to a turn) plus `fraction` ∈ [0, 1) of one step, counter-clockwise
/// from the reference direction. Whole steps only permute the points (exactly).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StartPoint {
    /// Whole angular steps, 0 to [`POINTS_PER_CIRCLE`] − 1.
    pub step: usize,
    /// The rest, a fraction of one step in [0, 1).
    pub fraction: f32,
}

impl StartPoint {
    /// The start point at `angle` radians.
    pub fn from_angle(angle: f32) -> Self {
        let steps = (angle / TAU * POINTS_PER_CIRCLE as f32).rem_euclid(POINTS_PER_CIRCLE as f32);
        let step = (steps.floor() as usize).min(POINTS_PER_CIRCLE - 1);
        StartPoint { step, fraction: (steps - step as f32).clamp(0.0, 1.0 - f32::EPSILON) }
    }

    /// Point k of circle c as a fraction of a turn, and its index on the circle when the start
    /// point is `fraction` alone (the whole steps move it by `step · c` places).
    fn turn_of(&self, c: usize, k: usize) -> (f32, usize) {
        let n = RoundStencil::circle_len(c);
        let place = (k + self.step * c) % n;
        ((place as f32 + self.fraction * c as f32) / n as f32, place)
    }
}

/// One arc of a circle inside one flattened face: from `from` (fraction of a turn) to the
/// next arc's start.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Arc {
    from: f32,
    /// The face's corners, or [`OUTSIDE`] beyond the patch.
    vertices: [u32; 3],
    /// The face's corners flattened, in the vertex's reference frame (world units).
    corners: [Vec2; 3],
}

/// The marching of every vertex of a mesh: per vertex and circle, the circle's arcs through
/// the flattened patch, in a reference frame independent of the texture direction.
#[derive(Clone, Debug, PartialEq)]
pub struct SurfaceMarching {
    /// The circles each vertex's neighbourhood is read on.
    pub stencil: RoundStencil,
    /// Distance between circles on the surface.
    pub texel: f32,
    /// Per vertex the reference tangent its arcs are measured from, and the normal.
    reference: Vec<(Vec3, Vec3)>,
    /// CSR over (vertex, circle): arcs of circle c of v are
    /// `arcs[arc_start[v · circles + c − 1] .. arc_start[v · circles + c]]`.
    arc_start: Vec<u32>,
    arcs: Vec<Arc>,
}

impl SurfaceMarching {
    /// Marches every vertex of `mesh` (with unit `normals`): the expensive part, done once.
    pub fn new(mesh: &Mesh, normals: &[Vec3], texel: f32, stencil: RoundStencil) -> Result<Self> {
        if normals.len() != mesh.vertex_count() {
            return Err(Error::invalid(format!(
                "{} normals for {} vertices",
                normals.len(),
                mesh.vertex_count()
            )));
        }
        if !(texel.is_finite() && texel > 0.0) || stencil.circles == 0 {
            return Err(Error::invalid("round neighbourhoods need a positive texel and a circle"));
        }
        // Any tangent will do, as long as it does not depend on the texture direction.
        let tangents: Vec<Vec3> = normals.iter().map(|n| n.any_orthonormal_vector()).collect();
        let reference_frames = Frames::from_directions(normals, &tangents);
        let topology = Topology::new(mesh);
        let reach = stencil.circles as f32 * texel;
        let per_vertex: Vec<Vec<Vec<Arc>>> = (0..mesh.vertex_count())
            .into_par_iter()
            .map_init(
                || Patch::new(mesh),
                |patch, v| {
                    flatten(mesh, &reference_frames, &topology, v as u32, Cover::Disc(reach), patch);
                    (1..=stencil.circles).map(|c| circle_arcs(mesh, patch, c as f32 * texel)).collect()
                },
            )
            .collect();
        let (mut arc_start, mut arcs) = (vec![0u32], Vec::new());
        for circles in per_vertex {
            for circle in circles {
                arcs.extend(circle);
                arc_start.push(arcs.len() as u32);
            }
        }
        let reference = reference_frames.s.iter().zip(normals).map(|(&s, &n)| (s, n)).collect();
        Ok(SurfaceMarching { stencil, texel, reference, arc_start, arcs })
    }

    /// Number of vertices marched.
    pub fn vertices(&self) -> usize {
        self.reference.len()
    }

    /// Where each vertex's round neighbourhood starts for the texture directions `frames.s`:
    /// the direction's angle from the vertex's reference tangent.
    pub fn start_points(&self, frames: &Frames) -> Vec<StartPoint> {
        self.reference
            .iter()
            .zip(&frames.s)
            .map(|(&(reference, n), &s)| {
                let up = n.cross(reference);
                StartPoint::from_angle(s.dot(up).atan2(s.dot(reference)))
            })
            .collect()
    }

    /// The round neighbourhood of vertex `v` from `start`, as surface textons in the order of
    /// [`RoundStencil::layout`] (into `out`); points beyond the patch hold the default texton.
    pub fn slots(&self, v: usize, start: StartPoint, out: &mut Vec<Slot>) {
        out.clear();
        out.resize(self.stencil.points(), Slot::DEFAULT);
        out[0] = Slot::at(v as u32);
        for c in 1..=self.stencil.circles {
            let i = v * self.stencil.circles + c - 1;
            let arcs = &self.arcs[self.arc_start[i] as usize..self.arc_start[i + 1] as usize];
            let radius = c as f32 * self.texel;
            for k in 0..RoundStencil::circle_len(c) {
                let (turn, _) = start.turn_of(c, k);
                out[RoundStencil::circle_start(c) + k] = point_slot(arcs, turn, radius);
            }
        }
    }

    /// Vertex `v`'s surface points at `points` (circle, fraction of a turn from `start`),
    /// for stencils other than [`RoundStencil::layout`]'s (the isotropic one,
    /// [`super::isotropic`]): the same marched arcs, any number of points per circle.
    /// Circle 0 is the vertex itself; points beyond the patch hold the default texton.
    pub fn slots_at(&self, v: usize, start: StartPoint, points: &[(usize, f32)], out: &mut Vec<Slot>) {
        out.clear();
        let start_turn = (start.step as f32 + start.fraction) / POINTS_PER_CIRCLE as f32;
        out.extend(points.iter().map(|&(c, turn)| {
            if c == 0 || c > self.stencil.circles {
                return if c == 0 { Slot::at(v as u32) } else { Slot::DEFAULT };
            }
            let i = v * self.stencil.circles + c - 1;
            let arcs = &self.arcs[self.arc_start[i] as usize..self.arc_start[i + 1] as usize];
            point_slot(arcs, (turn + start_turn).rem_euclid(1.0), c as f32 * self.texel)
        }));
    }

    /// Appends the marching to `out` in a compact little-endian form (read back by
    /// [`SurfaceMarching::read_from`]): the stencil's circles and the texel, then the
    /// reference frames, the CSR offsets and the arcs, each array after its length.
    pub fn write_to(&self, out: &mut Vec<u8>) {
        let floats =
            |out: &mut Vec<u8>, values: &[f32]| values.iter().for_each(|x| out.extend(x.to_le_bytes()));
        out.extend((self.stencil.circles as u64).to_le_bytes());
        out.extend(self.texel.to_le_bytes());
        out.extend((self.reference.len() as u64).to_le_bytes());
        for (s, n) in &self.reference {
            floats(out, &[s.x, s.y, s.z, n.x, n.y, n.z]);
        }
        out.extend((self.arc_start.len() as u64).to_le_bytes());
        self.arc_start.iter().for_each(|i| out.extend(i.to_le_bytes()));
        out.extend((self.arcs.len() as u64).to_le_bytes());
        for arc in &self.arcs {
            out.extend(arc.from.to_le_bytes());
            arc.vertices.iter().for_each(|i| out.extend(i.to_le_bytes()));
            let [a, b, c] = arc.corners;
            floats(out, &[a.x, a.y, b.x, b.y, c.x, c.y]);
        }
    }

    /// Reads a marching written by [`SurfaceMarching::write_to`], all of `bytes` and nothing
    /// more. Lengths are checked against the bytes present before anything is allocated, and
    /// the offsets and corner indices against each other, so damaged bytes give an error
    /// (the message says what is wrong), never a panic or a marching that would index out
    /// of range.
    pub fn read_from(bytes: &[u8]) -> std::result::Result<Self, String> {
        let mut r = LeReader(bytes);
        let circles = usize::try_from(r.u64()?).map_err(|_| "too many circles")?;
        if circles == 0 || circles > 64 {
            return Err(format!("{circles} circles"));
        }
        let texel = r.f32()?;
        if !(texel.is_finite() && texel > 0.0) {
            return Err(format!("texel {texel}"));
        }
        let vertices = r.len(24)?;
        let reference = (0..vertices)
            .map(|_| Ok((Vec3::new(r.f32()?, r.f32()?, r.f32()?), Vec3::new(r.f32()?, r.f32()?, r.f32()?))))
            .collect::<std::result::Result<Vec<_>, String>>()?;
        let offsets = r.len(4)?;
        if Some(offsets) != vertices.checked_mul(circles).map(|n| n + 1) {
            return Err(format!("{offsets} arc offsets for {vertices} vertices of {circles} circles"));
        }
        let arc_start = (0..offsets).map(|_| r.u32()).collect::<std::result::Result<Vec<_>, String>>()?;
        let count = r.len(40)?;
        let arcs = (0..count)
            .map(|_| {
                let from = r.f32()?;
                let vertices = [r.u32()?, r.u32()?, r.u32()?];
                let mut corner = || Ok::<_, String>(Vec2::new(r.f32()?, r.f32()?));
                Ok(Arc { from, vertices, corners: [corner()?, corner()?, corner()?] })
            })
            .collect::<std::result::Result<Vec<_>, String>>()?;
        if !r.0.is_empty() {
            return Err(format!("{} bytes after the arcs", r.0.len()));
        }
        if arc_start[0] != 0
            || arc_start.windows(2).any(|w| w[0] > w[1])
            || arc_start[offsets - 1] as usize != count
        {
            return Err("the arc offsets do not run from 0 to the arc count".into());
        }
        let in_range = |i: u32| i == OUTSIDE || (i as usize) < vertices;
        if let Some(arc) =
            arcs.iter().find(|a| !a.from.is_finite() || !a.vertices.iter().all(|&i| in_range(i)))
        {
            return Err(format!("an arc from {} through vertices {:?}", arc.from, arc.vertices));
        }
        Ok(SurfaceMarching { stencil: RoundStencil { circles }, texel, reference, arc_start, arcs })
    }
}

/// Little-endian values read off the front of a byte slice; running out is an error.
struct LeReader<'a>(&'a [u8]);

impl LeReader<'_> {
    fn take<const N: usize>(&mut self) -> std::result::Result<[u8; N], String> {
        let (head, rest) = self.0.split_first_chunk::<N>().ok_or("the data ends early")?;
        self.0 = rest;
        Ok(*head)
    }

    fn u32(&mut self) -> std::result::Result<u32, String> {
        self.take().map(u32::from_le_bytes)
    }

    fn u64(&mut self) -> std::result::Result<u64, String> {
        self.take().map(u64::from_le_bytes)
    }

    fn f32(&mut self) -> std::result::Result<f32, String> {
        self.take().map(f32::from_le_bytes)
    }

    /// An array length, refused unless that many items of `item_size` bytes could follow.
    fn len(&mut self, item_size: usize) -> std::result::Result<usize, String> {
        let n = self.u64()?;
        usize::try_from(n)
            .ok()
            .filter(|&n| n.checked_mul(item_size).is_some_and(|b| b <= self.0.len()))
            .ok_or_else(|| format!("an array of {n} items in {} bytes", self.0.len()))
    }
}

/// A mesh level's round neighbourhoods: its marching (done once) and the start points of
/// its texture directions (redone per direction, cheaply).
#[derive(Clone, Debug, PartialEq)]
pub struct MarchedLevel {
    /// The circles of every vertex through its flattened patch.
    pub marching: SurfaceMarching,
    /// Per vertex, the start point of its texture direction.
    pub starts: Vec<StartPoint>,
    /// Where the marching came from and how long that took (for reports).
    pub origin: MarchingOrigin,
}

impl MarchedLevel {
    /// Marches `mesh` with circles `texel` apart and starts them at `frames`' directions.
    pub fn new(mesh: &Mesh, frames: &Frames, texel: f32, stencil: RoundStencil) -> Result<Self> {
        Self::with_cache(mesh, frames, texel, stencil, None)
    }

    /// As [`MarchedLevel::new`], but the marching is read from `cache` where it holds one
    /// for exactly these inputs, and stored there when it had to be computed.
    pub fn with_cache(
        mesh: &Mesh,
        frames: &Frames,
        texel: f32,
        stencil: RoundStencil,
        cache: Option<&MarchingCache>,
    ) -> Result<Self> {
        let started = std::time::Instant::now();
        let (marching, source) = match cache {
            Some(cache) => cache.marching(mesh, &frames.n, texel, stencil)?,
            None => (SurfaceMarching::new(mesh, &frames.n, texel, stencil)?, MarchingSource::Computed),
        };
        let seconds = started.elapsed().as_secs_f64();
        let starts = marching.start_points(frames);
        Ok(MarchedLevel { marching, starts, origin: MarchingOrigin { source, seconds } })
    }
}

/// The slot at `turn` (fraction of a turn) on a circle of `radius` cut into `arcs`.
fn point_slot(arcs: &[Arc], turn: f32, radius: f32) -> Slot {
    // The arc holding `turn`: the last one starting at or before it (cyclically).
    let after = arcs.partition_point(|a| a.from <= turn);
    let Some(arc) = arcs.get(if after == 0 { arcs.len().wrapping_sub(1) } else { after - 1 }) else {
        return Slot::DEFAULT;
    };
    if arc.vertices[0] == OUTSIDE {
        return Slot::DEFAULT;
    }
    let q = Vec2::from_angle(turn * TAU) * radius;
    // On the arc's ends the point sits on an edge: clamp what rounding leaves outside.
    let weights = raw_barycentric(q, &arc.corners);
    slot(arc.vertices, weights)
}

/// Barycentric weights of `q` in a non-degenerate triangle, clamped to ≥ 0 and renormalised.
fn raw_barycentric(q: Vec2, t: &[Vec2; 3]) -> [f32; 3] {
    let area = (t[1] - t[0]).perp_dot(t[2] - t[0]);
    let w1 = (q - t[0]).perp_dot(t[2] - t[0]) / area;
    let w2 = (t[1] - t[0]).perp_dot(q - t[0]) / area;
    let w = [1.0 - w1 - w2, w1, w2].map(|x| x.max(0.0));
    let sum: f32 = w.iter().sum::<f32>().max(f32::EPSILON);
    w.map(|x| x / sum)
}

/// The circle of `radius` around the patch's centre cut where it crosses the patch's edges;
/// each piece takes the first face (breadth-first, the least distorted) holding its middle,
/// as the square templates do.
fn circle_arcs(mesh: &Mesh, patch: &Patch, radius: f32) -> Vec<Arc> {
    let faces = &patch.faces;
    let mut cuts: Vec<f32> = Vec::new();
    for (_, corners) in faces {
        for k in 0..3 {
            edge_crossings(corners[k], corners[(k + 1) % 3], radius, &mut cuts);
        }
    }
    cuts.sort_by(f32::total_cmp);
    cuts.dedup_by(|a, b| (*a - *b).abs() < 1e-6);
    if cuts.is_empty() {
        cuts.push(0.0);
    }
    let mut arcs: Vec<Arc> = Vec::with_capacity(cuts.len());
    for (i, &from) in cuts.iter().enumerate() {
        let to = cuts.get(i + 1).copied().unwrap_or(cuts[0] + 1.0);
        let middle = Vec2::from_angle((from + to) / 2.0 * TAU) * radius;
        let face = faces.iter().find(|(_, corners)| barycentric(middle, corners).is_some());
        let arc = match face {
            Some(&(f, corners)) => Arc { from, vertices: mesh.triangles()[f as usize], corners },
            None => Arc { from, vertices: [OUTSIDE; 3], corners: [Vec2::ZERO; 3] },
        };
        if arcs.last().is_none_or(|last| last.vertices != arc.vertices) {
            arcs.push(arc);
        }
    }
    arcs
}

/// Where segment a → b crosses the circle of `radius` around 0, as fractions of a turn.
fn edge_crossings(a: Vec2, b: Vec2, radius: f32, out: &mut Vec<f32>) {
    let d = b - a;
    let (qa, qb, qc) = (d.dot(d), 2.0 * a.dot(d), a.dot(a) - radius * radius);
    let disc = qb * qb - 4.0 * qa * qc;
    if qa <= 0.0 || disc < 0.0 {
        return;
    }
    for sign in [-1.0, 1.0] {
        let u = (-qb + sign * disc.sqrt()) / (2.0 * qa);
        if (0.0..=1.0).contains(&u) {
            let p = a + d * u;
            out.push((p.y.atan2(p.x) / TAU).rem_euclid(1.0));
        }
    }
}

/// The round neighbourhoods of every texel of one sample level (§5.3), from the start point
/// at the sample's own x axis, resampled bilinearly once per level: `points × dims` values
/// per texel.
#[derive(Clone, Debug)]
pub struct RoundSample {
    /// The circles each texel's neighbourhood is read on.
    pub stencil: RoundStencil,
    /// Width of the sample level in texels.
    pub width: usize,
    /// Height of the sample level in texels.
    pub height: usize,
    /// Values per point: the resampled map's dimensions.
    pub dims: usize,
    values: Vec<f32>,
}

impl RoundSample {
    /// Resamples `map` (a `width × height` level; its border supplies texels past the edge).
    pub fn new(map: &AppearanceMap, width: usize, height: usize, stencil: RoundStencil) -> Result<Self> {
        if stencil.circles > MAX_CIRCLES {
            return Err(Error::invalid(format!("at most {MAX_CIRCLES} circles")));
        }
        let offsets = layout_offsets(&stencil.layout());
        let dims = map.dims;
        let values = resample_at_offsets(map, width, height, &offsets, bilinear);
        Ok(RoundSample { stencil, width, height, dims, values })
    }

    /// The round neighbourhood of texel (x, y): `points × dims` values.
    pub fn at(&self, x: usize, y: usize) -> &[f32] {
        let n = self.stencil.points() * self.dims;
        let o = (y * self.width + x) * n;
        &self.values[o..o + n]
    }
}

/// The texel offsets of a stencil's `(circle, turn)` points: x along s, y down t (image
/// rows), as the square templates.
pub(crate) fn layout_offsets(layout: &[(usize, f32)]) -> Vec<Vec2> {
    layout
        .iter()
        .map(|&(c, turn)| {
            let p = Vec2::from_angle(turn * TAU) * c as f32;
            Vec2::new(p.x, -p.y)
        })
        .collect()
}

/// Every texel's neighbourhood of a `width × height` level of `map`: per texel, per offset,
/// `read` at the texel plus the offset (`dims` values each), texel after texel.
pub(crate) fn resample_at_offsets(
    map: &AppearanceMap,
    width: usize,
    height: usize,
    offsets: &[Vec2],
    read: impl Fn(&AppearanceMap, Vec2, &mut [f32]) + Sync,
) -> Vec<f32> {
    let dims = map.dims;
    let mut values = vec![0.0f32; width * height * offsets.len() * dims];
    values.par_chunks_mut(offsets.len() * dims).enumerate().for_each(|(p, texel)| {
        let centre = Vec2::new((p % width) as f32, (p / width) as f32);
        for (point, offset) in texel.chunks_mut(dims).zip(offsets) {
            read(map, centre + *offset, point);
        }
    });
    values
}

/// `map` at the real position `p` by bilinear interpolation, into `out`.
fn bilinear(map: &AppearanceMap, p: Vec2, out: &mut [f32]) {
    let (x0, y0) = (p.x.floor(), p.y.floor());
    let (fx, fy) = (p.x - x0, p.y - y0);
    let (x0, y0) = (x0 as i64, y0 as i64);
    out.fill(0.0);
    for (dx, dy, w) in
        [(0, 0, (1.0 - fx) * (1.0 - fy)), (1, 0, fx * (1.0 - fy)), (0, 1, (1.0 - fx) * fy), (1, 1, fx * fy)]
    {
        if w > 0.0 {
            for (o, &v) in out.iter_mut().zip(map.at(x0 + dx, y0 + dy)) {
                *o += w * v;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::surface::tests::{bunny, flat_grid};
    use crate::synth::target::OUTSIDE;

    const STENCIL: RoundStencil = RoundStencil { circles: 3 };

    #[test]
    fn the_stencil_has_equal_arc_steps() {
        assert_eq!(STENCIL.points(), 1 + 8 + 16 + 24);
        assert_eq!(RoundStencil::points_within(1), 9);
        let layout = STENCIL.layout();
        assert_eq!(layout.len(), STENCIL.points());
        for c in 1..=3 {
            let circle: Vec<f32> = layout.iter().filter(|p| p.0 == c).map(|p| p.1).collect();
            // Arc length between neighbours: 2π c / (8c), the same on every circle.
            let step = TAU * c as f32 * (circle[1] - circle[0]);
            assert!((step - TAU / 8.0).abs() < 1e-6, "circle {c}: {step}");
        }
    }

    /// Each point of a flat grid's round neighbourhood is the position it names: the slot's
    /// vertices blended by its weights land on the circle at its angle.
    #[test]
    fn points_lie_on_their_circles_on_a_flat_grid() {
        let (mesh, _) = flat_grid(13, 13, 0.5);
        let normals = vec![Vec3::Z; mesh.vertex_count()];
        let marching = SurfaceMarching::new(&mesh, &normals, 0.5, STENCIL).unwrap();
        let frames = Frames::from_directions(&normals, &vec![Vec3::new(1.0, 1.0, 0.0); normals.len()]);
        let starts = marching.start_points(&frames);
        let v = 6 * 13 + 6;
        let mut slots = Vec::new();
        marching.slots(v, starts[v], &mut slots);
        let p = mesh.positions();
        for (i, &(c, turn)) in STENCIL.layout().iter().enumerate() {
            let s = slots[i];
            assert_ne!(s.vertices[0], OUTSIDE);
            let at: Vec3 = (0..3).map(|k| p[s.vertices[k] as usize] * s.weights[k]).sum();
            // The direction (1, 1) is 45° from x; the texture's up is z × s.
            let angle = TAU / 8.0 + turn * TAU;
            let want = p[v] + Vec3::new(angle.cos(), angle.sin(), 0.0) * 0.5 * c as f32;
            assert!(at.distance(want) < 1e-4, "point {i}: {at} vs {want}");
        }
    }

    /// Whole angular steps permute the points exactly; a direction turned by 45° gives the
    /// same points, moved c places on circle c.
    #[test]
    fn rotating_by_angular_steps_permutes_the_samples_exactly() {
        let (mesh, frames, texel) = bunny();
        let marching = SurfaceMarching::new(&mesh, &frames.n, texel, STENCIL).unwrap();
        let starts = marching.start_points(&frames);
        let (mut a, mut b) = (Vec::new(), Vec::new());
        for v in (0..marching.vertices()).step_by(37) {
            for j in 1..8 {
                marching.slots(v, starts[v], &mut a);
                let turned = StartPoint { step: (starts[v].step + j) % 8, ..starts[v] };
                marching.slots(v, turned, &mut b);
                assert_eq!(a[0], b[0]);
                for c in 1..=3 {
                    let (n, o) = (RoundStencil::circle_len(c), RoundStencil::circle_start(c));
                    for k in 0..n {
                        assert_eq!(b[o + k], a[o + (k + j * c) % n], "v {v}, circle {c}, point {k}");
                    }
                }
            }
        }
        // Through the frames: a direction turned by 45° about the normal.
        let turned: Vec<Vec3> = (0..frames.len()).map(|v| (frames.s[v] + frames.t[v]).normalize()).collect();
        let turned_frames = Frames::from_directions(&frames.n, &turned);
        let again = marching.start_points(&turned_frames);
        for v in 0..marching.vertices() {
            let (s0, s1) = (starts[v], again[v]);
            let whole = (s1.step + 8 - s0.step) % 8;
            let near = (whole == 1 && (s1.fraction - s0.fraction).abs() < 1e-3)
                || (whole == 2 && s0.fraction > 0.999 && s1.fraction < 1e-3)
                || (whole == 0 && s0.fraction < 1e-3 && s1.fraction > 0.999);
            assert!(near, "vertex {v}: {s0:?} → {s1:?}");
        }
    }

    /// A new direction reads the marching, never recomputes it: `slots` and `start_points`
    /// take it by shared reference, and it is the same value after serving two directions.
    #[test]
    fn a_new_direction_reuses_the_marching() {
        let (mesh, frames, texel) = bunny();
        let marching = SurfaceMarching::new(&mesh, &frames.n, texel, STENCIL).unwrap();
        let kept = marching.clone();
        let other = Frames::from_directions(&frames.n, &vec![Vec3::Y; frames.len()]);
        let (mut a, mut b) = (Vec::new(), Vec::new());
        let (sa, sb) = (marching.start_points(&frames), marching.start_points(&other));
        let mut differ = 0;
        for v in 0..marching.vertices() {
            marching.slots(v, sa[v], &mut a);
            marching.slots(v, sb[v], &mut b);
            differ += usize::from(a != b);
        }
        assert!(differ > marching.vertices() / 2, "only {differ} neighbourhoods turned");
        assert_eq!(marching, kept);
    }

    /// The written form reads back to an equal marching, and every cut-short prefix of it is
    /// an error, never a panic or a marching.
    #[test]
    fn a_written_marching_reads_back_equal_and_truncation_is_an_error() {
        let (mesh, frames, texel) = bunny();
        let marching = SurfaceMarching::new(&mesh, &frames.n, texel, STENCIL).unwrap();
        let mut bytes = Vec::new();
        marching.write_to(&mut bytes);
        assert_eq!(SurfaceMarching::read_from(&bytes).unwrap(), marching);
        let step = (bytes.len() / 997).max(1);
        for len in (0..bytes.len()).step_by(step).chain([bytes.len() - 1]) {
            assert!(
                SurfaceMarching::read_from(&bytes[..len]).is_err(),
                "{len} of {} bytes read",
                bytes.len()
            );
        }
        let mut longer = bytes.clone();
        longer.push(0);
        assert!(SurfaceMarching::read_from(&longer).is_err());
        // An arc offset past the arcs (the first offset after the reference frames).
        let offsets_at = 8 + 4 + 8 + 24 * marching.vertices() + 8;
        let mut damaged = bytes.clone();
        damaged[offsets_at + 4..offsets_at + 8].copy_from_slice(&u32::MAX.to_le_bytes());
        assert!(SurfaceMarching::read_from(&damaged).is_err());
    }

    #[test]
    fn the_sample_is_resampled_on_the_same_circles() {
        // A ramp in x and one in y: bilinear resampling is exact on them.
        let (w, h) = (12usize, 10usize);
        let vectors: Vec<f32> = (0..w * h).flat_map(|p| [(p % w) as f32, (p / w) as f32]).collect();
        let map = AppearanceMap::new(w, h, 2, &vectors, false);
        let round = RoundSample::new(&map, w, h, STENCIL).unwrap();
        let centre = map.at(5, 5).to_vec();
        let unit_x = map.at(6, 5)[0] - centre[0];
        let unit_y = map.at(5, 6)[1] - centre[1];
        let values = round.at(5, 5);
        for (i, &(c, turn)) in STENCIL.layout().iter().enumerate() {
            let angle = turn * TAU;
            let want =
                [centre[0] + unit_x * c as f32 * angle.cos(), centre[1] - unit_y * c as f32 * angle.sin()];
            let got = &values[i * 2..i * 2 + 2];
            assert!((got[0] - want[0]).abs() < 1e-4 && (got[1] - want[1]).abs() < 1e-4, "{i}: {got:?}");
        }
        assert!(RoundSample::new(&map, w, h, RoundStencil { circles: 8 }).is_err());
    }
}
