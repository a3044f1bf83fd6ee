//! Edge-length statistics: how uniform a remeshed surface's sampling is.

use crate::mesh::{topology, Mesh};
use std::fmt;

/// Lengths of a mesh's undirected edges.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EdgeLengthStats {
    /// Number of edges.
    pub count: usize,
    /// Mean length.
    pub mean: f64,
    /// Shortest edge.
    pub min: f64,
    /// Longest edge.
    pub max: f64,
    /// Population standard deviation.
    pub std_dev: f64,
    /// `std_dev / mean`: 0 for perfectly uniform edges; isotropic remeshing gives ≈ 0.2.
    pub coefficient_of_variation: f64,
}

/// The edge-length statistics of `mesh`.
pub fn edge_length_stats(mesh: &Mesh) -> EdgeLengthStats {
    let p = mesh.positions();
    let lengths: Vec<f64> = topology::edges(mesh)
        .iter()
        .map(|&[a, b]| f64::from(p[a as usize].distance(p[b as usize])))
        .collect();
    let count = lengths.len();
    let n = count.max(1) as f64;
    let mean = lengths.iter().sum::<f64>() / n;
    let variance = lengths.iter().map(|l| (l - mean).powi(2)).sum::<f64>() / n;
    let std_dev = variance.sqrt();
    EdgeLengthStats {
        count,
        mean,
        min: lengths.iter().copied().fold(f64::INFINITY, f64::min),
        max: lengths.iter().copied().fold(0.0, f64::max),
        std_dev,
        coefficient_of_variation: if mean > 0.0 { std_dev / mean } else { 0.0 },
    }
}

impl fmt::Display for EdgeLengthStats {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{} edges, length mean {:.4e}, min {:.4e}, max {:.4e}, CV {:.3}",
            self.count, self.mean, self.min, self.max, self.coefficient_of_variation
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::test_meshes::cube;

    #[test]
    fn cube_edges_are_sides_and_diagonals() {
        let s = edge_length_stats(&cube());
        assert_eq!(s.count, 18);
        assert!((s.min - 1.0).abs() < 1e-9 && (s.max - 2f64.sqrt()).abs() < 1e-6);
        let mean = (12.0 + 6.0 * 2f64.sqrt()) / 18.0;
        assert!((s.mean - mean).abs() < 1e-6);
        assert!(s.coefficient_of_variation > 0.1 && s.coefficient_of_variation < 0.3);
    }
}
