//! One template pixel as the engine stores it: three vertices and barycentric weights. A
//! leaf (it uses only [`crate::sentinel`]), so that targets, flattening and round
//! neighbourhoods can all name it.

/// Marks a template pixel outside the patch: it holds the default texton.
pub use crate::sentinel::OUTSIDE;

/// One template pixel: s = Σ wₐ t(vertexₐ), the 6-tuple (w0, w1, w2, t0, t1, t2) of Tong
/// §5.1 with the textons looked up from the vertices at synthesis time. A pixel outside the
/// patch has `vertices[0] == OUTSIDE`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Slot {
    /// The three vertices whose textons the pixel blends; `vertices[0]` is [`OUTSIDE`]
    /// outside the patch.
    pub vertices: [u32; 3],
    /// Their barycentric weights (summing to 1, or all 0 for [`Slot::NONE`]).
    pub weights: [f32; 3],
}

impl Slot {
    /// Outside a surface patch: the default texton (Tong §5.1).
    pub const DEFAULT: Slot = Slot { vertices: [OUTSIDE; 3], weights: [1.0, 0.0, 0.0] };
    /// Not compared at all: past the edge of a plane, where nothing exists to match.
    pub const NONE: Slot = Slot { vertices: [OUTSIDE; 3], weights: [0.0; 3] };

    /// A template pixel that falls exactly on one vertex.
    pub fn at(vertex: u32) -> Slot {
        Slot { vertices: [vertex, vertex, vertex], weights: [1.0, 0.0, 0.0] }
    }
}
