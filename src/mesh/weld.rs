//! Welding coincident vertices, so that patches written with duplicated seam vertices
//! (the Utah teapot, OBJ groups, UV seams) become one connected surface.

use glam::Vec3;
use std::collections::HashMap;

/// Maps every vertex to the first earlier vertex within `tolerance` of it (itself if none),
/// and counts the vertices so merged. Greedy in index order, so the result is
/// deterministic; `tolerance = 0` welds only exactly equal positions.
pub(crate) fn weld(positions: &[Vec3], tolerance: f32) -> (Vec<u32>, usize) {
    if tolerance > 0.0 && tolerance.is_finite() {
        weld_within(positions, tolerance)
    } else {
        weld_exact(positions)
    }
}

fn weld_exact(positions: &[Vec3]) -> (Vec<u32>, usize) {
    // +0.0 and −0.0 are the same point but have different bits.
    let key = |p: Vec3| (p + Vec3::ZERO).to_array().map(f32::to_bits);
    let mut first = HashMap::with_capacity(positions.len());
    let remap: Vec<u32> =
        (0..positions.len() as u32).map(|i| *first.entry(key(positions[i as usize])).or_insert(i)).collect();
    let merged = remap.iter().enumerate().filter(|&(i, &r)| r as usize != i).count();
    (remap, merged)
}

/// Hashes vertices into cells of side `tolerance`; a match lies in one of the 27 cells
/// around a vertex's own.
fn weld_within(positions: &[Vec3], tolerance: f32) -> (Vec<u32>, usize) {
    let cell = |p: Vec3| (p / tolerance).floor().to_array().map(|c| c as i64);
    let mut grid: HashMap<[i64; 3], Vec<u32>> = HashMap::with_capacity(positions.len());
    let mut remap = Vec::with_capacity(positions.len());
    let mut merged = 0;
    for (i, &p) in positions.iter().enumerate() {
        let c = cell(p);
        let found = neighbour_cells(c)
            .filter_map(|n| grid.get(&n))
            .flatten()
            .copied()
            .filter(|&j| positions[j as usize].distance(p) <= tolerance)
            .min();
        match found {
            Some(j) => {
                remap.push(j);
                merged += 1;
            }
            None => {
                remap.push(i as u32);
                grid.entry(c).or_default().push(i as u32);
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

    #[test]
    fn exact_weld_merges_equal_positions_and_signed_zeros() {
        let p = [Vec3::ZERO, Vec3::X, Vec3::new(-0.0, 0.0, 0.0), Vec3::X];
        assert_eq!(weld(&p, 0.0), (vec![0, 1, 0, 1], 2));
    }

    #[test]
    fn tolerance_weld_merges_near_points_only() {
        let p = [Vec3::ZERO, Vec3::new(1e-4, 0.0, 0.0), Vec3::new(0.1, 0.0, 0.0), Vec3::new(-5e-5, 0.0, 0.0)];
        assert_eq!(weld(&p, 2e-4), (vec![0, 0, 2, 0], 2));
    }

    #[test]
    fn tolerance_weld_finds_matches_across_cell_borders() {
        let t = 1e-3;
        let p = [Vec3::splat(t * 0.999), Vec3::splat(t * 1.001)];
        assert_eq!(weld(&p, t).0, vec![0, 0]);
    }
}
