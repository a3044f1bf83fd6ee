//! Near-isometric flattening of a cluster's faces: the local/global ("as rigid as
//! possible") parametrization of Liu et al. 2008, started from a given chart.
//!
//! The recursive coordinates of §3.2 place a cluster's vertices by barycentric coordinates
//! in projections of its ancestors' control polygons, which is exact on a plane but, on a
//! curved surface, compounds the projection error of every level: on the dragon at the
//! default scale, 281 of level 5's 1,212 clusters (16.5 faces each) folded and level 4's
//! 90th-percentile area error was 0.48, so the mapping fell to clusters of a few faces. The
//! paper asks of a chart only that it keep the surface's lengths and angles as well as it
//! can (§3.2, "same edge lengths and near angles"); this finishes the recursive chart by
//! pulling every face towards a rotated copy of its own 3D shape, which is what its
//! distortion limit measures.

use glam::{DVec2, Vec2, Vec3};

/// Alternations of the local (best rotation per face) and global (least squares) steps.
const ROUNDS: usize = 12;
/// Conjugate-gradient iterations per global step (warm-started from the last round).
const SOLVER_STEPS: usize = 40;

/// The faces of a chart, each with its own 3D shape laid flat and its edge weights.
pub(super) struct Faces {
    /// Per face, its corners (indices in the chart's vertices).
    corners: Vec<[u32; 3]>,
    /// Per face, its corners' positions in a plane frame of the face (isometric).
    shape: Vec<[DVec2; 3]>,
    /// Per face, the cotangent weight of the edge opposite each corner (clamped).
    weight: Vec<[f64; 3]>,
}

impl Faces {
    /// The faces `corners` over the vertices at 3D `positions`.
    pub(super) fn new(corners: &[[u32; 3]], positions: &[Vec3]) -> Faces {
        let shape: Vec<[DVec2; 3]> =
            corners.iter().map(|t| flat_shape(t.map(|i| positions[i as usize]))).collect();
        let weight = shape.iter().map(cotangents).collect();
        Faces { corners: corners.to_vec(), shape, weight }
    }

    /// Whether the faces have no usable weight (every one without area).
    fn is_empty(&self) -> bool {
        self.weight.iter().all(|w| w.iter().all(|&x| x == 0.0))
    }

    /// Edges of face `f` as (from corner, to corner, weight): the edge opposite corner k.
    fn edges(&self, f: usize) -> impl Iterator<Item = (usize, usize, f64)> + '_ {
        let t = self.corners[f];
        (0..3).map(move |k| (t[(k + 1) % 3] as usize, t[(k + 2) % 3] as usize, self.weight[f][k]))
    }
}

/// Flattens `faces` from `start` (a chart's positions per vertex, counter-clockwise): the
/// vertices moved to lower the faces' departure from rigid copies of their 3D shapes.
pub(super) fn flatten(faces: &Faces, start: &[Vec2]) -> Vec<Vec2> {
    let n = start.len();
    if faces.is_empty() || n < 3 {
        return start.to_vec();
    }
    let mut u: Vec<DVec2> = start.iter().map(|p| p.as_dvec2()).collect();
    let diagonal = diagonal(faces, n);
    for _ in 0..ROUNDS {
        let rhs = right_hand_side(faces, &u, n);
        solve(faces, &diagonal, &rhs, &mut u);
    }
    let mean = u.iter().copied().sum::<DVec2>() / n as f64;
    u.iter().map(|&p| (p - mean).as_vec2()).collect()
}

/// A face's corners in a plane frame of its own: a at the origin, b on +x, c above.
fn flat_shape([a, b, c]: [Vec3; 3]) -> [DVec2; 3] {
    let (a, b, c) = (a.as_dvec3(), b.as_dvec3(), c.as_dvec3());
    let ab = (b - a).length();
    let x = if ab > 0.0 { (b - a) / ab } else { glam::DVec3::X };
    let along = (c - a).dot(x);
    let height = ((c - a) - along * x).length();
    [DVec2::ZERO, DVec2::new(ab, 0.0), DVec2::new(along, height)]
}

/// Per corner, the cotangent of its angle: the weight of the opposite edge. Clamped to
/// [0, 100] so that slivers and obtuse angles cannot make the system indefinite or stiff.
fn cotangents(p: &[DVec2; 3]) -> [f64; 3] {
    let twice_area = (p[1] - p[0]).perp_dot(p[2] - p[0]).abs();
    if twice_area <= 0.0 {
        return [0.0; 3];
    }
    std::array::from_fn(|k| {
        let (o, a, b) = (p[k], p[(k + 1) % 3], p[(k + 2) % 3]);
        ((a - o).dot(b - o) / twice_area).clamp(0.0, 100.0)
    })
}

/// The diagonal of the system's matrix (the weighted Laplacian): the preconditioner.
fn diagonal(faces: &Faces, n: usize) -> Vec<f64> {
    let mut d = vec![0f64; n];
    for f in 0..faces.corners.len() {
        for (i, j, w) in faces.edges(f) {
            d[i] += w;
            d[j] += w;
        }
    }
    d.iter().map(|&x| if x > 0.0 { 1.0 / x } else { 0.0 }).collect()
}

/// The local step and the global step's right-hand side: per face the rotation closest to
/// its current map, then Σ w R (xᵢ − xⱼ) per vertex.
fn right_hand_side(faces: &Faces, u: &[DVec2], n: usize) -> Vec<DVec2> {
    let mut rhs = vec![DVec2::ZERO; n];
    for f in 0..faces.corners.len() {
        let t = faces.corners[f];
        let x = faces.shape[f];
        let local = |i: usize| x[t.iter().position(|&v| v as usize == i).unwrap_or(0)];
        // tr(Rᵀ S), S = Σ w (uᵢ − uⱼ)(xᵢ − xⱼ)ᵀ, is largest at the angle below.
        let (mut cos, mut sin) = (0f64, 0f64);
        for (i, j, w) in faces.edges(f) {
            let (du, dx) = (u[i] - u[j], local(i) - local(j));
            cos += w * du.dot(dx);
            sin += w * dx.perp_dot(du);
        }
        let rotation = DVec2::from_angle(sin.atan2(cos));
        for (i, j, w) in faces.edges(f) {
            let target = w * rotation.rotate(local(i) - local(j));
            rhs[i] += target;
            rhs[j] -= target;
        }
    }
    rhs
}

/// The weighted Laplacian times `u`.
fn apply(faces: &Faces, u: &[DVec2], out: &mut [DVec2]) {
    out.iter_mut().for_each(|o| *o = DVec2::ZERO);
    for f in 0..faces.corners.len() {
        for (i, j, w) in faces.edges(f) {
            let d = w * (u[i] - u[j]);
            out[i] += d;
            out[j] -= d;
        }
    }
}

/// Preconditioned conjugate gradients on the Laplacian (singular only by translations,
/// which the right-hand side, summing to zero, never excites), both axes at once.
fn solve(faces: &Faces, inverse_diagonal: &[f64], rhs: &[DVec2], u: &mut [DVec2]) {
    let n = u.len();
    let dot = |a: &[DVec2], b: &[DVec2]| a.iter().zip(b).map(|(p, q)| p.dot(*q)).sum::<f64>();
    let mut r = vec![DVec2::ZERO; n];
    apply(faces, u, &mut r);
    r.iter_mut().zip(rhs).for_each(|(r, &b)| *r = b - *r);
    let norm = dot(rhs, rhs).max(f64::MIN_POSITIVE);
    let precondition =
        |r: &[DVec2]| -> Vec<DVec2> { r.iter().zip(inverse_diagonal).map(|(&r, &d)| r * d).collect() };
    let mut z = precondition(&r);
    let mut p = z.clone();
    let mut rz = dot(&r, &z);
    let mut ap = vec![DVec2::ZERO; n];
    for _ in 0..SOLVER_STEPS {
        if dot(&r, &r) <= 1e-18 * norm {
            break;
        }
        apply(faces, &p, &mut ap);
        let pap = dot(&p, &ap);
        if pap <= 0.0 || !pap.is_finite() {
            break;
        }
        let alpha = rz / pap;
        u.iter_mut().zip(&p).for_each(|(u, &p)| *u += alpha * p);
        r.iter_mut().zip(&ap).for_each(|(r, &a)| *r -= alpha * a);
        z = precondition(&r);
        let next = dot(&r, &z);
        let beta = next / rz.max(f64::MIN_POSITIVE);
        rz = next;
        p.iter_mut().zip(&z).for_each(|(p, &z)| *p = z + beta * *p);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A bent strip: two rows of a grid folded 60° along its middle column line.
    fn bent(n: usize) -> (Vec<Vec3>, Vec<[u32; 3]>) {
        let mut p = Vec::new();
        for y in 0..=1 {
            for x in 0..=n {
                let (fx, half) = (x as f32, n as f32 / 2.0);
                let bend = (fx - half).max(0.0);
                p.push(Vec3::new(fx.min(half) + bend * 0.5, y as f32, bend * 0.866));
            }
        }
        let w = n as u32 + 1;
        let mut t = Vec::new();
        for x in 0..n as u32 {
            t.push([x, x + 1, w + x + 1]);
            t.push([x, w + x + 1, w + x]);
        }
        (p, t)
    }

    #[test]
    fn a_developable_strip_unbends_to_its_lengths() {
        let (p, t) = bent(8);
        // Start from the projection on z = 0, which shortens the bent half by half.
        let start: Vec<Vec2> = p.iter().map(|q| Vec2::new(q.x, q.y)).collect();
        let faces = Faces::new(&t, &p);
        let flat = flatten(&faces, &start);
        for tri in &t {
            for k in 0..3 {
                let (a, b) = (tri[k] as usize, tri[(k + 1) % 3] as usize);
                let (real, now) = (p[a].distance(p[b]), flat[a].distance(flat[b]));
                assert!((real - now).abs() < 1e-3 * real.max(1.0), "edge {a}-{b}: {now} for {real}");
            }
        }
        // The start was far from isometric, so the flattening did the work.
        let worst =
            t.iter().flat_map(|tri| (0..3).map(move |k| (tri[k] as usize, tri[(k + 1) % 3] as usize)));
        let shortest =
            worst.map(|(a, b)| start[a].distance(start[b]) / p[a].distance(p[b])).fold(1f32, f32::min);
        assert!(shortest < 0.6, "{shortest}");
    }
}
