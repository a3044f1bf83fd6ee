//! The bodies of factorized files: DFMF (btflib's `read_ubo_dfmf`) and FMF
//! (`read_ubo_fmf`). Reading a body records where each matrix lies and checks that it fits
//! in the file; the matrices themselves are read later, and only for the crop decoded.

use super::bytes::Cursor;
use super::factors::{ChannelLayout, Matrix, Scalar, Side};
use crate::btf::colour::ColourModel;
use crate::Result;

/// What a factorized body holds.
#[derive(Clone, Debug, PartialEq)]
pub struct FactorBody {
    /// How the channels encode RGB (FMF files are plain RGB).
    pub model: ColourModel,
    /// The data are log(value + ε) ("dynamic range reduction"); decoding takes exp − ε.
    pub log_encoded: bool,
    pub scalar: Scalar,
    /// Per channel.
    pub channels: Vec<ChannelLayout>,
    /// Per channel: the stored singular values.
    pub singular_values: Vec<Vec<f32>>,
    /// An FMF height map's size (rows, columns), if the file carries one.
    pub height_map: Option<(u32, u32)>,
    /// The file's "max components" field (DFMF) or component count (FMF).
    pub max_components: u32,
}

/// The counts a body is checked against.
pub struct Shape {
    pub images: u64,
    pub pixels: u64,
    pub channels: usize,
}

/// Reads a DFMF body: model, mean and transform, then per channel its scalar size,
/// component count, matrix sizes, S, U and SxV.
pub fn read_dfmf(c: &mut Cursor, shape: &Shape) -> Result<FactorBody> {
    c.section("DFMF colour model");
    let max_components = c.u32("the component count")?;
    let model_id = c.i32("the colour model")?;
    let mean = c.f32s::<3>("the colour mean")?;
    let t = c.f32s::<9>("the colour transform")?;
    let transform = [[t[0], t[1], t[2]], [t[3], t[4], t[5]], [t[6], t[7], t[8]]];
    let model = ColourModel::from_id(model_id, mean, transform).map_err(|m| c.error(m))?;
    let mut channels = Vec::with_capacity(shape.channels);
    let mut singular_values = Vec::with_capacity(shape.channels);
    let mut scalar = None;
    for ch in 0..shape.channels {
        c.section(CHANNEL_SECTIONS[ch.min(CHANNEL_SECTIONS.len() - 1)]);
        let size = c.u8("the scalar size")?;
        let s = Scalar::from_size(size)
            .ok_or_else(|| c.error(format!("scalar size {size} is not 2 (half), 4 (float) or 8 (double)")))?;
        scalar.get_or_insert(s);
        let components = c.u32("the component count")? as usize;
        let rows = c.u32("the row count")? as u64;
        let cols = c.u32("the column count")? as u64;
        let (s_values, u, sxv) = read_matrices(c, ch, s, components, rows, cols)?;
        let (image, pixel) = orient(c, shape, u, sxv)?;
        channels.push(ChannelLayout { image: Side::Rows(image), pixel: Side::Rows(pixel), components });
        singular_values.push(s_values);
    }
    Ok(FactorBody {
        model,
        log_encoded: false,
        scalar: scalar.unwrap_or(Scalar::F32),
        channels,
        singular_values,
        height_map: None,
        max_components,
    })
}

/// Section names of the per-channel blocks (files with more channels are refused earlier).
const CHANNEL_SECTIONS: [&str; 3] = ["channel 0 factors", "channel 1 factors", "channel 2 factors"];

/// S, U (rows × components) and SxV (cols × components) of one factorization.
fn read_matrices(
    c: &mut Cursor,
    ch: usize,
    scalar: Scalar,
    components: usize,
    rows: u64,
    cols: u64,
) -> Result<(Vec<f32>, Matrix, Matrix)> {
    if components == 0 {
        return Err(c.error("the component count is 0"));
    }
    c.need(components as u64, scalar.size(), "the singular values")?;
    let s_raw = c.take(components as u64 * scalar.size(), "the singular values")?;
    let mut s_values = vec![0f32; components];
    scalar.decode(&s_raw, &mut s_values);
    let mut matrix = |name: &str, n: u64| -> Result<Matrix> {
        let row_bytes = components as u64 * scalar.size();
        c.need(n, row_bytes, &format!("{name} ({n} × {components})"))?;
        let m = Matrix {
            name: format!("channel {ch} {name}"),
            offset: c.pos(),
            rows: n,
            cols: components,
            scalar,
        };
        c.skip(m.bytes(), name)?;
        Ok(m)
    };
    let u = matrix("U", rows)?;
    let sxv = matrix("SxV", cols)?;
    Ok((s_values, u, sxv))
}

/// Decides which matrix is the image side: U has lights × views rows (the usual layout)
/// or width × height rows (images stacked the other way).
fn orient(c: &Cursor, shape: &Shape, u: Matrix, sxv: Matrix) -> Result<(Matrix, Matrix)> {
    if u.rows == shape.images && sxv.rows == shape.pixels {
        Ok((u, sxv))
    } else if u.rows == shape.pixels && sxv.rows == shape.images {
        Ok((sxv, u))
    } else {
        Err(c.error(format!(
            "a {} × {} matrix pair does not fit {} images of {} pixels (expected (lights × views) × (width × height); the rotation block or an earlier count may be wrong)",
            u.rows, sxv.rows, shape.images, shape.pixels
        )))
    }
}

/// Reads an FMF body: the extended header (FMF12), then one factorization whose rows
/// interleave the channels.
pub fn read_fmf(c: &mut Cursor, shape: &Shape, extended: bool) -> Result<FactorBody> {
    c.section("FMF header");
    let (log_encoded, height_map) = if extended { read_fmf_extension(c)? } else { (false, None) };
    let _components_in_file = c.u32("the component count")?;
    let size = c.u8("the scalar size")?;
    let scalar = Scalar::from_size(size)
        .ok_or_else(|| c.error(format!("scalar size {size} is not 2 (half), 4 (float) or 8 (double)")))?;
    let components = c.u32("the component count")? as usize;
    let rows = c.u32("the row count")? as u64;
    let cols = c.u32("the column count")? as u64;
    c.section("FMF factors");
    let (s_values, u, sxv) = read_matrices(c, 0, scalar, components, rows, cols)?;
    let n = shape.channels as u64;
    let interleave = |matrix: &Matrix, channel: usize| Side::Interleaved {
        matrix: matrix.clone(),
        channels: shape.channels,
        channel,
    };
    let channels: Vec<ChannelLayout> = if u.rows == n * shape.images && sxv.rows == shape.pixels {
        (0..shape.channels)
            .map(|ch| ChannelLayout { image: interleave(&u, ch), pixel: Side::Rows(sxv.clone()), components })
            .collect()
    } else if u.rows == n * shape.pixels && sxv.rows == shape.images {
        (0..shape.channels)
            .map(|ch| ChannelLayout { image: Side::Rows(sxv.clone()), pixel: interleave(&u, ch), components })
            .collect()
    } else {
        return Err(c.error(format!(
            "a {} × {} matrix pair does not fit {} channels × {} images of {} pixels",
            u.rows, sxv.rows, shape.channels, shape.images, shape.pixels
        )));
    };
    Ok(FactorBody {
        model: ColourModel::Rgb,
        log_encoded,
        scalar,
        singular_values: vec![s_values; shape.channels],
        channels,
        height_map,
        max_components: components as u32,
    })
}

/// FMF12's extension: a version byte, then the dynamic-range flag (version ≥ 1) and a
/// half-float height map (version ≥ 2).
fn read_fmf_extension(c: &mut Cursor) -> Result<(bool, Option<(u32, u32)>)> {
    let version = c.u8("the extended header version")?;
    if version >= 3 {
        return Err(c.error(format!("not supported yet: FMF extended header version {version}")));
    }
    let log_encoded = if version >= 1 { c.u32("the dynamic range flag")? != 0 } else { false };
    let mut height_map = None;
    if version >= 2 {
        let rows = c.u32("the height map rows")?;
        let cols = c.u32("the height map columns")?;
        let n = rows as u64 * cols as u64;
        c.need(n, 2, "the height map")?;
        c.skip(n * 2, "the height map")?;
        height_map = (n > 0).then_some((rows, cols));
    }
    Ok((log_encoded, height_map))
}
