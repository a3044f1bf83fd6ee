//! Reading a textured glTF model back: the geometry, the first texture coordinates and the
//! base colour texture of its first primitive, as [`super::export`] writes them (and as other
//! tools write simple models), so that `eval` can judge the texture a user imports.
//!
//! Only what that needs is read: `.glb` with its images in the binary chunk, or `.gltf` with
//! its buffer and images as files beside it; float positions and texture coordinates;
//! 8-, 16- or 32-bit indices (or none). Anything else is one clear error.

use crate::eval::Picture;
use crate::{Error, Result};
use glam::{Vec2, Vec3};
use serde_json::Value;
use std::path::{Path, PathBuf};

/// A textured model's first primitive.
#[derive(Clone, Debug)]
pub struct Model {
    /// Vertex positions.
    pub positions: Vec<Vec3>,
    /// Triangles, as indices into `positions`.
    pub triangles: Vec<[u32; 3]>,
    /// Per vertex, `TEXCOORD_0` (glTF convention: v down, [0, 1]² spans the texture).
    pub uv: Vec<Vec2>,
    /// The material's base colour texture (sRGB-encoded values, as stored).
    pub base_colour: Picture,
    /// True if the texture repeats beyond [0, 1] (glTF `REPEAT`), else it is clamped.
    pub repeat: bool,
    /// The material's `extras` (btfsynth records its provenance there), `Null` if none.
    pub extras: Value,
}

/// Reads the model at `path` (`.glb` or `.gltf`).
pub fn read_model(path: &Path) -> Result<Model> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    model_from_bytes(&bytes, path)
}

/// A model from the bytes of a `.glb` or `.gltf` (whose files lie beside `path`, the name
/// errors give).
pub fn model_from_bytes(bytes: &[u8], path: &Path) -> Result<Model> {
    let bad = |m: &str| Error::format(path, m.to_string());
    let (json, bin): (Value, Option<Vec<u8>>) = if bytes.starts_with(b"glTF") {
        let (json, bin) = glb_chunks(bytes).ok_or_else(|| bad("a truncated or malformed .glb"))?;
        (
            serde_json::from_slice(json).map_err(|e| bad(&format!("its JSON chunk: {e}")))?,
            bin.map(<[u8]>::to_vec),
        )
    } else {
        (serde_json::from_slice(bytes).map_err(|e| bad(&format!("not glTF JSON: {e}")))?, None)
    };
    let dir = path.parent().unwrap_or(Path::new("")).to_path_buf();
    let doc = Doc { json: &json, bin, dir, path };
    let primitive = &json["meshes"][0]["primitives"][0];
    if !primitive.is_object() {
        return Err(bad("no mesh primitive"));
    }
    let positions = doc.floats::<3>(&primitive["attributes"]["POSITION"])?;
    let uv = doc.floats::<2>(&primitive["attributes"]["TEXCOORD_0"])?;
    if uv.len() != positions.len() {
        return Err(bad("TEXCOORD_0 and POSITION differ in length"));
    }
    let indices = match &primitive["indices"] {
        Value::Null => (0..positions.len() as u32).collect(),
        accessor => doc.indices(accessor)?,
    };
    if indices.len() % 3 != 0 || indices.iter().any(|&i| i as usize >= positions.len()) {
        return Err(bad("its indices are not triangles of its vertices"));
    }
    let material = &json["materials"][primitive["material"].as_u64().unwrap_or(0) as usize];
    let texture = &json["textures"][material["pbrMetallicRoughness"]["baseColorTexture"]["index"]
        .as_u64()
        .ok_or_else(|| bad("its material has no base colour texture"))?
        as usize];
    let image = doc.image(&json["images"][texture["source"].as_u64().unwrap_or(u64::MAX) as usize])?;
    let sampler = &json["samplers"][texture["sampler"].as_u64().unwrap_or(u64::MAX) as usize];
    // glTF's default wrap is REPEAT (10497).
    let repeat = sampler["wrapS"].as_u64().unwrap_or(10497) == 10497;
    Ok(Model {
        positions: positions.into_iter().map(Vec3::from_array).collect(),
        triangles: indices.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect(),
        uv: uv.into_iter().map(Vec2::from_array).collect(),
        base_colour: image,
        repeat,
        extras: material["extras"].clone(),
    })
}

/// The JSON and binary chunks of a `.glb`.
fn glb_chunks(bytes: &[u8]) -> Option<(&[u8], Option<&[u8]>)> {
    let word = |at: usize| Some(u32::from_le_bytes(bytes.get(at..at + 4)?.try_into().ok()?) as usize);
    let json_len = word(12)?;
    if bytes.get(16..20)? != b"JSON" {
        return None;
    }
    let json = bytes.get(20..20 + json_len)?;
    let at = 20 + json_len;
    let bin = match word(at) {
        Some(len) if bytes.get(at + 4..at + 8)? == b"BIN\0" => Some(bytes.get(at + 8..at + 8 + len)?),
        _ => None,
    };
    Some((json, bin))
}

/// A document being read: its JSON, its binary chunk (a `.glb`) and where its files are.
struct Doc<'a> {
    json: &'a Value,
    bin: Option<Vec<u8>>,
    dir: PathBuf,
    path: &'a Path,
}

impl Doc<'_> {
    fn bad(&self, m: impl Into<String>) -> Error {
        Error::format(self.path, m.into())
    }

    /// The bytes of buffer view `view`.
    fn view(&self, view: &Value) -> Result<Vec<u8>> {
        let buffer = view["buffer"].as_u64().unwrap_or(0) as usize;
        let data = match (&self.bin, self.json["buffers"][buffer]["uri"].as_str()) {
            (Some(bin), None) => bin.clone(),
            (_, Some(uri)) if !uri.starts_with("data:") => {
                let file = self.dir.join(uri_unescape(uri));
                std::fs::read(&file).map_err(|e| Error::io(&file, e))?
            }
            _ => return Err(self.bad("a buffer that is neither the .glb's own nor a file beside it")),
        };
        let offset = view["byteOffset"].as_u64().unwrap_or(0) as usize;
        let length = view["byteLength"].as_u64().unwrap_or(0) as usize;
        data.get(offset..offset + length)
            .map(<[u8]>::to_vec)
            .ok_or_else(|| self.bad("a buffer view past its buffer"))
    }

    /// The accessor `index` (a JSON number): its data, element count and stride in bytes.
    fn accessor(
        &self,
        index: &Value,
        component: u64,
        width: usize,
    ) -> Result<(Vec<u8>, usize, usize, usize)> {
        let accessor =
            &self.json["accessors"][index.as_u64().ok_or_else(|| self.bad("a missing accessor"))? as usize];
        let kind = accessor["componentType"].as_u64().unwrap_or(0);
        if component != 0 && kind != component {
            return Err(
                self.bad(format!("an accessor of component type {kind} where {component} was expected"))
            );
        }
        let view = &self.json["bufferViews"][accessor["bufferView"].as_u64().unwrap_or(u64::MAX) as usize];
        if !view.is_object() {
            return Err(self.bad("an accessor without a buffer view"));
        }
        let data = self.view(view)?;
        let count = accessor["count"].as_u64().unwrap_or(0) as usize;
        let size = match kind {
            5121 => 1,
            5123 => 2,
            _ => 4,
        };
        let stride = view["byteStride"].as_u64().map_or(size * width, |s| s as usize);
        let offset = accessor["byteOffset"].as_u64().unwrap_or(0) as usize;
        if count > 0 && offset + (count - 1) * stride + size * width > data.len() {
            return Err(self.bad("an accessor past its buffer view"));
        }
        Ok((data, count, stride, offset))
    }

    fn floats<const N: usize>(&self, index: &Value) -> Result<Vec<[f32; N]>> {
        let (data, count, stride, offset) = self.accessor(index, 5126, N)?;
        Ok((0..count)
            .map(|i| {
                std::array::from_fn(|k| {
                    let at = offset + i * stride + 4 * k;
                    f32::from_le_bytes([data[at], data[at + 1], data[at + 2], data[at + 3]])
                })
            })
            .collect())
    }

    fn indices(&self, index: &Value) -> Result<Vec<u32>> {
        let kind = self.json["accessors"][index.as_u64().unwrap_or(u64::MAX) as usize]["componentType"]
            .as_u64()
            .unwrap_or(0);
        let (data, count, stride, offset) = self.accessor(index, 0, 1)?;
        let read = |at: usize| match kind {
            5121 => Some(u32::from(data[at])),
            5123 => Some(u32::from(u16::from_le_bytes([data[at], data[at + 1]]))),
            5125 => Some(u32::from_le_bytes([data[at], data[at + 1], data[at + 2], data[at + 3]])),
            _ => None,
        };
        (0..count)
            .map(|i| {
                read(offset + i * stride).ok_or_else(|| self.bad(format!("indices of component type {kind}")))
            })
            .collect()
    }

    fn image(&self, image: &Value) -> Result<Picture> {
        let bytes = match (image["bufferView"].as_u64(), image["uri"].as_str()) {
            (Some(view), _) => self.view(&self.json["bufferViews"][view as usize])?,
            (None, Some(uri)) if !uri.starts_with("data:") => {
                let file = self.dir.join(uri_unescape(uri));
                std::fs::read(&file).map_err(|e| Error::io(&file, e))?
            }
            _ => return Err(self.bad("its base colour image is neither in the .glb nor a file beside it")),
        };
        let rgb = image::load_from_memory(&bytes)
            .map_err(|e| self.bad(format!("its base colour image: {e}")))?
            .to_rgb32f();
        let (width, height) = (rgb.width() as usize, rgb.height() as usize);
        Ok(Picture { width, height, rgb: rgb.pixels().map(|p| p.0).collect() })
    }
}

/// A relative URI's `%XX` escapes decoded (what [`super::gltf`] writes for file names).
fn uri_unescape(uri: &str) -> String {
    let bytes = uri.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        let hex = (bytes[i] == b'%')
            .then(|| std::str::from_utf8(bytes.get(i + 1..i + 3)?).ok())
            .flatten()
            .and_then(|h| u8::from_str_radix(h, 16).ok());
        match hex {
            Some(b) => {
                out.push(b);
                i += 3;
            }
            None => {
                out.push(bytes[i]);
                i += 1;
            }
        }
    }
    String::from_utf8_lossy(&out).into_owned()
}
