//! What synthesis rewrites, pass after pass: the texton map of one level. A leaf of the
//! engine, so that every part can name it without depending on the others.

/// The surface texton map of one level: per vertex a texton label and a sample coordinate.
#[derive(Clone, Debug, PartialEq)]
pub struct State {
    /// Texton label per vertex (or pixel).
    pub labels: Vec<u16>,
    /// Sample coordinate per vertex (or pixel): the column and row, in texels, of the
    /// sample texel it copies.
    pub uv: Vec<[i32; 2]>,
    /// Per vertex, where it lies within the texel it copies, in texels (each axis within
    /// ±0.5 of the texel's centre), where the synthesis knows; empty where it gives whole
    /// texels only. A surface's vertices are not on a grid, so a patch copied whole onto
    /// them falls between texels; rounding every vertex to its texel jitters the copy by up
    /// to half a texel, which a renderer shows as jagged edges (docs/surfaces.md). Set once
    /// the passes are done (the passes move vertices by whole texels).
    pub subtexel: Vec<[f32; 2]>,
}

impl State {
    /// A state of whole texels.
    pub fn new(labels: Vec<u16>, uv: Vec<[i32; 2]>) -> State {
        State { labels, uv, subtexel: Vec::new() }
    }

    /// Vertex `v`'s sample coordinate with its place within the texel, where known.
    pub fn coordinate(&self, v: usize) -> [f32; 2] {
        let [x, y] = self.uv[v].map(|c| c as f32);
        match self.subtexel.get(v) {
            Some([dx, dy]) => [x + dx, y + dy],
            None => [x, y],
        }
    }
}
