//! The parts every Bonn BTF file shares: the signature, the meta header, the direction
//! table, the image size and the optional block of frame rotations (btflib's
//! `read_common_header`, `read_meta_data`, `read_bidir_sampling`).

use super::bytes::Cursor;
use crate::btf::{Direction, DirectionPair};
use crate::Result;

/// The file layouts a signature announces.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Variant {
    /// Decorrelated full matrix factorization: one SVD per colour channel.
    Dfmf,
    /// Full matrix factorization: one SVD of all channels; `extended` files carry a
    /// header version with the dynamic-range flag and an optional height map.
    Fmf {
        /// Whether the signature is `!FMF12FCER` (header version, dynamic-range flag,
        /// optional height map) rather than `!FMF06FC`.
        extended: bool,
    },
    /// Per-view factorization (not read yet).
    Pvf,
    /// Bidirectional image file: raw ABRDFs in chunks of scan lines.
    Bdi,
}

impl Variant {
    /// The format's short name.
    pub fn name(&self) -> &'static str {
        match self {
            Variant::Dfmf => "DFMF",
            Variant::Fmf { .. } => "FMF",
            Variant::Pvf => "PVF",
            Variant::Bdi => "BDI",
        }
    }
}

/// Every signature btflib knows, plus `!DFMF08FC` (DFMF without a rotation block, which
/// btf-extractor reads). A trailing `R` (for BDI: the `R` before `2!`) announces the
/// rotation block.
pub const SIGNATURES: [(&str, Variant); 8] = [
    ("!DFMF08FCR", Variant::Dfmf),
    ("!DFMF08FC", Variant::Dfmf),
    ("!FMF12FCER", Variant::Fmf { extended: true }),
    ("!FMF06FCR", Variant::Fmf { extended: false }),
    ("!FMF06FC", Variant::Fmf { extended: false }),
    ("!PVF06FCR", Variant::Pvf),
    ("!PVF06FC", Variant::Pvf),
    ("!BDIF06R2!", Variant::Bdi),
];

/// True if the signature announces a rotation block.
pub fn has_rotation_block(signature: &str) -> bool {
    signature.ends_with('R') || signature == "!BDIF06R2!"
}

/// The signatures that `start` (the first bytes of a file) may begin with, longest first:
/// `!DFMF08FCR…` may be a DFMF with rotations, or one without whose header size happens to
/// start with the byte `R`, so both are tried.
pub fn candidate_signatures(start: &[u8]) -> Vec<(&'static str, Variant)> {
    let mut found: Vec<(&'static str, Variant)> =
        SIGNATURES.iter().copied().filter(|(s, _)| start.starts_with(s.as_bytes())).collect();
    found.sort_by_key(|(s, _)| std::cmp::Reverse(s.len()));
    found
}

/// The meta header's fields.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct Meta {
    /// Header version (2 adds the cosine flag, 3 the XML, 4 the channel names).
    pub version: u32,
    /// The measurement setup's description (free text).
    pub measurement_setup: String,
    /// The camera sensor's description (free text).
    pub image_sensor: String,
    /// The light source's description (free text).
    pub light_source: String,
    /// Resolution of the sample in pixels per millimetre, as recorded.
    pub pixels_per_mm: f32,
    /// Scale factors of R, G and B recorded by the measurement (informational).
    pub rgb_scale: [f32; 3],
    /// The data hold radiance × cos θ_light; decoding divides it out.
    pub cosine_flag: bool,
    /// The measurement's XML description (may be empty).
    pub xml: String,
    /// Channel names (R, G, B unless the header says otherwise).
    pub channels: Vec<String>,
}

/// Largest meta header accepted: generous for the XML, small enough to refuse nonsense.
const MAX_META_BYTES: u32 = 64 << 20;

/// Reads the meta header; it must consume exactly the `size` it declares.
pub fn read_meta(c: &mut Cursor) -> Result<Meta> {
    c.section("meta header");
    let start = c.pos();
    let size = c.u32("the header size")?;
    if !(8..=MAX_META_BYTES).contains(&size) {
        return Err(c.error(format!("declared size {size} bytes is not a meta header size")));
    }
    let version = c.u32("the header version")?;
    let mut meta = Meta {
        version,
        measurement_setup: c.text(80, "the measurement setup")?,
        image_sensor: c.text(80, "the image sensor")?,
        light_source: c.text(80, "the light source")?,
        pixels_per_mm: c.f32("pixels per mm")?,
        rgb_scale: c.f32s("the RGB scale")?,
        channels: ["R", "G", "B"].map(String::from).to_vec(),
        ..Meta::default()
    };
    if version > 1 {
        meta.cosine_flag = c.u32("the cosine flag")? != 0;
    }
    if version > 2 {
        let n = c.u32("the XML length")?;
        meta.xml = String::from_utf8_lossy(&c.take(n as u64, "the XML")?).into_owned();
    }
    if version > 3 {
        let n = c.u32("the channel count")?;
        c.need(n as u64, 4, "the channel names")?;
        meta.channels = (0..n).map(|_| read_name(c)).collect::<Result<_>>()?;
    }
    let read = c.pos() - start;
    if read != size as u64 {
        return Err(c.error(format!("declares {size} bytes but its fields take {read}")));
    }
    Ok(meta)
}

fn read_name(c: &mut Cursor) -> Result<String> {
    let n = c.u32("a channel name length")?;
    let raw = c.take(n as u64, "a channel name")?;
    Ok(String::from_utf8_lossy(&raw).trim_end_matches('\0').to_string())
}

/// The direction table: every image's (light, view) pair, image `l + lights·v` under light
/// `l` of view `v` (the row order of the factorized matrices).
#[derive(Clone, Debug, PartialEq)]
pub struct Directions {
    pub views: usize,
    pub lights: usize,
    pub pairs: Vec<DirectionPair>,
}

/// Reads the direction table: u32 view count, then per view (θ, φ) in radians, a u32
/// light count and that many (θ, φ). Every view must have the same number of lights.
pub fn read_directions(c: &mut Cursor) -> Result<Directions> {
    c.section("direction table");
    let views = c.u32("the view count")? as u64;
    // Each view takes at least its angles and its light count.
    c.need(views, 12, "the views")?;
    if views == 0 {
        return Err(c.error("the file has no views"));
    }
    let mut lights_per_view = None;
    let mut pairs = Vec::new();
    for v in 0..views {
        let angles = c.f32s::<2>("a view direction")?;
        let view = direction(c, angles, format!("view {v}"))?;
        let count = c.u32("a light count")? as u64;
        c.need(count, 8, "the light directions")?;
        match lights_per_view {
            None if count == 0 => return Err(c.error("view 0 has no lights")),
            None => lights_per_view = Some(count),
            Some(n) if n != count => {
                return Err(c.error(format!(
                    "view {v} has {count} lights but view 0 has {n}; every view must use one light count"
                )))
            }
            _ => {}
        }
        for l in 0..count {
            let angles = c.f32s::<2>("a light direction")?;
            let light = direction(c, angles, format!("light {l} of view {v}"))?;
            pairs.push(DirectionPair { light, view });
        }
    }
    let lights = lights_per_view.unwrap_or(0) as usize;
    if let Some((a, b)) = crate::btf::directions::first_duplicate(&pairs) {
        return Err(
            c.error(format!("images {a} and {b} have the same light and view directions ({})", pairs[a]))
        );
    }
    Ok(Directions { views: views as usize, lights, pairs })
}

/// Radians from the file to degrees, rounded to 0.0001° so that whole-degree angles read
/// back as whole degrees; φ is taken modulo 360°.
fn direction(c: &Cursor, [theta, phi]: [f32; 2], what: String) -> Result<Direction> {
    if !theta.is_finite() || !phi.is_finite() {
        return Err(c.error(format!("{what} has a non-finite angle (θ = {theta}, φ = {phi} rad)")));
    }
    let round = |deg: f64| ((deg * 1e4).round() / 1e4) as f32;
    let theta_deg = (theta as f64).to_degrees();
    // A θ a hair above 90° is float noise at the horizon.
    let theta_deg = if theta_deg > 90.0 && theta_deg < 90.001 { 90.0 } else { theta_deg };
    let phi_deg = (phi as f64).to_degrees().rem_euclid(360.0);
    Direction::new(round(theta_deg), round(phi_deg)).map_err(|e| c.error(format!("{what}: {e}")))
}

/// Reads the image size; both sides must be positive.
pub fn read_size(c: &mut Cursor) -> Result<(usize, usize)> {
    c.section("image size");
    let width = c.u32("the width")?;
    let height = c.u32("the height")?;
    if width == 0 || height == 0 {
        return Err(c.error(format!("{width}x{height} pixels: both sides must be positive")));
    }
    Ok((width as usize, height as usize))
}

/// A 3×3 frame rotation, row-major.
pub type Rotation = [[f32; 3]; 3];

/// Reads the rotation block: a u32 count and that many 3×3 f32 matrices.
pub fn read_rotations(c: &mut Cursor) -> Result<Vec<Rotation>> {
    c.section("rotation block");
    let count = c.u32("the rotation count")? as u64;
    c.need(count, 36, &format!("{count} rotation matrices"))?;
    (0..count)
        .map(|i| {
            let m = c.f32s::<9>("a rotation matrix")?;
            if m.iter().any(|v| !v.is_finite()) {
                return Err(c.error(format!("rotation {i} has a non-finite entry")));
            }
            Ok([[m[0], m[1], m[2]], [m[3], m[4], m[5]], [m[6], m[7], m[8]]])
        })
        .collect()
}
