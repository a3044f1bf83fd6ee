//! Directions read from Bonn/UTIA file names (`tl015 pl000 tv000 pv000.jpg`), for image
//! folders and zip archives alike.

use crate::btf::{Direction, DirectionPair};
use crate::{Error, Result};
use std::path::Path;

/// Angles named in a Bonn/UTIA file name; the parent folder may supply `tv`/`pv`.
pub(crate) fn pair_from_name(file: &Path) -> Result<DirectionPair> {
    let stem = file.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    let bad = |why: String| {
        Error::format(
            file,
            format!("cannot read directions from the name ({why}); expected tl015_pl000_tv000_pv000.png"),
        )
    };
    let mut angles = parse_tokens(&stem).map_err(bad)?;
    let folder = file.parent().and_then(|p| p.file_name()).map(|s| s.to_string_lossy().into_owned());
    if let Some(Ok(from_folder)) = folder.as_deref().map(parse_tokens) {
        for (slot, value) in [(2, from_folder[2]), (3, from_folder[3])] {
            match (angles[slot], value) {
                (None, v) => angles[slot] = v,
                (Some(a), Some(b)) if a != b => {
                    return Err(bad(format!(
                        "its view angles disagree with its folder {}",
                        folder.unwrap_or_default()
                    )))
                }
                _ => {}
            }
        }
    }
    let get = |i: usize, tag: &str| angles[i].ok_or_else(|| bad(format!("no {tag} angle")));
    let (tl, pl, tv, pv) = (get(0, "tl")?, get(1, "pl")?, get(2, "tv")?, get(3, "pv")?);
    let light = Direction::new(tl, pl).map_err(|e| bad(format!("light: {e}")))?;
    let view = Direction::new(tv, pv).map_err(|e| bad(format!("view: {e}")))?;
    Ok(DirectionPair { light, view })
}

/// Splits `tl015 pl000 tv000 pv000` (spaces or underscores) into its four angles; a token
/// that is not one of them makes the name unparseable.
fn parse_tokens(stem: &str) -> Result<[Option<f32>; 4], String> {
    const TAGS: [&str; 4] = ["tl", "pl", "tv", "pv"];
    let mut angles = [None; 4];
    for token in stem.split([' ', '_']).filter(|t| !t.is_empty()) {
        let lower = token.to_ascii_lowercase();
        let slot = TAGS
            .iter()
            .position(|tag| lower.starts_with(tag))
            .ok_or_else(|| format!("unexpected '{token}'"))?;
        let digits = &lower[2..];
        if digits.is_empty() || !digits.bytes().all(|b| b.is_ascii_digit()) {
            return Err(format!("'{token}' is not a tag followed by integer degrees"));
        }
        if angles[slot].is_some() {
            return Err(format!("{} appears twice", TAGS[slot]));
        }
        angles[slot] = Some(digits.parse::<u32>().map_err(|_| format!("'{token}' is too large"))? as f32);
    }
    Ok(angles)
}
