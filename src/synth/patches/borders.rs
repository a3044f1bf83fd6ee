//! Moving patch borders to where the two textures agree, once every face is mapped.
//!
//! The hierarchy fixes where patches meet; the fit and the relaxation then make the textures
//! agree along those borders as well as they can. A face on a border may as well take the
//! texture of the patch across one of its edges, continued rigidly over it: the border then
//! runs along the face's other edges. Such a move is kept where it lowers the texture's
//! jump summed along the face's edges, so borders drift, face by face, to where the two
//! patches' textures already agree: the minimum-error boundary of image quilting (Efros and
//! Freeman 2001, whom §3.1 of the paper cites for non-straight borders), found greedily on
//! the mesh's edges rather than by a cut through pixels. A face alone in its patch, whose
//! every side is a seam, is taken over by the neighbour it continues best.

use super::chart::unfold;
use super::fit::FitImage;
use super::graph::NONE;
use super::mapper::{Mapper, Mapping};
use glam::Vec2;

/// Passes over the surface; each stops early once no face moves.
const SWEEPS: usize = 4;

/// Moves border faces to the patch across their edges wherever that lowers the jump summed
/// along their edges; returns how many moves were made.
pub(super) fn move_borders(m: &Mapper, mapping: &mut Mapping) -> usize {
    let graph = m.graph;
    let mut moves = 0;
    for _ in 0..SWEEPS {
        let before = moves;
        for f in 0..graph.face_count() as u32 {
            if graph.area[f as usize] <= 0.0 || mapping.mapped_by[f as usize] == NONE {
                continue;
            }
            let own = mapping.mapped_by[f as usize];
            let mut others: Vec<u32> = graph.across[f as usize]
                .iter()
                .filter(|&&g| g != NONE)
                .map(|&g| mapping.mapped_by[g as usize])
                .filter(|&p| p != own && p != NONE)
                .collect();
            if others.is_empty() {
                continue;
            }
            others.sort_unstable();
            others.dedup();
            let now = jump(m, mapping, f, &mapping.face_uv[f as usize]);
            let best = others
                .into_iter()
                .filter_map(|p| continued(m, mapping, f, p).map(|uv| (jump(m, mapping, f, &uv), p, uv)))
                .min_by(|a, b| a.0.total_cmp(&b.0));
            if let Some((cost, p, uv)) = best.filter(|b| b.0 < now * (1.0 - 1e-4)) {
                debug_assert!(cost.is_finite());
                mapping.mapped_by[f as usize] = p;
                mapping.face_uv[f as usize] = uv;
                moves += 1;
            }
        }
        if moves == before {
            break;
        }
    }
    moves
}

/// The squared difference (fitting space) between face `f`'s texture at `uv` and its
/// textured neighbours' along its edges, summed at about one point per texel.
fn jump(m: &Mapper, mapping: &Mapping, f: u32, uv: &[Vec2; 3]) -> f32 {
    let (graph, image) = (m.graph, &m.fitter.image);
    let t = graph.corners[f as usize];
    let mut total = 0.0;
    for k in 0..3 {
        let g = graph.across[f as usize][k];
        if g == NONE || mapping.mapped_by[g as usize] == NONE {
            continue;
        }
        let (a, b) = (t[k], t[(k + 1) % 3]);
        let (Some(ga), Some(gb)) = (graph.corner_of(g, a), graph.corner_of(g, b)) else { continue };
        let other = mapping.face_uv[g as usize];
        total += edge_jump(image, (uv[k], uv[(k + 1) % 3]), (other[ga], other[gb]));
    }
    total
}

/// The squared difference (fitting space) between two textures along one edge, given by
/// its two ends' coordinates in each (`mine` and `theirs`, in the same order), summed at
/// about one point per texel of its length.
pub(super) fn edge_jump(image: &FitImage, mine: (Vec2, Vec2), theirs: (Vec2, Vec2)) -> f32 {
    let ((ua, ub), (ta, tb)) = (mine, theirs);
    let (mut here, mut there) = (vec![0f32; image.channels], vec![0f32; image.channels]);
    let steps = (ua.distance(ub).max(ta.distance(tb)).ceil() as usize).clamp(1, 64);
    let mut total = 0.0;
    for i in 0..=steps {
        let s = i as f32 / steps as f32;
        image.sample(ua.lerp(ub, s), &mut here);
        image.sample(ta.lerp(tb, s), &mut there);
        total += here.iter().zip(&there).map(|(x, y)| (x - y) * (x - y)).sum::<f32>() / (steps + 1) as f32
            * ua.distance(ub).max(1.0);
    }
    total
}

/// Face `f`'s coordinates in patch `p`'s texture continued over it: a corner it shares
/// with any face of `p` (across an edge or only at the corner) takes that face's
/// coordinates, so the patch stays one continuous texture; a corner left over is unfolded
/// from a shared edge with the face's own lengths, on the side that keeps the face's
/// winding. None where no edge is shared, `p`'s faces disagree at a corner, the face would
/// turn over, or a corner leaves a sample that does not tile.
fn continued(m: &Mapper, mapping: &Mapping, f: u32, p: u32) -> Option<[Vec2; 3]> {
    let graph = m.graph;
    let t = graph.corners[f as usize];
    let mut known: [Option<Vec2>; 3] = [None; 3];
    for j in 0..3 {
        for &g in graph.faces_of(t[j]) {
            if g == f || mapping.mapped_by[g as usize] != p {
                continue;
            }
            let at = mapping.face_uv[g as usize][graph.corner_of(g, t[j])?];
            if known[j].get_or_insert(at).distance(at) > 1e-3 {
                return None;
            }
        }
    }
    let k = (0..3).find(|&k| {
        let g = graph.across[f as usize][k];
        g != NONE && mapping.mapped_by[g as usize] == p
    })?;
    let apex = (k + 2) % 3;
    // The texture's winding is the face's own, as its current coordinates have it.
    let own = mapping.face_uv[f as usize];
    let sign = (own[1] - own[0]).perp_dot(own[2] - own[0]);
    let uv = match known[apex] {
        Some(_) => {
            let uv = known.map(|c| c.unwrap_or_default());
            if (uv[1] - uv[0]).perp_dot(uv[2] - uv[0]) * sign <= 0.0 {
                return None;
            }
            uv
        }
        None => {
            let (a, b) = (known[k]?, known[(k + 1) % 3]?);
            let scale = m.params.texels_per_unit;
            let at = |i: usize| graph.positions[t[i] as usize];
            let (la, lb) = (at(k).distance(at(apex)) * scale, at((k + 1) % 3).distance(at(apex)) * scale);
            let mut uv = [Vec2::ZERO; 3];
            uv[k] = a;
            uv[(k + 1) % 3] = b;
            uv[apex] = unfold(a, b, la, lb);
            if (uv[1] - uv[0]).perp_dot(uv[2] - uv[0]) * sign < 0.0 {
                uv[apex] = unfold(b, a, lb, la);
            }
            uv
        }
    };
    uv.iter().all(|&c| m.fitter.image.inside(c)).then_some(uv)
}

#[cfg(test)]
pub(super) mod tests {
    use super::super::chart::Flattening;
    use super::super::fit::{FitImage, Fitter};
    use super::super::graph::{tests::grid, SurfaceGraph};
    use super::super::hierarchy::Hierarchy;
    use super::super::SolerParams;
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;
    use std::path::Path;

    /// A unit plane of `n`² squares over a 64² noise sample, at 40 texels per unit: noise,
    /// so that the texture shifted agrees with the original nowhere, and a misplaced face
    /// or strip has exactly one right place. The border moves and cuts are tested on it.
    pub struct NoisePlane {
        pub graph: SurfaceGraph,
        hierarchy: Hierarchy,
        flattening: Flattening,
        fitter: Fitter,
        params: SolerParams,
    }

    impl NoisePlane {
        pub fn new(n: u32) -> Self {
            let (p, t) = grid(n);
            let graph = SurfaceGraph::new(&p, &t, Path::new("grid")).unwrap();
            let hierarchy = Hierarchy::build(&graph, &mut ChaCha8Rng::seed_from_u64(1));
            let flattening = Flattening::new(&graph, &hierarchy);
            let side = 64;
            let values: Vec<f32> = (0..side * side * 3)
                .map(|i: usize| ((i as u32).wrapping_mul(2_654_435_761) >> 16) as f32 / 65_536.0)
                .collect();
            let fitter = Fitter::new(FitImage::new(side, side, 3, values, false).unwrap(), 4).unwrap();
            let params = SolerParams { texels_per_unit: 40.0, ..SolerParams::default() };
            NoisePlane { graph, hierarchy, flattening, fitter, params }
        }

        pub fn mapper(&self) -> Mapper<'_> {
            Mapper {
                graph: &self.graph,
                hierarchy: &self.hierarchy,
                flattening: &self.flattening,
                fitter: &self.fitter,
                params: &self.params,
                first_face: None,
            }
        }

        /// The rigid map's texel of vertex `v`: chart texels mirrored to image rows, as the
        /// mapping writes them.
        pub fn texel(&self, v: u32) -> Vec2 {
            let q = self.graph.positions[v as usize];
            Vec2::new(10.0 + 40.0 * q.x, 50.0 - 40.0 * q.y)
        }
    }

    /// A plane textured by one rigid map but labelled as two patches (left and right
    /// halves), with one face of the left half given the same texture shifted, as a patch
    /// of its own: that face alone moves, back onto the map its neighbours continue, and
    /// the seamless border between the halves stays where it is.
    #[test]
    fn a_misplaced_face_takes_the_texture_its_neighbours_continue() {
        let plane = NoisePlane::new(4);
        let (graph, m) = (&plane.graph, plane.mapper());
        let map = |v: u32| plane.texel(v);
        let mut mapping = Mapping::new(graph.face_count());
        for f in 0..graph.face_count() {
            let centre: f32 = graph.corners[f].iter().map(|&v| graph.positions[v as usize].x).sum::<f32>();
            mapping.mapped_by[f] = u32::from(centre > 1.5);
            mapping.face_uv[f] = graph.corners[f].map(map);
        }
        let odd = (0..graph.face_count())
            .find(|&f| {
                // Its neighbours come after it, so it is the first face with a seam that the
                // sweep meets (no neighbour moves first to continue it instead).
                let across = graph.across[f].iter().filter(|&&g| g != NONE);
                mapping.mapped_by[f] == 0
                    && across.clone().count() > 0
                    && across.clone().all(|&g| g as usize > f && mapping.mapped_by[g as usize] == 0)
            })
            .unwrap();
        mapping.mapped_by[odd] = 2;
        mapping.face_uv[odd] = mapping.face_uv[odd].map(|c| c + Vec2::new(3.0, 2.0));
        let expected = mapping.face_uv[odd];
        let want = graph.corners[odd].map(map);

        assert_eq!(move_borders(&m, &mut mapping), 1);
        assert_eq!(mapping.mapped_by[odd], 0);
        for (got, want) in mapping.face_uv[odd].iter().zip(want) {
            assert!(got.distance(want) < 1e-3, "{got} against {want} (was {expected:?})");
        }
        let labels: Vec<u32> = (0..graph.face_count())
            .filter(|&f| f != odd)
            .map(|f| {
                u32::from(graph.corners[f].iter().map(|&v| graph.positions[v as usize].x).sum::<f32>() > 1.5)
            })
            .collect();
        let now: Vec<u32> =
            (0..graph.face_count()).filter(|&f| f != odd).map(|f| mapping.mapped_by[f]).collect();
        assert_eq!(labels, now);
        for f in 0..graph.face_count() {
            let want = graph.corners[f].map(map);
            let uv = mapping.face_uv[f];
            assert!(uv.iter().zip(want).all(|(got, want)| got.distance(want) < 1e-3), "face {f}");
        }
    }
}
