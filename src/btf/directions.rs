//! Directions on the hemisphere above the sample, and the measurement domes that BTFs are
//! captured on.
//!
//! Angles are kept in the degrees they were read or generated in, so that a stack
//! round-trips exactly through its files; geometry goes through [`Direction::unit`].

use crate::{Error, Param, Result};
use glam::Vec3;
use std::collections::HashMap;
use std::fmt;

/// A direction in the sample's tangent frame: polar angle θ from the normal (0–90°) and
/// azimuth φ from the tangent s towards t, both in degrees.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Direction {
    /// Polar angle from the normal in degrees, 0–90.
    pub theta: f32,
    /// Azimuth from the tangent s towards t in degrees, -360–360.
    pub phi: f32,
}

impl Direction {
    /// Checks the angles: finite, θ in [0, 90], φ in [-360, 360].
    pub fn new(theta: f32, phi: f32) -> Result<Self> {
        if !theta.is_finite() || !phi.is_finite() {
            return Err(Error::invalid(format!("angle θ={theta}, φ={phi} is not a number")));
        }
        if !(0.0..=90.0).contains(&theta) {
            return Err(Error::invalid(format!("θ={theta}° is outside 0–90°")));
        }
        if !(-360.0..=360.0).contains(&phi) {
            return Err(Error::invalid(format!("φ={phi}° is outside -360–360°")));
        }
        Ok(Direction { theta, phi })
    }

    /// The normal: θ = 0.
    pub const NORMAL: Direction = Direction { theta: 0.0, phi: 0.0 };

    /// Unit vector (x along s, y along t, z along the normal).
    pub fn unit(&self) -> Vec3 {
        let (t, p) = (self.theta.to_radians(), self.phi.to_radians());
        Vec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos())
    }

    /// A key equal for directions that differ by less than 0.001° (φ is irrelevant at θ = 0).
    pub(crate) fn key(&self) -> (i64, i64) {
        let theta = (self.theta as f64 * 1000.0).round() as i64;
        let phi = if theta == 0 {
            0
        } else {
            ((self.phi as f64).rem_euclid(360.0) * 1000.0).round() as i64 % 360_000
        };
        (theta, phi)
    }

    /// True if both name the same direction.
    pub fn same_as(&self, other: &Direction) -> bool {
        self.key() == other.key()
    }
}

impl fmt::Display for Direction {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "θ={}° φ={}°", self.theta, self.phi)
    }
}

/// The light and view directions under which one image was taken.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DirectionPair {
    /// Direction towards the light.
    pub light: Direction,
    /// Direction towards the camera.
    pub view: Direction,
}

impl DirectionPair {
    /// True if both lights and both views name the same directions (see [`Direction::same_as`]).
    pub fn same_as(&self, other: &DirectionPair) -> bool {
        self.light.same_as(&other.light) && self.view.same_as(&other.view)
    }
}

impl fmt::Display for DirectionPair {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "light {}, view {}", self.light, self.view)
    }
}

/// Direction pairs stored as rows of θ_light, φ_light, θ_view, φ_view in degrees (an
/// analysis' `directions.npy`), each checked as [`Direction::new`] does; the message names
/// the first bad row.
pub fn pairs_from_rows(rows: &[f32]) -> std::result::Result<Vec<DirectionPair>, String> {
    if rows.len() % 4 != 0 {
        return Err(format!("{} values are not rows of four angles", rows.len()));
    }
    rows.chunks_exact(4)
        .enumerate()
        .map(|(i, r)| {
            let light = Direction::new(r[0], r[1]).map_err(|e| format!("row {i}, light: {e}"))?;
            let view = Direction::new(r[2], r[3]).map_err(|e| format!("row {i}, view: {e}"))?;
            Ok(DirectionPair { light, view })
        })
        .collect()
}

/// Indices of the first two pairs that name the same directions, if any.
pub fn first_duplicate(pairs: &[DirectionPair]) -> Option<(usize, usize)> {
    let mut seen = HashMap::with_capacity(pairs.len());
    for (i, p) in pairs.iter().enumerate() {
        if let Some(&j) = seen.get(&(p.light.key(), p.view.key())) {
            return Some((j, i));
        }
        seen.insert((p.light.key(), p.view.key()), i);
    }
    None
}

/// The distinct directions of `dirs`, in first-seen order.
pub fn distinct(dirs: impl Iterator<Item = Direction>) -> Vec<Direction> {
    let mut seen = std::collections::HashSet::new();
    dirs.filter(|d| seen.insert(d.key())).collect()
}

/// A measurement dome: the set of directions used for both views and lights; a stack
/// generated on it holds every view × light pair.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DirectionSet {
    /// Bonn UBO2003: 81 directions, rings at θ = 0, 15, …, 75° with 1, 6, 12, 18, 20, 24 azimuths.
    Ubo81,
    /// Bonn UBO2014: 151 directions on ten rings from θ = 0 to 75°.
    Ubo151,
    /// N directions spread evenly (by area) over the cap θ ≤ 75°, for quick tests.
    Grid(usize),
}

const UBO81_RINGS: [(f32, usize); 6] = [(0.0, 1), (15.0, 6), (30.0, 12), (45.0, 18), (60.0, 20), (75.0, 24)];
const UBO151_RINGS: [(f32, usize); 10] = [
    (0.0, 1),
    (11.0, 6),
    (23.5, 12),
    (30.0, 12),
    (37.5, 12),
    (45.0, 18),
    (52.5, 18),
    (60.0, 24),
    (67.5, 24),
    (75.0, 24),
];
/// Grazing limit of the generated domes, as in the Bonn setups.
const MAX_THETA: f32 = 75.0;

impl DirectionSet {
    /// The directions of the dome.
    pub fn directions(&self) -> Vec<Direction> {
        match self {
            DirectionSet::Ubo81 => rings(&UBO81_RINGS),
            DirectionSet::Ubo151 => rings(&UBO151_RINGS),
            DirectionSet::Grid(n) => spiral(*n),
        }
    }

    /// Every (light, view) pair, view-major (all lights for the first view, then the next).
    pub fn pairs(&self) -> Vec<DirectionPair> {
        let dirs = self.directions();
        dirs.iter().flat_map(|&view| dirs.iter().map(move |&light| DirectionPair { light, view })).collect()
    }
}

impl std::str::FromStr for DirectionSet {
    type Err = Error;

    fn from_str(s: &str) -> Result<Self> {
        match s {
            "ubo81" => Ok(DirectionSet::Ubo81),
            "ubo151" => Ok(DirectionSet::Ubo151),
            _ => match s.strip_prefix("grid:").map(str::parse::<usize>) {
                Some(Ok(n)) if (1..=1000).contains(&n) => Ok(DirectionSet::Grid(n)),
                _ => Err(Error::out_of_range(
                    Param::Directions,
                    format!("'{s}'"),
                    "expected ubo81, ubo151 or grid:N with N in 1..=1000",
                )),
            },
        }
    }
}

impl fmt::Display for DirectionSet {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            DirectionSet::Ubo81 => write!(f, "ubo81"),
            DirectionSet::Ubo151 => write!(f, "ubo151"),
            DirectionSet::Grid(n) => write!(f, "grid:{n}"),
        }
    }
}

fn rings(spec: &[(f32, usize)]) -> Vec<Direction> {
    spec.iter()
        .flat_map(|&(theta, count)| {
            (0..count).map(move |k| Direction { theta, phi: 360.0 * k as f32 / count as f32 })
        })
        .collect()
}

/// A Fibonacci spiral, equal-area in cos θ, from the normal to θ = 75°; angles rounded to
/// 0.001° so that manifests stay readable.
fn spiral(n: usize) -> Vec<Direction> {
    let cos_max = MAX_THETA.to_radians().cos() as f64;
    let golden = 180.0 * (3.0 - 5f64.sqrt());
    let round = |a: f64| ((a * 1000.0).round() / 1000.0) as f32;
    (0..n)
        .map(|k| {
            let f = if n == 1 { 0.0 } else { k as f64 / (n - 1) as f64 };
            let theta = (1.0 - (1.0 - cos_max) * f).acos().to_degrees();
            let phi = if k == 0 { 0.0 } else { (k as f64 * golden).rem_euclid(360.0) };
            Direction { theta: round(theta), phi: round(phi) }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn domes_have_their_published_counts() {
        assert_eq!(DirectionSet::Ubo81.directions().len(), 81);
        assert_eq!(DirectionSet::Ubo151.directions().len(), 151);
        assert_eq!(DirectionSet::Ubo81.pairs().len(), 6561);
        assert_eq!(DirectionSet::Grid(7).directions().len(), 7);
        for set in [DirectionSet::Ubo81, DirectionSet::Ubo151, DirectionSet::Grid(50)] {
            let pairs = set.pairs();
            assert_eq!(first_duplicate(&pairs), None, "{set}");
            assert!(set.directions().iter().all(|d| d.theta <= 75.0 && d.theta >= 0.0));
        }
    }

    #[test]
    fn phi_is_irrelevant_at_the_pole_and_wraps() {
        let a = Direction::new(0.0, 0.0).unwrap();
        let b = Direction::new(0.0, 120.0).unwrap();
        assert!(a.same_as(&b));
        let c = Direction::new(30.0, -90.0).unwrap();
        let d = Direction::new(30.0, 270.0).unwrap();
        assert!(c.same_as(&d));
        assert!(!c.same_as(&Direction::new(30.0, 90.0).unwrap()));
    }

    #[test]
    fn bad_angles_are_rejected() {
        assert!(Direction::new(f32::NAN, 0.0).is_err());
        assert!(Direction::new(91.0, 0.0).is_err());
        assert!(Direction::new(-1.0, 0.0).is_err());
        assert!(Direction::new(10.0, 400.0).is_err());
        assert!("grid:0".parse::<DirectionSet>().is_err());
        assert_eq!("grid:5".parse::<DirectionSet>().unwrap(), DirectionSet::Grid(5));
    }

    #[test]
    fn unit_vectors_point_into_the_upper_hemisphere() {
        for d in DirectionSet::Ubo151.directions() {
            let u = d.unit();
            assert!((u.length() - 1.0).abs() < 1e-6 && u.z > 0.25);
        }
    }
}
