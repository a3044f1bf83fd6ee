//! `btfsynth export`: a surface map on the user's mesh as glTF with baked textures.

use super::progress::Bars;
use super::shots::parse_angles;
use crate::btf::Direction;
use crate::export::{export, CoordinateFormat, ExportOptions, UvChoice, SIZE_RANGE};
use anyhow::Result;
use std::path::PathBuf;

/// How the sample-coordinate map is stored.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
enum CoordinateArg {
    /// 16-bit RGB PNG, normalised to the sample size.
    Png,
    /// 32-bit float RGB EXR, in sample texels.
    Exr,
}

#[derive(clap::Args)]
#[command(
    long_about = "Writes the user's original mesh (the one `synth` was given) as glTF 2.0 with the synthesized \
material baked into textures: into the mesh's own UVs (OBJ vt, PLY s,t) if it has them, else into a \
generated atlas. Each atlas texel finds its point on the mesh, the nearest point of the synthesized \
surface and the sample coordinate there, and looks the BTF up (as `render --mode pixel` does).\n\n\
A one-image BTF (a photograph) bakes to baseColorTexture. A BTF stack bakes the image seen head-on \
under --light (default: the stack's most frontal image) and always also writes the sample-coordinate \
map, referenced from the material's extras.btfsynth, so an engine can do its own BTF lookups. \
Material maps stored by `analyze --maps` go to their glTF slots: normalTexture (re-oriented into the \
atlas' tangent frame), metallicRoughnessTexture and occlusionTexture; height to a 16-bit PNG in extras.",
    after_help = "Examples:\n  btfsynth export bunny.ply -o bunny.glb\n  \
btfsynth export bunny.ply -o bunny.gltf --size 2048 --light 45,0\n  \
btfsynth export bunny.ply -o bunny-dense.glb --vertex-colors"
)]
pub struct ExportArgs {
    /// The surface map (a PLY from `btfsynth synth`).
    surface: PathBuf,
    /// Output: a .glb (one binary file) or a .gltf (with .bin and .png files beside it).
    #[arg(short, long, value_name = "OUT.glb|OUT.gltf")]
    output: PathBuf,
    /// The original mesh [default: the one named in the surface map's header, as written,
    /// relative to the surface map, or its recorded absolute path].
    #[arg(long, value_name = "FILE")]
    mesh: Option<PathBuf>,
    /// The analysis directory [default: the one named in the surface map's header].
    #[arg(long, value_name = "DIR")]
    analysis: Option<PathBuf>,
    /// Use --analysis even though it is not the analysis the map was synthesized from.
    #[arg(long, requires = "analysis")]
    force_analysis: bool,
    /// Atlas width and height in texels [default: about one texel per synthesized sample
    /// texel, rounded up to a power of two].
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(i64::from(*SIZE_RANGE.start())..=i64::from(*SIZE_RANGE.end())))]
    size: Option<u32>,
    /// Bake into the mesh's own UVs; fail if it has none.
    #[arg(long, conflicts_with = "new_uvs")]
    keep_uvs: bool,
    /// Generate an atlas even if the mesh has UVs.
    #[arg(long)]
    new_uvs: bool,
    /// Empty texels around each chart of a generated atlas [default: size / 256, at least 2].
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=256))]
    padding: Option<u32>,
    /// For a BTF stack: bake the image under this light, θ,φ in degrees in the sample's
    /// frame (θ from the normal, φ from the texture's s towards t), seen head-on.
    #[arg(long, value_name = "θ,φ", value_parser = parse_light)]
    light: Option<Direction>,
    /// How the sample-coordinate map of a BTF stack is stored.
    #[arg(long, value_enum, default_value_t = CoordinateArg::Png)]
    format: CoordinateArg,
    /// Write the dense synthesized mesh with per-vertex colours instead (no textures, no
    /// atlas): a quick look.
    #[arg(long)]
    vertex_colors: bool,
    /// Replace existing output files.
    #[arg(long)]
    force: bool,
}

fn parse_light(s: &str) -> Result<Direction, String> {
    let (theta, phi) = parse_angles(s)?;
    Direction::new(theta, phi).map_err(|e| format!("'{s}': {e}"))
}

pub fn run(args: ExportArgs, bars: &Bars) -> Result<()> {
    let inputs: Vec<&std::path::Path> =
        [Some(args.surface.as_path()), args.mesh.as_deref(), args.analysis.as_deref()]
            .into_iter()
            .flatten()
            .collect();
    crate::fsutil::check_not_input("-o", &args.output, &inputs)?;
    let options = ExportOptions {
        mesh: args.mesh,
        analysis: args.analysis,
        force_analysis: args.force_analysis,
        size: args.size,
        uvs: match (args.keep_uvs, args.new_uvs) {
            (true, _) => UvChoice::Keep,
            (_, true) => UvChoice::Generate,
            _ => UvChoice::Auto,
        },
        padding: args.padding,
        light: args.light,
        coordinates: match args.format {
            CoordinateArg::Png => CoordinateFormat::Png,
            CoordinateArg::Exr => CoordinateFormat::Exr,
        },
        vertex_colours: args.vertex_colors,
        overwrite: args.force,
    };
    let report = export(&args.surface, &args.output, &options, bars)?;
    match &report.atlas {
        Some(atlas) => {
            let maps: Vec<&str> = atlas.maps.iter().map(|k| k.name()).collect();
            eprintln!(
                "  atlas     {0}x{0}, {1} ({2} charts), {3} texels baked{4}",
                atlas.size,
                if atlas.generated { "generated" } else { "the mesh's own UVs" },
                atlas.charts,
                atlas.baked_texels,
                if maps.is_empty() { String::new() } else { format!("; maps: {}", maps.join(", ")) }
            );
        }
        None => eprintln!("  per-vertex colours of the synthesized surface"),
    }
    let [read, layout, bake, write] = report.seconds;
    eprintln!(
        "wrote {} vertices, {} triangles in {:.1} s (reading {read:.1}, layout {layout:.1}, baking {bake:.1}, encoding and writing {write:.1})",
        report.vertices,
        report.triangles,
        read + layout + bake + write
    );
    for file in &report.files {
        super::print(file.display())?;
    }
    Ok(())
}
