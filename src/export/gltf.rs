//! A minimal glTF 2.0 writer: one mesh with one primitive and one material, its vertex
//! data in one buffer, and images either inside a binary `.glb` or as files beside a
//! `.gltf` (with the buffer as `<stem>.bin`).

use serde_json::{json, Map, Value};

/// `ARRAY_BUFFER` and `ELEMENT_ARRAY_BUFFER` buffer-view targets.
const ARRAY_BUFFER: u32 = 34962;
const ELEMENT_ARRAY_BUFFER: u32 = 34963;
/// Component types.
const FLOAT: u32 = 5126;
const UNSIGNED_INT: u32 = 5125;

/// An encoded image to store with the document.
#[derive(Clone, Debug, PartialEq)]
pub struct ImageData {
    /// A short name, also the suffix of its file beside a `.gltf` (`<stem>_<name>.<ext>`).
    pub name: String,
    /// Its MIME type (`image/png`, or `image/x-exr` for a float coordinate map).
    pub mime: &'static str,
    /// Its file extension.
    pub extension: &'static str,
    /// The encoded file.
    pub bytes: Vec<u8>,
}

/// A glTF document under construction.
#[derive(Debug, Default)]
pub struct Document {
    bin: Vec<u8>,
    views: Vec<Value>,
    accessors: Vec<Value>,
    images: Vec<ImageData>,
    /// Files that are not glTF images (EXR), each with the path of the object inside the
    /// material that gets its reference.
    attachments: Vec<(ImageData, Vec<String>)>,
    textures: Vec<Value>,
    mesh: Option<Value>,
    material: Value,
    name: String,
    /// Textures repeat beyond [0, 1] (else they are clamped).
    repeat: bool,
}

impl Document {
    /// An empty document whose node is called `name`.
    pub fn new(name: &str) -> Document {
        Document { name: name.to_string(), material: json!({}), ..Document::default() }
    }

    /// Stores `bytes` in the binary buffer (4-byte aligned) and returns its buffer view.
    fn view(&mut self, bytes: &[u8], target: Option<u32>) -> usize {
        while self.bin.len() % 4 != 0 {
            self.bin.push(0);
        }
        let mut view = json!({"buffer": 0, "byteOffset": self.bin.len(), "byteLength": bytes.len()});
        if let Some(target) = target {
            view["target"] = target.into();
        }
        self.bin.extend_from_slice(bytes);
        self.views.push(view);
        self.views.len() - 1
    }

    /// A vertex attribute of `items` (each `N` floats: `VEC2`, `VEC3`, `VEC4`); returns its
    /// accessor. Bounds are recorded (glTF requires them for positions).
    pub fn attribute<const N: usize>(&mut self, items: &[[f32; N]]) -> usize {
        let bytes: Vec<u8> = items.iter().flatten().flat_map(|v| v.to_le_bytes()).collect();
        let view = self.view(&bytes, Some(ARRAY_BUFFER));
        let mut min = [f32::INFINITY; N];
        let mut max = [f32::NEG_INFINITY; N];
        for item in items {
            for k in 0..N {
                min[k] = min[k].min(item[k]);
                max[k] = max[k].max(item[k]);
            }
        }
        self.accessors.push(json!({
            "bufferView": view, "componentType": FLOAT, "count": items.len(),
            "type": format!("VEC{N}"), "min": min.to_vec(), "max": max.to_vec(),
        }));
        self.accessors.len() - 1
    }

    /// Triangle indices; returns their accessor.
    pub fn indices(&mut self, triangles: &[[u32; 3]]) -> usize {
        let bytes: Vec<u8> = triangles.iter().flatten().flat_map(|i| i.to_le_bytes()).collect();
        let view = self.view(&bytes, Some(ELEMENT_ARRAY_BUFFER));
        let count = triangles.len() * 3;
        self.accessors.push(
            json!({"bufferView": view, "componentType": UNSIGNED_INT, "count": count, "type": "SCALAR"}),
        );
        self.accessors.len() - 1
    }

    /// Adds an image; returns its index in `images`.
    pub fn image(&mut self, image: ImageData) -> usize {
        self.images.push(image);
        self.images.len() - 1
    }

    /// Stores a file glTF has no image type for (an EXR) with the document: inside a
    /// `.glb` as a buffer view, beside a `.gltf` as a file. The material's object at `at`
    /// (keys from the material down, e.g. `["extras", "btfsynth", "coordinates"]`) gets
    /// `"bufferView"` and `"mimeType"`, or `"uri"`.
    pub fn attachment(&mut self, data: ImageData, at: &[&str]) {
        self.attachments.push((data, at.iter().map(|k| k.to_string()).collect()));
    }

    /// Makes the document's one sampler repeat textures beyond [0, 1] (a tileable sample
    /// mapped directly) instead of clamping them (an atlas).
    pub fn repeat(&mut self, repeat: bool) {
        self.repeat = repeat;
    }

    /// A texture showing image `image` with the document's one sampler (trilinear, clamped
    /// at the atlas' edges unless [`Document::repeat`]); returns its index in `textures`.
    pub fn texture(&mut self, image: usize) -> usize {
        self.textures.push(json!({"sampler": 0, "source": image}));
        self.textures.len() - 1
    }

    /// The mesh's one primitive: `attributes` (name → accessor) and `indices`.
    pub fn primitive(&mut self, attributes: Map<String, Value>, indices: usize) {
        self.mesh = Some(json!({
            "name": self.name,
            "primitives": [{"attributes": attributes, "indices": indices, "material": 0, "mode": 4}],
        }));
    }

    /// Vertices and triangles of the primitive (0 before [`Document::primitive`]).
    pub fn counts(&self) -> (usize, usize) {
        let count = |accessor: &Value| {
            accessor.as_u64().and_then(|i| self.accessors.get(i as usize)).and_then(|a| a["count"].as_u64())
        };
        let primitive = self.mesh.as_ref().map(|m| &m["primitives"][0]);
        let vertices = primitive.and_then(|p| count(&p["attributes"]["POSITION"])).unwrap_or(0);
        let indices = primitive.and_then(|p| count(&p["indices"])).unwrap_or(0);
        (vertices as usize, indices as usize / 3)
    }

    /// The one material (a glTF material object).
    pub fn material(&mut self, material: Value) {
        self.material = material;
    }

    /// The document as one binary `.glb`.
    pub fn to_glb(mut self) -> Vec<u8> {
        let images = std::mem::take(&mut self.images);
        let image_json: Vec<Value> = images
            .iter()
            .map(|image| {
                let view = self.view(&image.bytes, None);
                json!({"name": image.name, "mimeType": image.mime, "bufferView": view})
            })
            .collect();
        for (data, at) in std::mem::take(&mut self.attachments) {
            let view = self.view(&data.bytes, None);
            let reference = json!({"bufferView": view, "mimeType": data.mime});
            self.refer(&at, reference);
        }
        while self.bin.len() % 4 != 0 {
            self.bin.push(0);
        }
        let buffer = json!({"byteLength": self.bin.len()});
        let mut text = self.json(buffer, image_json).to_string().into_bytes();
        while text.len() % 4 != 0 {
            text.push(b' ');
        }
        let total = 12 + 8 + text.len() + 8 + self.bin.len();
        let mut out = Vec::with_capacity(total);
        out.extend_from_slice(b"glTF");
        out.extend_from_slice(&2u32.to_le_bytes());
        out.extend_from_slice(&(total as u32).to_le_bytes());
        out.extend_from_slice(&(text.len() as u32).to_le_bytes());
        out.extend_from_slice(b"JSON");
        out.extend_from_slice(&text);
        out.extend_from_slice(&(self.bin.len() as u32).to_le_bytes());
        out.extend_from_slice(b"BIN\0");
        out.extend_from_slice(&self.bin);
        out
    }

    /// The document as a `.gltf` and the files beside it, named from `stem`: `(file name,
    /// bytes)`, the `.gltf` itself last.
    pub fn to_gltf_files(mut self, stem: &str) -> Vec<(String, Vec<u8>)> {
        let images = std::mem::take(&mut self.images);
        let mut files = Vec::new();
        let image_json: Vec<Value> = images
            .into_iter()
            .map(|image| {
                let file = format!("{stem}_{}.{}", image.name, image.extension);
                let entry = json!({"name": image.name, "mimeType": image.mime, "uri": uri_escape(&file)});
                files.push((file, image.bytes));
                entry
            })
            .collect();
        for (data, at) in std::mem::take(&mut self.attachments) {
            let file = format!("{stem}_{}.{}", data.name, data.extension);
            self.refer(&at, json!({"uri": uri_escape(&file), "mimeType": data.mime}));
            files.push((file, data.bytes));
        }
        let bin_name = format!("{stem}.bin");
        let buffer = json!({"byteLength": self.bin.len(), "uri": uri_escape(&bin_name)});
        let text = serde_json::to_vec_pretty(&self.json(buffer, image_json)).unwrap_or_default();
        files.push((bin_name, std::mem::take(&mut self.bin)));
        files.push((format!("{stem}.gltf"), text));
        files
    }

    /// Merges `reference` into the material's object at `at`.
    fn refer(&mut self, at: &[String], reference: Value) {
        let target = at.iter().fold(&mut self.material, |node, key| &mut node[key.as_str()]);
        match (target.as_object_mut(), reference) {
            (Some(object), Value::Object(fields)) => object.extend(fields),
            (_, reference) => *target = reference,
        }
    }

    fn json(&self, buffer: Value, images: Vec<Value>) -> Value {
        let mut root = json!({
            "asset": {"version": "2.0", "generator": concat!("btfsynth ", env!("CARGO_PKG_VERSION"))},
            "scene": 0,
            "scenes": [{"nodes": [0]}],
            "nodes": [{"name": self.name, "mesh": 0}],
            "meshes": [self.mesh.clone().unwrap_or(Value::Null)],
            "materials": [self.material],
            "accessors": self.accessors,
            "bufferViews": self.views,
            "buffers": [buffer],
        });
        if !images.is_empty() {
            root["images"] = images.into();
        }
        if !self.textures.is_empty() {
            root["textures"] = self.textures.clone().into();
            // Trilinear filtering, clamped: an atlas does not repeat (a tileable sample does).
            let wrap = if self.repeat { 10497 } else { 33071 };
            root["samplers"] = json!([{"magFilter": 9729, "minFilter": 9987, "wrapS": wrap, "wrapT": wrap}]);
        }
        root
    }
}

/// A relative URI for a file name: unreserved characters as they are, the rest
/// percent-encoded.
fn uri_escape(name: &str) -> String {
    name.bytes()
        .map(|b| match b {
            b'A'..=b'Z' | b'a'..=b'z' | b'0'..=b'9' | b'-' | b'_' | b'.' | b'~' => (b as char).to_string(),
            _ => format!("%{b:02X}"),
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn triangle() -> Document {
        let mut doc = Document::new("t");
        let position = doc.attribute(&[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0f32]]);
        let indices = doc.indices(&[[0, 1, 2]]);
        let mut attributes = Map::new();
        attributes.insert("POSITION".into(), position.into());
        doc.primitive(attributes, indices);
        doc.image(ImageData { name: "x".into(), mime: "image/png", extension: "png", bytes: vec![1, 2, 3] });
        doc.material(json!({"extras": {"a": {"note": "kept"}}}));
        let exr = ImageData { name: "y".into(), mime: "image/x-exr", extension: "exr", bytes: vec![4, 5] };
        doc.attachment(exr, &["extras", "a"]);
        doc
    }

    #[test]
    fn glb_chunks_are_aligned_and_sized() {
        let glb = triangle().to_glb();
        assert_eq!(&glb[..4], b"glTF");
        let word = |o: usize| u32::from_le_bytes([glb[o], glb[o + 1], glb[o + 2], glb[o + 3]]) as usize;
        assert_eq!(word(8), glb.len());
        let json_len = word(12);
        assert_eq!(json_len % 4, 0);
        let json: Value = serde_json::from_slice(&glb[20..20 + json_len]).expect("JSON chunk");
        let bin_len = word(20 + json_len);
        assert_eq!(20 + json_len + 8 + bin_len, glb.len());
        assert_eq!(json["buffers"][0]["byteLength"], bin_len);
        assert_eq!(json["accessors"][0]["max"], json!([1.0, 1.0, 0.0]));
        let view = &json["bufferViews"][json["images"][0]["bufferView"].as_u64().unwrap() as usize];
        let start = 20 + json_len + 8 + view["byteOffset"].as_u64().unwrap() as usize;
        assert_eq!(&glb[start..start + 3], &[1, 2, 3]);
        let a = &json["materials"][0]["extras"]["a"];
        assert_eq!((&a["note"], &a["mimeType"]), (&json!("kept"), &json!("image/x-exr")));
        let view = &json["bufferViews"][a["bufferView"].as_u64().unwrap() as usize];
        let start = 20 + json_len + 8 + view["byteOffset"].as_u64().unwrap() as usize;
        assert_eq!(&glb[start..start + 2], &[4, 5]);
    }

    #[test]
    fn gltf_files_reference_each_other_by_escaped_uri() {
        let files = triangle().to_gltf_files("my model");
        let names: Vec<&str> = files.iter().map(|(n, _)| n.as_str()).collect();
        assert_eq!(names, ["my model_x.png", "my model_y.exr", "my model.bin", "my model.gltf"]);
        let json: Value = serde_json::from_slice(&files[3].1).expect("JSON");
        assert_eq!(json["materials"][0]["extras"]["a"]["uri"], "my%20model_y.exr");
        assert_eq!(json["images"][0]["uri"], "my%20model_x.png");
        assert_eq!(json["buffers"][0]["uri"], "my%20model.bin");
    }
}
