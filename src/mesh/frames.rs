//! Tangent frames (s, t, n) per vertex (Tong §5.1, Turk §4): n is the surface normal, s
//! the "right" direction of the texture, t = n × s its "up".

use glam::Vec3;

/// One orthonormal, right-handed frame per vertex (s × t = n).
#[derive(Clone, Debug, PartialEq)]
pub struct Frames {
    /// The texture's "right" direction, a unit tangent.
    pub s: Vec<Vec3>,
    /// The texture's "up" direction, `n × s`.
    pub t: Vec<Vec3>,
    /// The unit surface normal.
    pub n: Vec<Vec3>,
}

impl Frames {
    /// Frames from unit normals and desired directions: each direction is projected onto its
    /// tangent plane and normalised; where it (nearly) vanishes, any tangent is used.
    pub fn from_directions(normals: &[Vec3], directions: &[Vec3]) -> Frames {
        let mut frames = Frames {
            s: Vec::with_capacity(normals.len()),
            t: Vec::with_capacity(normals.len()),
            n: normals.to_vec(),
        };
        for (&n, &d) in normals.iter().zip(directions) {
            let s = tangent_towards(n, d);
            frames.s.push(s);
            frames.t.push(n.cross(s));
        }
        frames
    }

    /// Number of vertices.
    pub fn len(&self) -> usize {
        self.n.len()
    }

    /// True if there are no vertices.
    pub fn is_empty(&self) -> bool {
        self.n.is_empty()
    }
}

/// The unit tangent of the plane ⟂ `n` closest to `d` (any tangent if `d` is parallel to `n`).
pub fn tangent_towards(n: Vec3, d: Vec3) -> Vec3 {
    let projected = d - n * n.dot(d);
    if projected.length_squared() > 1e-12 {
        projected.normalize()
    } else {
        n.any_orthonormal_vector()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_are_orthonormal_and_right_handed() {
        let normals = [Vec3::Z, Vec3::new(1.0, 1.0, 0.0).normalize(), Vec3::X];
        let frames = Frames::from_directions(&normals, &[Vec3::X, Vec3::X, Vec3::X]);
        for i in 0..3 {
            let (s, t, n) = (frames.s[i], frames.t[i], frames.n[i]);
            assert!((s.length() - 1.0).abs() < 1e-6 && (t.length() - 1.0).abs() < 1e-6);
            assert!(s.dot(n).abs() < 1e-6 && t.dot(n).abs() < 1e-6 && s.dot(t).abs() < 1e-6);
            assert!((s.cross(t) - n).length() < 1e-5);
        }
        assert!((frames.s[0] - Vec3::X).length() < 1e-6);
    }
}
