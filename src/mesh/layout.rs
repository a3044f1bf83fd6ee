//! Memory layout of a mesh: vertices renumbered along a space-filling curve so that
//! neighbours on the surface are neighbours in memory.
//!
//! The remesher appends every split vertex at the end, in its global longest-edge-first
//! order, so a remeshed mesh's neighbouring vertices lie scattered over the arrays. Every
//! later stage walks neighbourhoods (flattening templates, the synthesis passes, linking
//! levels), and on a 250k-vertex surface those walks were bound by cache misses:
//! flattening alone was a third of the run.

use glam::Vec3;
use rayon::prelude::*;

/// Bits per axis of the Morton code (3 × 21 = 63 bits).
const BITS: u32 = 21;

/// A renumbering of `positions` and `triangles`: per new vertex its old index, in Morton
/// (Z-order) of the positions in their bounding box (ties in the old order), and the faces
/// renumbered and sorted by their lowest new vertex (ties in the old order). Each face
/// keeps its corners' cyclic order, so its orientation.
pub fn spatial_order(positions: &[Vec3], triangles: &[[u32; 3]]) -> (Vec<u32>, Vec<[u32; 3]>) {
    let (lo, hi) =
        positions.iter().fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), &p| (lo.min(p), hi.max(p)));
    let scale = ((1u32 << BITS) - 1) as f32 / (hi - lo).max_element().max(f32::MIN_POSITIVE);
    // Each code once, not once per comparison (a sort compares each key about log n times).
    let mut keys: Vec<(u64, u32)> = positions
        .par_iter()
        .enumerate()
        .map(|(v, &p)| (morton(((p - lo) * scale).to_array()), v as u32))
        .collect();
    keys.sort_unstable();
    let order: Vec<u32> = keys.into_iter().map(|(_, v)| v).collect();
    let mut renumber = vec![0u32; positions.len()];
    for (new, &old) in order.iter().enumerate() {
        renumber[old as usize] = new as u32;
    }
    let mut faces: Vec<[u32; 3]> = triangles.iter().map(|t| t.map(|c| renumber[c as usize])).collect();
    faces.sort_by_key(|t| t.iter().copied().min());
    (order, faces)
}

/// `values` (one per old vertex) in the new order of [`spatial_order`].
pub fn permuted<T: Copy>(values: &[T], order: &[u32]) -> Vec<T> {
    order.iter().map(|&v| values[v as usize]).collect()
}

/// The Morton code of a point whose coordinates are already scaled to [0, 2^BITS).
fn morton(p: [f32; 3]) -> u64 {
    p.iter().enumerate().fold(0, |code, (axis, &x)| code | (spread(x as u64) << axis))
}

/// The low [`BITS`] bits of `x` moved to every third bit, by halving the distance
/// between moved groups five times (32, 16, 8, 4, 2 places).
fn spread(x: u64) -> u64 {
    let mut x = x & ((1 << BITS) - 1);
    x = (x | x << 32) & 0x001f_0000_0000_ffff;
    x = (x | x << 16) & 0x001f_0000_ff00_00ff;
    x = (x | x << 8) & 0x100f_00f0_0f00_f00f;
    x = (x | x << 4) & 0x10c3_0c30_c30c_30c3;
    (x | x << 2) & 0x1249_2492_4924_9249
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The bit tricks move each bit where moving them one at a time does.
    #[test]
    fn spread_moves_every_bit_to_every_third() {
        let one_at_a_time = |x: u64| (0..BITS as u64).fold(0, |out, bit| out | ((x >> bit) & 1) << (3 * bit));
        let mut x = 0x9e37_79b9_7f4a_7c15u64;
        for _ in 0..10_000 {
            x = x.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1_442_695_040_888_963_407);
            assert_eq!(spread(x), one_at_a_time(x), "{x:#x}");
        }
        for x in [0, 1, (1 << BITS) - 1, 1 << BITS, u64::MAX] {
            assert_eq!(spread(x), one_at_a_time(x), "{x:#x}");
        }
    }

    /// The layout is a permutation: the same faces around the same points, each with its
    /// orientation, only numbered otherwise; and neighbours along a line end up close.
    #[test]
    fn renumbering_keeps_every_face_and_brings_neighbours_together() {
        // A strip of triangles along x whose vertices are numbered in a scattered order.
        let n = 64u32;
        let scatter = |i: u32| (i * 37) % (2 * n);
        let mut positions = vec![Vec3::ZERO; 2 * n as usize];
        for i in 0..n {
            positions[scatter(2 * i) as usize] = Vec3::new(i as f32, 0.0, 0.0);
            positions[scatter(2 * i + 1) as usize] = Vec3::new(i as f32, 1.0, 0.0);
        }
        let triangles: Vec<[u32; 3]> = (0..n - 1)
            .flat_map(|i| {
                let [a, b, c, d] = [2 * i, 2 * i + 1, 2 * i + 2, 2 * i + 3].map(scatter);
                [[a, c, b], [b, c, d]]
            })
            .collect();
        let (order, t) = spatial_order(&positions, &triangles);
        let p = permuted(&positions, &order);
        let corners = |ps: &[Vec3], ts: &[[u32; 3]]| {
            let mut faces: Vec<[[i64; 3]; 3]> = ts
                .iter()
                .map(|f| {
                    let c = f.map(|v| ps[v as usize].to_array().map(|x| x as i64));
                    // The cyclic rotation that starts at the smallest corner.
                    let k = (0..3).min_by_key(|&k| c[k]).unwrap();
                    [c[k], c[(k + 1) % 3], c[(k + 2) % 3]]
                })
                .collect();
            faces.sort();
            faces
        };
        assert_eq!(corners(&p, &t), corners(&positions, &triangles));
        let spread =
            |ts: &[[u32; 3]]| ts.iter().map(|f| f.iter().max().unwrap() - f.iter().min().unwrap()).max();
        assert!(spread(&t) < Some(12), "{:?} against {:?}", spread(&t), spread(&triangles));
    }

    #[test]
    fn morton_interleaves_the_axes() {
        assert_eq!(morton([1.0, 0.0, 0.0]), 0b001);
        assert_eq!(morton([0.0, 1.0, 0.0]), 0b010);
        assert_eq!(morton([0.0, 0.0, 1.0]), 0b100);
        assert_eq!(morton([3.0, 0.0, 0.0]), 0b001_001);
    }
}
