//! Welding coincident vertices, so that patches written with duplicated seam vertices
//! (the Utah teapot, OBJ groups, UV seams) become one connected surface.

use glam::Vec3;
use std::collections::{BTreeMap, HashMap};

/// The fraction of a vertex's shortest edge within which [`weld`] looks for its twin.
pub(crate) const LOCAL_FRACTION: f32 = 0.01;

/// Maps every vertex to the first earlier vertex within tolerance of it (itself if none),
/// and counts the vertices so merged. Greedy in index order, so the result is
/// deterministic.
///
/// Each vertex has its own tolerance: `relative` × the shortest edge it has in `triangles`,
/// and at most `cap`; two vertices weld if they are closer than the smaller of their two.
/// A weld therefore never moves a vertex by more than that fraction of its shortest edge
/// and never joins the ends of an edge, whatever else lies in the file: a stray triangle far
/// away (which inflates a bounding-box tolerance) changes nothing. `cap = 0` (or `relative =
/// 0`) welds only exactly equal positions.
pub(crate) fn weld(positions: &[Vec3], triangles: &[[u32; 3]], relative: f32, cap: f32) -> (Vec<u32>, usize) {
    if cap > 0.0 && cap.is_finite() && relative > 0.0 && relative.is_finite() {
        weld_within(positions, &local_tolerances(positions, triangles, relative, cap))
    } else {
        weld_exact(positions)
    }
}

/// The exact-position key (+0.0 and −0.0 are the same point but have different bits).
fn key(p: Vec3) -> [u32; 3] {
    (p + Vec3::ZERO).to_array().map(f32::to_bits)
}

fn weld_exact(positions: &[Vec3]) -> (Vec<u32>, usize) {
    let mut first = HashMap::with_capacity(positions.len());
    let remap: Vec<u32> =
        (0..positions.len() as u32).map(|i| *first.entry(key(positions[i as usize])).or_insert(i)).collect();
    let merged = remap.iter().enumerate().filter(|&(i, &r)| r as usize != i).count();
    (remap, merged)
}

/// Per vertex: `relative` × its shortest non-zero edge, at most `cap`; 0 (exact matches
/// only) for a vertex without such an edge.
fn local_tolerances(positions: &[Vec3], triangles: &[[u32; 3]], relative: f32, cap: f32) -> Vec<f32> {
    let mut shortest = vec![f32::INFINITY; positions.len()];
    for t in triangles {
        for k in 0..3 {
            let (a, b) = (t[k] as usize, t[(k + 1) % 3] as usize);
            let (Some(&pa), Some(&pb)) = (positions.get(a), positions.get(b)) else { continue };
            let d = pa.distance(pb);
            if d > 0.0 && d.is_finite() {
                shortest[a] = shortest[a].min(d);
                shortest[b] = shortest[b].min(d);
            }
        }
    }
    shortest.into_iter().map(|s| if s.is_finite() { (relative * s).min(cap) } else { 0.0 }).collect()
}

/// Vertices by grid cell.
type Grid = HashMap<[i64; 3], Vec<u32>>;

/// Kept vertices are hashed into grids, one per octave of tolerance (cells twice the
/// octave's largest tolerance), so a match lies in one of the 27 cells around a vertex's
/// own in each grid, however much the tolerances vary.
fn weld_within(positions: &[Vec3], tolerance: &[f32]) -> (Vec<u32>, usize) {
    let cell_of = |p: Vec3, cell: f32| (p / cell).floor().to_array().map(|c| c as i64);
    let mut exact: HashMap<[u32; 3], u32> = HashMap::with_capacity(positions.len());
    let mut grids: BTreeMap<i32, (f32, Grid)> = BTreeMap::new();
    let mut remap = Vec::with_capacity(positions.len());
    let mut merged = 0;
    for (i, (&p, &t)) in positions.iter().zip(tolerance).enumerate() {
        let mut found = exact.get(&key(p)).copied();
        if t > 0.0 {
            for (cell, grid) in grids.values() {
                let near = neighbour_cells(cell_of(p, *cell))
                    .filter_map(|n| grid.get(&n))
                    .flatten()
                    .copied()
                    .filter(|&j| positions[j as usize].distance(p) <= t.min(tolerance[j as usize]));
                found = found.into_iter().chain(near).min();
            }
        }
        match found {
            Some(j) => {
                remap.push(j);
                merged += 1;
            }
            None => {
                remap.push(i as u32);
                exact.insert(key(p), i as u32);
                if t > 0.0 {
                    let octave = t.log2().floor() as i32;
                    let (cell, grid) = grids
                        .entry(octave)
                        .or_insert_with(|| (2f32.powi(octave.saturating_add(1)), HashMap::new()));
                    grid.entry(cell_of(p, *cell)).or_default().push(i as u32);
                }
            }
        }
    }
    (remap, merged)
}

fn neighbour_cells(c: [i64; 3]) -> impl Iterator<Item = [i64; 3]> {
    (0..27).map(move |k| {
        let d = [k % 3 - 1, (k / 3) % 3 - 1, k / 9 - 1];
        [0, 1, 2].map(|a| c[a].saturating_add(d[a]))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Tolerances given directly, as [`weld`] derives them from the edges.
    fn weld_with(p: &[Vec3], t: f32) -> (Vec<u32>, usize) {
        weld_within(p, &vec![t; p.len()])
    }

    #[test]
    fn exact_weld_merges_equal_positions_and_signed_zeros() {
        let p = [Vec3::ZERO, Vec3::X, Vec3::new(-0.0, 0.0, 0.0), Vec3::X];
        assert_eq!(weld(&p, &[], 0.01, 0.0), (vec![0, 1, 0, 1], 2));
        assert_eq!(weld(&p, &[], 0.01, 1.0), (vec![0, 1, 0, 1], 2), "no edges: exact matches only");
    }

    #[test]
    fn tolerance_weld_merges_near_points_only() {
        let p = [Vec3::ZERO, Vec3::new(1e-4, 0.0, 0.0), Vec3::new(0.1, 0.0, 0.0), Vec3::new(-5e-5, 0.0, 0.0)];
        assert_eq!(weld_with(&p, 2e-4), (vec![0, 0, 2, 0], 2));
    }

    #[test]
    fn tolerance_weld_finds_matches_across_cell_borders() {
        let t = 1e-3;
        let p = [Vec3::splat(t * 0.999), Vec3::splat(t * 1.001)];
        assert_eq!(weld_with(&p, t).0, vec![0, 0]);
    }

    #[test]
    fn tolerances_follow_the_local_edges_not_the_whole_file() {
        // Two unit triangles sharing an edge written twice (a seam 1e-4 apart), and a
        // stray triangle a million units away whose size gives a large cap.
        let p = [
            Vec3::ZERO,
            Vec3::X,
            Vec3::Y,
            Vec3::new(1.0, 1e-4, 0.0),
            Vec3::new(0.0, 1.0 + 1e-4, 0.0),
            Vec3::ONE,
            Vec3::splat(1e6),
            Vec3::splat(1e6) + Vec3::X * 1e5,
            Vec3::splat(1e6) + Vec3::Y * 1e5,
        ];
        let triangles = [[0, 1, 2], [3, 5, 4], [6, 7, 8]];
        let (remap, merged) = weld(&p, &triangles, 0.01, 100.0);
        assert_eq!((remap[3], remap[4], merged), (1, 2, 2), "the seam welds");
        // A triangle of edges 1e-3 next to a vertex 5e-4 away: 1% of the edges is below.
        let q = [Vec3::ZERO, Vec3::X * 1e-3, Vec3::Y * 1e-3, Vec3::X * 5e-4 + Vec3::Z * 1e-9];
        let (remap, merged) = weld(&q, &[[0, 1, 2], [3, 1, 2]], 0.01, 100.0);
        assert_eq!((remap, merged), (vec![0, 1, 2, 3], 0), "no edge collapses, whatever the cap");
    }
}
