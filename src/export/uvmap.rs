//! Export of a texture-mapped result (pattern mapping, [`crate::synth::patches`]): nothing is
//! baked. The mesh is the one in the result (the user's, faces as given), split at texture seams;
//! its texture coordinates are the result's; its textures are the sample itself at full resolution
//! (the image [`ExportOptions::light`] picks, as for baking) and the analysis' material maps
//! sampled at the sample's texels. A tileable sample repeats (glTF `REPEAT`), one that does not is
//! clamped (its coordinates never leave it).

use super::bake::{bake_blend, Baked, MapLookup};
use super::layout::{vertex_normals, vertex_tangents, AtlasMesh};
use super::{to_arrays, write_document, AtlasReport, ExportOptions, ExportReport, Look, TexturedJob};
use crate::maps::{stored::open_maps, MapKind};
use crate::render::scene::open_surface;
use crate::render::Material;
use crate::synth::patches::output::read_uv_map;
use crate::{Error, Result};
use glam::{Vec2, Vec3};
use serde_json::Map;
use std::path::Path;
use std::time::Instant;

/// Exports the texture-mapped result at `surface` to `output` (see the module documentation).
pub(super) fn export_uv_map(
    surface: &Path,
    output: &Path,
    binary: bool,
    options: &ExportOptions,
) -> Result<ExportReport> {
    let started = Instant::now();
    let (scene, analysis_dir) = open_surface(surface, options.analysis.as_deref(), !options.force_analysis)?;
    let map = read_uv_map(surface)?;
    let material = Material::open(&analysis_dir)?;
    if (material.width(), material.height()) != map.sample {
        return Err(Error::invalid(format!(
            "{}: its coordinates index a {}x{} sample, but the analysis {} holds a {}x{} one",
            surface.display(),
            map.sample.0,
            map.sample.1,
            analysis_dir.display(),
            material.width(),
            material.height()
        )));
    }
    if options.size.is_some() {
        tracing::warn!(
            "{}: a texture-mapped result uses the sample itself; the atlas size is ignored",
            surface.display()
        );
    }
    let light = options.light.filter(|_| material.len() > 1);
    let look = Look { scene: &scene, material: &material, blend: bake_blend(&material, light), light };
    let maps = open_maps(&analysis_dir)?
        .iter()
        .map(|m| MapLookup::new(m, material.tileable))
        .collect::<Result<Vec<_>>>()?;
    let mut seconds = [started.elapsed().as_secs_f64(), 0.0, 0.0, 0.0];
    let started = Instant::now();
    let mesh = &map.mesh;
    let uvs =
        mesh.uvs.as_ref().ok_or_else(|| Error::format(surface, "the result has no texture coordinates"))?;
    let atlas = AtlasMesh::from_file_uvs(mesh, uvs);
    let normals = vertex_normals(mesh, &atlas);
    let needs_tangents = maps.iter().any(|m| m.kind == MapKind::Normal);
    let tangents = if needs_tangents { vertex_tangents(mesh, &atlas, &normals) } else { Vec::new() };
    seconds[1] = started.elapsed().as_secs_f64();
    // The sample's own texels: the colour of the blend, and every map at the same texels.
    let started = Instant::now();
    let (w, h) = map.sample;
    let texels: Vec<Vec2> = (0..w * h).map(|i| Vec2::new((i % w) as f32, (i / w) as f32)).collect();
    let baked = Baked {
        width: w,
        height: h,
        covered: vec![true; w * h],
        colour: texels.iter().map(|s| material.shade(&look.blend, s.x, s.y)).collect(),
        coordinate: texels.clone(),
        maps: maps.iter().map(|m| texels.iter().map(|&s| m.at(s)).collect::<Vec<Vec3>>()).collect(),
    };
    seconds[2] = started.elapsed().as_secs_f64();
    let started = Instant::now();
    let name = super::stem(output);
    let job = TexturedJob {
        name: &name,
        mesh,
        mesh_path: surface,
        look: &look,
        maps: &maps,
        options,
        direct: true,
    };
    let mut document = super::gltf::Document::new(&name);
    document.repeat(map.tileable);
    let positions: Vec<[f32; 3]> =
        atlas.source_vertex.iter().map(|&v| mesh.positions[v as usize].to_array()).collect();
    let mut attributes = Map::new();
    attributes.insert("POSITION".into(), document.attribute(&positions).into());
    attributes.insert("NORMAL".into(), document.attribute(&to_arrays(&normals)).into());
    attributes.insert("TEXCOORD_0".into(), document.attribute(&to_arrays(&atlas.uv)).into());
    if needs_tangents {
        attributes.insert("TANGENT".into(), document.attribute(&to_arrays(&tangents)).into());
    }
    let indices = document.indices(&atlas.triangles);
    document.primitive(attributes, indices);
    let mut extras = look.provenance(surface, &analysis_dir);
    extras["textureCoordinates"] = serde_json::json!({
        "method": "soler2002",
        "note": "TEXCOORD_0 indexes the sample itself: baseColorTexture is the sample (and the maps are its maps) at full resolution",
        "sampleWidth": w, "sampleHeight": h, "tileable": map.tileable,
    });
    let material_json = job.material_textures(&mut document, &baked, &mut extras)?;
    document.material(material_json);
    let (vertices, triangles) = document.counts();
    let files = write_document(document, output, binary, options.overwrite)?;
    seconds[3] = started.elapsed().as_secs_f64();
    let charts = atlas.chart.iter().collect::<std::collections::HashSet<_>>().len();
    let atlas = AtlasReport {
        size: w.max(h) as u32,
        generated: false,
        charts,
        baked_texels: 0,
        maps: maps.iter().map(|m| m.kind).collect(),
    };
    Ok(ExportReport { files, vertices, triangles, atlas: Some(atlas), seconds })
}
