//! The points of Castellanos and Williams' isotropic stencil (§3.12) and how a 60° turn
//! permutes them: a leaf, so that the isotropic neighbourhood ([`super::isotropic`]) and its
//! kd-trees ([`super::kdtrees`]) share it without using each other.

/// Points on each ring: the inner (radius 1 texel), then the outer (radius 2).
pub const RING_POINTS: [usize; 2] = [12, 24];

/// Points of the stencil, centre excluded (the paper's 36 faces).
pub const POINTS: usize = RING_POINTS[0] + RING_POINTS[1];

/// Eq. 7's proximity weight per ring: the mean of exp(−½ (d / 1.3 σ_k)²) over the paper's
/// 12 one-distant faces (d = 1, √3 and 2 spacings, 3, 6 and 3 of them) and its 24
/// two-distant faces (√7, 3, 2√3 and √13, 6 each), σ_k one adjacent-face spacing.
pub const BETA: [f32; 2] = [0.4684, 0.0615];

/// The rotations compared: 0°, 60° and 120°.
pub const TURNS: usize = 3;

/// Point `p`'s ring (0 inner, 1 outer) and its place on it.
pub fn ring_of(p: usize) -> (usize, usize) {
    if p < RING_POINTS[0] {
        (0, p)
    } else {
        (1, p - RING_POINTS[0])
    }
}

/// The point that point `p` moves to when the stencil turns by `turn` × 60°.
pub fn turned(p: usize, turn: usize) -> usize {
    let (ring, k) = ring_of(p);
    let n = RING_POINTS[ring];
    let first = if ring == 0 { 0 } else { RING_POINTS[0] };
    first + (k + turn * n / 6) % n
}
