//! Export: a synthesized surface on the user's own mesh, as glTF 2.0 with baked textures,
//! for the tools people use (Blender, game engines, the Khronos validator).
//!
//! 1. The surface map's original mesh (its header's `mesh`, or `mesh_absolute`) is read
//!    exactly as its file gives it ([`crate::mesh::textured`]).
//! 2. Its texture layout is its own UVs if it has them, else a generated atlas
//!    ([`layout`]).
//! 3. Every atlas texel near a triangle is mapped to its surface point ([`raster`]), the
//!    nearest point of the synthesized surface gives a sample coordinate, and the BTF and the
//!    material maps are looked up there ([`bake`](mod@bake)); gutters copy the nearest baked texel.
//! 4. The textures are encoded ([`textures`]) and written with the mesh as `.glb` or
//!    `.gltf` + files ([`gltf`]), all or nothing.
//!
//! With [`ExportOptions::vertex_colours`], the dense synthesized mesh is written instead,
//! with one colour per vertex and no textures.

pub mod bake;
pub mod gltf;
pub mod layout;
pub mod raster;
pub mod read;
pub mod textures;
mod uvmap;

use crate::btf::Direction;
use crate::fsutil::{check_not_input, check_target, commit_all, Staged};
use crate::maps::{stored::open_maps, MapKind, MaterialMap};
use crate::mesh::bvh::TriangleBvh;
use crate::mesh::textured::{load_textured, TexturedMesh};
use crate::progress::Progress;
use crate::render::scene::open_surface;
use crate::render::{Blend16, Material, Scene};
use crate::{Error, Param, Remedy, Result};
use bake::{bake, bake_blend, vertex_colours, Baked, MapLookup, Source, Target};
use glam::Vec3;
use gltf::Document;
use layout::{vertex_normals, vertex_tangents, AtlasMesh, AtlasOptions};
use serde_json::{json, Map, Value};
use std::path::{Path, PathBuf};
use std::time::Instant;
pub use textures::CoordinateFormat;

/// Smallest and largest atlas side, in texels.
pub const SIZE_RANGE: std::ops::RangeInclusive<u32> = 16..=8192;

/// Which texture layout to bake into.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum UvChoice {
    /// The mesh's own UVs if it has them, else a generated atlas.
    #[default]
    Auto,
    /// The mesh's own UVs; a mesh without UVs is an error.
    Keep,
    /// A generated atlas, even if the mesh has UVs.
    Generate,
}

/// What an export writes and how.
#[derive(Clone, Debug, Default)]
pub struct ExportOptions {
    /// The original mesh (default: the one the surface map's header names).
    pub mesh: Option<PathBuf>,
    /// The analysis directory (default: the one the surface map's header names).
    pub analysis: Option<PathBuf>,
    /// Accept an analysis of another sample than the one the map was synthesized from.
    pub force_analysis: bool,
    /// Atlas width and height in texels (default: about one atlas texel per sample texel on
    /// the surface, rounded up to a power of two).
    pub size: Option<u32>,
    /// Which texture layout to bake into.
    pub uvs: UvChoice,
    /// Empty texels around each chart of a generated atlas (default: size / 256, at least 2).
    pub padding: Option<u32>,
    /// For a BTF stack: the light (in the sample's frame) the colour is baked under, seen
    /// head-on (default: the stack's image nearest head-on view and light).
    pub light: Option<Direction>,
    /// How the sample-coordinate map of a BTF stack is stored.
    pub coordinates: CoordinateFormat,
    /// Write the dense synthesized mesh with per-vertex colours instead of textures.
    pub vertex_colours: bool,
    /// Replace existing outputs.
    pub overwrite: bool,
}

/// What an export did.
#[derive(Clone, Debug, PartialEq)]
pub struct ExportReport {
    /// The files written, the `.glb`/`.gltf` last.
    pub files: Vec<PathBuf>,
    /// Vertices and triangles written.
    pub vertices: usize,
    /// Triangles written.
    pub triangles: usize,
    /// The atlas, unless vertex colours were written.
    pub atlas: Option<AtlasReport>,
    /// Seconds spent: reading, laying out, baking, encoding and writing.
    pub seconds: [f64; 4],
}

/// The atlas an export baked.
#[derive(Clone, Debug, PartialEq)]
pub struct AtlasReport {
    /// Width and height in texels.
    pub size: u32,
    /// True if generated (else the mesh's own UVs).
    pub generated: bool,
    /// Number of charts (UV islands).
    pub charts: usize,
    /// Texels baked from a triangle (the rest are gutter fill).
    pub baked_texels: usize,
    /// The material maps baked besides the colour.
    pub maps: Vec<MapKind>,
}

/// Exports the surface map at `surface` to `output` (`.glb`, or `.gltf` with files beside it):
/// the disk adapter of [`bake_export`], which reads the map, its analysis (sample and
/// material maps) and the original mesh, and writes the document all or nothing.
pub fn export(
    surface: &Path,
    output: &Path,
    options: &ExportOptions,
    progress: &dyn Progress,
) -> Result<ExportReport> {
    let started = Instant::now();
    let binary = is_binary_output(output)?;
    if let Some(size) = options.size.filter(|s| !SIZE_RANGE.contains(s)) {
        return Err(Error::out_of_range(
            Param::AtlasSize,
            size,
            format!("the atlas side must be between {} and {} texels", SIZE_RANGE.start(), SIZE_RANGE.end()),
        ));
    }
    for file in output_files(output, binary) {
        check_target(&file, options.overwrite)?;
    }
    if !options.vertex_colours && crate::synth::patches::output::uv_map_comments(surface).is_some() {
        return uvmap::export_uv_map(surface, output, binary, options);
    }
    let (scene, analysis_dir) = open_surface(surface, options.analysis.as_deref(), !options.force_analysis)?;
    // The analysis the map names is an input too: nothing may be written into it.
    for file in output_files(output, binary) {
        check_not_input("-o", &file, &[surface, &analysis_dir])?;
    }
    let material = Material::open(&analysis_dir)?;
    let (mesh, mesh_path, maps) = if options.vertex_colours {
        (None, PathBuf::new(), Vec::new())
    } else {
        let mesh_path = original_mesh(surface, options.mesh.as_deref())?;
        (Some(load_textured(&mesh_path)?), mesh_path, open_maps(&analysis_dir)?)
    };
    let read_seconds = started.elapsed().as_secs_f64();
    let names = SourceNames { surface, analysis: &analysis_dir, mesh: &mesh_path };
    let source = ExportSource { scene: &scene, material: &material, maps: &maps, mesh: mesh.as_ref(), names };
    let mut exported = bake_export(&stem(output), &source, options, progress)?;
    exported.seconds[0] += read_seconds;
    let started = Instant::now();
    let (vertices, triangles) = exported.document.counts();
    let files = write_document(exported.document, output, binary, options.overwrite)?;
    exported.seconds[3] += started.elapsed().as_secs_f64();
    Ok(ExportReport { files, vertices, triangles, atlas: exported.atlas, seconds: exported.seconds })
}

/// A synthesized surface to export, all in memory: what [`export`] reads from a surface map,
/// its analysis and the original mesh, for a caller that holds them already.
pub struct ExportSource<'a> {
    /// The synthesized surface ([`Scene::from_surface_map`]).
    pub scene: &'a Scene,
    /// The sample it was synthesized from ([`Material::from_btf`], [`Material::open`]).
    pub material: &'a Material,
    /// Material maps baked beside the colour ([`ExportOptions::vertex_colours`] bakes none).
    pub maps: &'a [MaterialMap],
    /// The user's own mesh exactly as its file gives it: the geometry and (with its UVs)
    /// the layout of a textured export. A vertex-colour export needs none.
    pub mesh: Option<&'a TexturedMesh>,
    /// What the provenance and the errors call the inputs; nothing is read from them.
    pub names: SourceNames<'a>,
}

/// The names an [`ExportSource`]'s parts go by: the files [`export`] read them from, or
/// any label a caller working in memory chooses.
#[derive(Clone, Copy, Debug)]
pub struct SourceNames<'a> {
    /// The surface map.
    pub surface: &'a Path,
    /// The analysis of its sample.
    pub analysis: &'a Path,
    /// The original mesh.
    pub mesh: &'a Path,
}

/// What [`bake_export`] made: a glTF document ([`Document::to_glb`] gives its bytes).
pub struct Exported {
    /// The mesh, its textures and material.
    pub document: Document,
    /// The atlas, unless vertex colours were baked.
    pub atlas: Option<AtlasReport>,
    /// Seconds spent: preparing, laying out, baking and encoding (the last slot also takes
    /// [`export`]'s writing).
    pub seconds: [f64; 4],
}

/// Bakes `source` into a glTF document named `name`, in memory: the user's mesh with
/// textures in its own or a generated layout, or with [`ExportOptions::vertex_colours`] the
/// dense synthesized mesh with a colour per vertex. The options' file fields (`mesh`,
/// `analysis`, `overwrite`) are [`export`]'s and are not read here.
pub fn bake_export(
    name: &str,
    source: &ExportSource<'_>,
    options: &ExportOptions,
    progress: &dyn Progress,
) -> Result<Exported> {
    let started = Instant::now();
    let material = source.material;
    let light = options.light.filter(|_| material.len() > 1);
    if options.light.is_some() && light.is_none() {
        tracing::warn!(
            "{}: a one-image BTF has one light; the light direction is ignored",
            source.names.analysis.display()
        );
    }
    let look = Look { scene: source.scene, material, blend: bake_blend(material, light), light };
    let provenance = look.provenance(source.names.surface, source.names.analysis);
    let mut seconds = [started.elapsed().as_secs_f64(), 0.0, 0.0, 0.0];
    if options.vertex_colours {
        let started = Instant::now();
        let colours = vertex_colours(source.scene, material, &look.blend);
        seconds[2] = started.elapsed().as_secs_f64();
        let document = vertex_colour_document(name, source.scene, &colours, provenance);
        return Ok(Exported { document, atlas: None, seconds });
    }
    let Some(mesh) = source.mesh else {
        return Err(Error::invalid("a textured export needs the original mesh (or vertex colours)"));
    };
    let maps =
        source.maps.iter().map(|m| MapLookup::new(m, material.tileable)).collect::<Result<Vec<_>>>()?;
    seconds[0] = started.elapsed().as_secs_f64();
    let job = TexturedJob {
        name,
        mesh,
        mesh_path: source.names.mesh,
        look: &look,
        maps: &maps,
        options,
        direct: false,
    };
    let (document, atlas) = job.run(provenance, &mut seconds, progress)?;
    Ok(Exported { document, atlas: Some(atlas), seconds })
}

/// What the colour shows: the synthesized surface, its BTF and the image baked.
struct Look<'a> {
    scene: &'a Scene,
    material: &'a Material,
    blend: Blend16,
    /// The light asked for, if any (else the blend is the most frontal image).
    light: Option<Direction>,
}

impl Look<'_> {
    /// `extras.btfsynth` of the material: where the result came from and what it shows.
    fn provenance(&self, surface: &Path, analysis: &Path) -> Value {
        let (light, view) = match self.light {
            Some(light) => ([light.theta, light.phi], [0.0, 0.0]),
            None => {
                let pair = self.material.pairs()[self.blend.image[0] as usize];
                ([pair.light.theta, pair.light.phi], [pair.view.theta, pair.view.phi])
            }
        };
        json!({
            "surface": surface.display().to_string(),
            "analysis": analysis.display().to_string(),
            "colour": {"light": light, "view": view, "note": "angles θ, φ in degrees in the sample's frame"},
            "sampleTexel": self.scene.texel,
        })
    }
}

/// One export into the user's mesh with baked textures.
struct TexturedJob<'a> {
    name: &'a str,
    mesh: &'a TexturedMesh,
    mesh_path: &'a Path,
    look: &'a Look<'a>,
    maps: &'a [MapLookup],
    options: &'a ExportOptions,
    /// The texture coordinates index the sample itself (a texture-mapped result): no
    /// sample-coordinate map is written.
    direct: bool,
}

impl TexturedJob<'_> {
    fn run(
        &self,
        mut extras: Value,
        seconds: &mut [f64; 4],
        progress: &dyn Progress,
    ) -> Result<(Document, AtlasReport)> {
        let started = Instant::now();
        let (atlas, size) = self.layout(progress)?;
        let normals = vertex_normals(self.mesh, &atlas);
        let needs_tangents = self.maps.iter().any(|m| m.kind == MapKind::Normal);
        let tangents = if needs_tangents { vertex_tangents(self.mesh, &atlas, &normals) } else { Vec::new() };
        let coverage = raster::rasterize(&atlas.uv, &atlas.triangles, (size as usize, size as usize));
        seconds[1] = started.elapsed().as_secs_f64();
        let started = Instant::now();
        let bvh = TriangleBvh::new(&self.look.scene.mesh);
        let target = Target { mesh: self.mesh, atlas: &atlas, normals: &normals, tangents: &tangents };
        let source = Source {
            scene: self.look.scene,
            bvh: &bvh,
            material: self.look.material,
            blend: self.look.blend,
            maps: self.maps,
        };
        let baked = bake(&target, &source, &coverage, progress)?;
        seconds[2] = started.elapsed().as_secs_f64();
        let started = Instant::now();
        let mut document = Document::new(self.name);
        let positions: Vec<[f32; 3]> =
            atlas.source_vertex.iter().map(|&v| self.mesh.positions[v as usize].to_array()).collect();
        let mut attributes = Map::new();
        attributes.insert("POSITION".into(), document.attribute(&positions).into());
        attributes.insert("NORMAL".into(), document.attribute(&to_arrays(&normals)).into());
        attributes.insert("TEXCOORD_0".into(), document.attribute(&to_arrays(&atlas.uv)).into());
        if needs_tangents {
            attributes.insert("TANGENT".into(), document.attribute(&to_arrays(&tangents)).into());
        }
        let indices = document.indices(&atlas.triangles);
        document.primitive(attributes, indices);
        let material = self.material_textures(&mut document, &baked, &mut extras)?;
        document.material(material);
        seconds[3] = started.elapsed().as_secs_f64();
        let charts = atlas.chart.iter().collect::<std::collections::HashSet<_>>().len();
        let report = AtlasReport {
            size,
            generated: atlas.generated,
            charts,
            baked_texels: coverage.baked(),
            maps: self.maps.iter().map(|m| m.kind).collect(),
        };
        Ok((document, report))
    }

    /// The texture layout and its size, following [`ExportOptions::uvs`].
    fn layout(&self, progress: &dyn Progress) -> Result<(AtlasMesh, u32)> {
        let texel = self.look.scene.texel;
        let surface_area = surface_area(self.mesh);
        match (&self.mesh.uvs, self.options.uvs) {
            (None, UvChoice::Keep) => Err(Error::unavailable(
                format!("{}: the mesh has no texture coordinates to keep", self.mesh_path.display()),
                Remedy::GenerateAtlas,
            )),
            (Some(uvs), UvChoice::Auto | UvChoice::Keep) => {
                let atlas = AtlasMesh::from_file_uvs(self.mesh, uvs);
                let size =
                    self.options.size.unwrap_or_else(|| default_size(surface_area, texel, atlas.uv_area()));
                Ok((atlas, size))
            }
            _ => {
                // A generated atlas covers about half of its square.
                let size = self.options.size.unwrap_or_else(|| default_size(surface_area, texel, 0.5));
                let padding = self.options.padding.unwrap_or((size / 256).max(2));
                let atlas = AtlasMesh::generate(self.mesh, AtlasOptions { size, padding }, progress)?;
                Ok((atlas, size))
            }
        }
    }

    /// Encodes the baked textures into `document` and returns the material using them.
    fn material_textures(&self, document: &mut Document, baked: &Baked, extras: &mut Value) -> Result<Value> {
        let (w, h) = (baked.width, baked.height);
        let map = |kind: MapKind| self.maps.iter().position(|m| m.kind == kind);
        let wide = |kinds: &[MapKind]| {
            self.maps.iter().any(|m| kinds.contains(&m.kind) && m.depth != crate::maps::Depth::U8)
        };
        let colour = document.image(textures::base_colour_image(w, h, &baked.colour)?);
        let mut pbr = json!({"baseColorTexture": {"index": document.texture(colour)}, "metallicFactor": 0.0, "roughnessFactor": 1.0});
        let mut material = json!({"name": self.name});
        if let Some(k) = map(MapKind::Normal) {
            let encoded: Vec<Vec3> = baked.maps[k].iter().map(|n| (*n + 1.0) * 0.5).collect();
            let image =
                document.image(textures::linear_image("normal", w, h, &encoded, wide(&[MapKind::Normal]))?);
            material["normalTexture"] = json!({"index": document.texture(image)});
        }
        let (occlusion, roughness, metallic) =
            (map(MapKind::Occlusion), map(MapKind::Roughness), map(MapKind::Metallic));
        if occlusion.is_some() || roughness.is_some() || metallic.is_some() {
            // One texture for both slots: R occlusion, G roughness, B metalness.
            let channel =
                |k: Option<usize>, i: usize, missing: f32| k.map_or(missing, |k| baked.maps[k][i].x);
            let orm: Vec<Vec3> = (0..w * h)
                .map(|i| {
                    Vec3::new(
                        channel(occlusion, i, 1.0),
                        channel(roughness, i, 1.0),
                        channel(metallic, i, 0.0),
                    )
                })
                .collect();
            let kinds = [MapKind::Occlusion, MapKind::Roughness, MapKind::Metallic];
            let image = document.image(textures::linear_image(
                "occlusionRoughnessMetallic",
                w,
                h,
                &orm,
                wide(&kinds),
            )?);
            let texture = document.texture(image);
            pbr["metallicRoughnessTexture"] = json!({"index": texture});
            pbr["metallicFactor"] = 1.0.into();
            if occlusion.is_some() {
                material["occlusionTexture"] = json!({"index": texture});
            }
        }
        if let Some(k) = map(MapKind::Height) {
            let (image, lo, hi) = textures::height_image(w, h, &baked.maps[k])?;
            let image = document.image(image);
            extras["height"] = json!({"image": image, "min": lo, "max": hi,
                "encoding": "16-bit grey PNG: height = min + value / 65535 * (max - min)"});
        }
        if self.look.material.len() > 1 && !self.direct {
            let sample = (self.look.material.width(), self.look.material.height());
            let format = self.options.coordinates;
            let image =
                textures::coordinate_image(format, (w, h), &baked.coordinate, &baked.covered, sample)?;
            extras["sampleCoordinates"] = json!({
                "sampleWidth": sample.0, "sampleHeight": sample.1,
                "tileable": self.look.material.tileable,
                "encoding": match format {
                    CoordinateFormat::Png => "16-bit RGB PNG: u = R / 65535 * sampleWidth - 0.5, v = G / 65535 * sampleHeight - 0.5 (sample texels, centres at integers, v down rows); B = 1 where baked from a triangle, 0 in gutters",
                    CoordinateFormat::Exr => "float RGB EXR: R = u, G = v (sample texels, centres at integers, v down rows); B = 1 where baked from a triangle, 0 in gutters",
                },
            });
            match format {
                // A PNG is a glTF image; an EXR is not, so it is attached by buffer view or URI.
                CoordinateFormat::Png => extras["sampleCoordinates"]["image"] = document.image(image).into(),
                CoordinateFormat::Exr => {
                    document.attachment(image, &["extras", "btfsynth", "sampleCoordinates"]);
                }
            }
        }
        material["pbrMetallicRoughness"] = pbr;
        material["extras"] = json!({"btfsynth": extras});
        Ok(material)
    }
}

/// The dense synthesized mesh with one linear colour per vertex.
fn vertex_colour_document(name: &str, scene: &Scene, colours: &[Vec3], provenance: Value) -> Document {
    let mut document = Document::new(name);
    let mut attributes = Map::new();
    let positions: Vec<[f32; 3]> = scene.mesh.positions().iter().map(|p| p.to_array()).collect();
    attributes.insert("POSITION".into(), document.attribute(&positions).into());
    attributes.insert("NORMAL".into(), document.attribute(&to_arrays(scene.normals())).into());
    let colours: Vec<[f32; 3]> = colours.iter().map(|c| c.clamp(Vec3::ZERO, Vec3::ONE).to_array()).collect();
    attributes.insert("COLOR_0".into(), document.attribute(&colours).into());
    let indices = document.indices(scene.mesh.triangles());
    document.primitive(attributes, indices);
    document.material(json!({
        "name": name,
        "pbrMetallicRoughness": {"metallicFactor": 0.0, "roughnessFactor": 1.0},
        "extras": {"btfsynth": provenance},
    }));
    document
}

/// Vectors as arrays, for [`Document::attribute`].
fn to_arrays<V: Copy + Into<A>, A>(items: &[V]) -> Vec<A> {
    items.iter().map(|&v| v.into()).collect()
}

/// Total area of a mesh's triangles.
fn surface_area(mesh: &TexturedMesh) -> f64 {
    mesh.triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|i| mesh.positions[i as usize]);
            0.5 * f64::from((b - a).cross(c - a).length())
        })
        .sum()
}

/// The atlas side that gives about one atlas texel per sample texel (`texel` model units)
/// when the layout covers `uv_area` of the atlas, rounded up to a power of two.
fn default_size(surface_area: f64, texel: f32, uv_area: f64) -> u32 {
    let side = (surface_area / (f64::from(texel).powi(2) * uv_area.max(1e-6))).sqrt();
    let side = if side.is_finite() { side.ceil() as u64 } else { u64::from(*SIZE_RANGE.end()) };
    side.next_power_of_two().clamp(u64::from(*SIZE_RANGE.start()), u64::from(*SIZE_RANGE.end())) as u32
}

/// `.glb` (true) or `.gltf` (false), else an error.
fn is_binary_output(output: &Path) -> Result<bool> {
    match output.extension().map(|e| e.to_string_lossy().to_ascii_lowercase()).as_deref() {
        Some("glb") => Ok(true),
        Some("gltf") => Ok(false),
        _ => Err(Error::output_refused(
            output,
            format!("{}: the output must be a .glb or .gltf file", output.display()),
        )),
    }
}

/// The file name of `output` without its extension.
fn stem(output: &Path) -> String {
    output.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_else(|| "btfsynth".into())
}

/// Every file an export to `output` may write (a `.gltf` has companions; not all are
/// written every time, but any of them would be replaced).
fn output_files(output: &Path, binary: bool) -> Vec<PathBuf> {
    if binary {
        return vec![output.to_path_buf()];
    }
    let dir = output.parent().unwrap_or(Path::new(""));
    Document::new("").to_gltf_files(&stem(output)).into_iter().map(|(name, _)| dir.join(name)).collect()
}

/// Writes the document; a `.gltf` and its companion files are staged and moved into place
/// together, so a failed or interrupted export replaces none of them.
fn write_document(document: Document, output: &Path, binary: bool, overwrite: bool) -> Result<Vec<PathBuf>> {
    let files = if binary {
        vec![(output.to_path_buf(), document.to_glb())]
    } else {
        let dir = output.parent().unwrap_or(Path::new(""));
        document
            .to_gltf_files(&stem(output))
            .into_iter()
            .map(|(name, bytes)| (dir.join(name), bytes))
            .collect()
    };
    let staged = files.iter().map(|(path, _)| Staged::file(path, overwrite)).collect::<Result<Vec<_>>>()?;
    for (staged, (_, bytes)) in staged.iter().zip(&files) {
        std::fs::write(staged.path(), bytes).map_err(|e| Error::io(staged.target(), e))?;
    }
    commit_all(staged)
}

/// The original mesh of the surface map at `surface`: `given` if any, else the header's
/// `mesh` as written (relative to the working directory), then relative to the surface
/// map, then the header's `mesh_absolute`.
pub fn original_mesh(surface: &Path, given: Option<&Path>) -> Result<PathBuf> {
    if let Some(path) = given {
        return if path.is_file() {
            Ok(path.to_path_buf())
        } else {
            Err(Error::out_of_range(Param::Mesh, path.display(), "no such file"))
        };
    }
    use crate::synth::surface_map::{comment_paths, comment_value, MESH_ABSOLUTE_KEY, MESH_KEY};
    let comments = surface_comments(surface)?;
    let field = |key: &str| comment_value(&comments, key).map(comment_paths).unwrap_or_default();
    let written = field(MESH_KEY);
    let Some(first) = written.first().cloned() else {
        return Err(Error::unavailable(
            format!("{}: no 'mesh' comment in the header", surface.display()),
            Remedy::GiveMesh,
        ));
    };
    let beside: Vec<PathBuf> =
        written.iter().filter_map(|w| surface.parent().map(|dir| dir.join(w))).collect();
    let candidates = written.into_iter().chain(beside).chain(field(MESH_ABSOLUTE_KEY));
    candidates.into_iter().find(|p| p.is_file()).ok_or_else(|| {
        Error::unavailable(
            format!("{}: its original mesh {} is missing", surface.display(), first.display()),
            Remedy::GiveMesh,
        )
    })
}

/// The `comment` lines of a surface map's PLY header.
fn surface_comments(surface: &Path) -> Result<Vec<String>> {
    use std::io::Read;
    let mut head = Vec::new();
    let file = std::fs::File::open(surface).map_err(|e| Error::io(surface, e))?;
    // The header is a few hundred bytes; its end must lie in the first megabyte.
    file.take(1 << 20).read_to_end(&mut head).map_err(|e| Error::io(surface, e))?;
    let header = crate::mesh::ply::parse_header(&head).map_err(|m| Error::format(surface, m))?;
    Ok(header.comments)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_size_gives_one_texel_per_sample_texel() {
        // 1 unit² at 1/100 unit per texel on half the atlas: √20000 ≈ 141 → 256.
        assert_eq!(default_size(1.0, 0.01, 0.5), 256);
        assert_eq!(default_size(1.0, 0.01, 1.0), 128);
        assert_eq!(default_size(1e9, 1e-6, 0.5), *SIZE_RANGE.end());
        assert_eq!(default_size(1e-9, 1.0, 0.5), *SIZE_RANGE.start());
    }

    #[test]
    fn outputs_are_glb_or_gltf() {
        assert!(is_binary_output(Path::new("a.GLB")).expect("glb"));
        assert!(!is_binary_output(Path::new("a.gltf")).expect("gltf"));
        assert!(is_binary_output(Path::new("a.obj")).is_err());
        let files = output_files(Path::new("out/a.gltf"), false);
        assert_eq!(files, vec![PathBuf::from("out/a.bin"), PathBuf::from("out/a.gltf")]);
    }
}
