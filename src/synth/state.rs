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
}
