//! The library's one error type. Every message names the file (or parameter) at fault and
//! says what is wrong with it, on one line, so the CLI can print it as a single line.
//!
//! Messages speak the library's language: a parameter is a [`Param`] and a way out is a
//! [`Remedy`], named in words ("first face", "decode a part of the stack (a crop)"). A
//! front end with names of its own for them (the command line's flags) renders the same
//! error with [`Error::describe`] and its own [`Vocabulary`], keyed on these enums rather
//! than on the text.

use std::fmt;
use std::path::{Path, PathBuf};

/// Declares [`Param`] and its [`Param::ALL`] from one list, so that the list of every
/// parameter cannot miss one.
macro_rules! params {
    ($($(#[$doc:meta])* $name:ident,)*) => {
        /// A parameter a caller chooses, as errors name it: an analysis setting, a synthesis or
        /// pattern-mapping setting, a rendering or export option.
        ///
        /// Deliberately exhaustive, so that a front end's table of names (see [`Vocabulary`])
        /// stops compiling when a parameter is added without a name there.
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
        pub enum Param {
            $($(#[$doc])* $name,)*
        }

        impl Param {
            /// Every parameter, in declaration order, for tables that must name each one.
            pub const ALL: &'static [Param] = &[$(Param::$name,)*];
        }
    };
}

params! {
    /// Components per colour channel of a factorization (`btf::factorize::factorize`).
    Components,
    /// The rectangle of the sample to read ([`crate::btf::Crop`]).
    Crop,
    /// The side of a baked texture atlas, in texels (`export::ExportOptions::size`).
    AtlasSize,
    /// The texels left between an atlas' charts (`export::ExportOptions::padding`).
    Padding,
    /// The light direction of a bake or a picture.
    Light,
    /// The original mesh of a surface map (`export::ExportOptions::mesh`).
    Mesh,
    /// The analysis directory a result is read with.
    Analysis,
    /// What the GPU receives of the sample: its images or its factors (`render::gpu::Upload`).
    Upload,
    /// The size of a rendered frame, in pixels.
    FrameSize,
    /// Rotations tried per pattern-mapped patch (`synth::patches::SolerParams::rotations`).
    Rotations,
    /// The seam band of pattern mapping, in texels (`SolerParams::band`).
    Band,
    /// The fixed orientation of pattern-mapped patches, in degrees (`SolerParams::orientation`).
    PatchOrientation,
    /// The face pattern mapping starts from (`SolerParams::first_face`).
    FirstFace,
    /// Texels per model unit of a surface result (`SolerParams::texels_per_unit`, a density).
    Scale,
    /// Texels across the mesh's largest extent (a density).
    TexelsAcross,
    /// The vertex count of the finest synthesis mesh (a density).
    Vertices,
    /// How the surface's tangent frames are oriented ([`crate::mesh::field::Orientation`]).
    FrameOrientation,
    /// The width × height of a synthesized plane, in texels.
    PlaneSize,
    /// Pyramid levels analysed or synthesized.
    Levels,
    /// Textons per level of an analysis (`AnalysisParams::textons`).
    Textons,
    /// Representative images an analysis selects (`AnalysisParams::selected`).
    SelectedImages,
    /// The length of the kNN candidate lists (`AnalysisParams::k`, `Search::KCoherence`).
    K,
    /// The rank of the images' basis (`AnalysisParams::basis_rank`).
    BasisRank,
    /// Dimensions of the appearance vectors (`AnalysisParams::appearance_dims`).
    AppearanceDims,
    /// The material maps given with an analysis, as `KIND=FILE` pairs ([`crate::maps`]).
    Maps,
    /// The side of a generated sample, in pixels (`btf::gen::GenParams::size`).
    SampleSize,
    /// Rays per pixel of a generated sample (`btf::gen::GenParams::samples_per_pixel`).
    SamplesPerPixel,
    /// A named set of view and light directions ([`crate::btf::DirectionSet`]).
    Directions,
    /// The target edge length of a remeshing (`mesh::remesh::RemeshParams`).
    EdgeLength,
    /// The colour space pattern mapping compares in (`synth::patches::ColourSpace`).
    ColourSpace,
    /// The largest flattening distortion of a pattern-mapped patch (`SolerParams::max_flat_error`).
    MaxDistortion,
    /// The largest seam error of a pattern-mapped patch (`SolerParams::max_fit_error`).
    FitThreshold,
    /// The side of the square neighbourhood matched, in texels (`neighborhood`).
    Neighbourhood,
    /// Where candidates come from: k-coherence or every texel ([`crate::synth::Search`]).
    Search,
    /// The synthesis recipe by name ([`crate::synth::recipe::Preset::by_name`]).
    Preset,
}

impl Param {
    /// The parameter in the library's words: "first face", "atlas size".
    pub fn name(self) -> &'static str {
        match self {
            Param::Components => "components",
            Param::Crop => "crop",
            Param::AtlasSize => "atlas size",
            Param::Padding => "atlas padding",
            Param::Light => "light",
            Param::Mesh => "mesh",
            Param::Analysis => "analysis",
            Param::Upload => "upload",
            Param::FrameSize => "frame size",
            Param::Rotations => "rotations",
            Param::Band => "band",
            Param::PatchOrientation => "patch orientation",
            Param::FirstFace => "first face",
            Param::Scale => "scale",
            Param::TexelsAcross => "texels across",
            Param::Vertices => "vertices",
            Param::FrameOrientation => "frame orientation",
            Param::PlaneSize => "plane size",
            Param::Levels => "levels",
            Param::Textons => "textons",
            Param::SelectedImages => "selected images",
            Param::K => "k",
            Param::BasisRank => "basis rank",
            Param::AppearanceDims => "appearance dimensions",
            Param::Maps => "material maps",
            Param::SampleSize => "sample size",
            Param::SamplesPerPixel => "samples per pixel",
            Param::Directions => "directions",
            Param::EdgeLength => "edge length",
            Param::ColourSpace => "colour space",
            Param::MaxDistortion => "maximum distortion",
            Param::FitThreshold => "fit threshold",
            Param::Neighbourhood => "neighbourhood",
            Param::Search => "search",
            Param::Preset => "preset",
        }
    }
}

impl fmt::Display for Param {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A way to get what was refused: the advice an error ends with.
///
/// Exhaustive for the same reason as [`Param`].
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Remedy {
    /// Read only a rectangle of the stack ([`Param::Crop`]).
    Crop,
    /// Ask for fewer texels on the surface: a lower scale, fewer texels across or vertices.
    LowerDensity,
    /// A larger atlas side or less padding between the charts.
    LargerAtlas,
    /// Generate an atlas rather than keep the mesh's own texture coordinates.
    GenerateAtlas,
    /// Name the original mesh ([`Param::Mesh`]).
    GiveMesh,
    /// Name the analysis directory ([`Param::Analysis`]).
    GiveAnalysis,
    /// Upload the sample's factors rather than its images ([`Param::Upload`]).
    UploadFactors,
    /// Upload the sample's images rather than its factors ([`Param::Upload`]).
    UploadImages,
    /// A smaller sample or mesh, or a smaller frame.
    SmallerScene,
    /// Render offscreen into a directory instead of a window.
    Headless,
    /// Analyse the sample again, or choose a preset that needs nothing the analysis lacks.
    Reanalyze,
    /// Take candidates by k-coherence ([`Param::Search`]).
    KCoherenceSearch,
    /// At most this many pyramid levels ([`Param::Levels`]).
    FewerLevels(usize),
    /// Allow the existing output to be overwritten.
    Overwrite,
}

impl fmt::Display for Remedy {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Remedy::Crop => f.write_str("decode a part of the stack (a crop)"),
            Remedy::LowerDensity => f.write_str("lower the scale, the texels across or the vertex count"),
            Remedy::LargerAtlas => f.write_str("give a larger atlas size or a smaller padding"),
            Remedy::GenerateAtlas => f.write_str("generate an atlas instead"),
            Remedy::GiveMesh => f.write_str("give the original mesh"),
            Remedy::GiveAnalysis => f.write_str("give the analysis directory"),
            Remedy::UploadFactors => f.write_str("upload the sample's factors instead of its images"),
            Remedy::UploadImages => f.write_str("upload the sample's images instead of its factors"),
            Remedy::SmallerScene => f.write_str("show a smaller sample or mesh, or a smaller frame"),
            Remedy::Headless => f.write_str("render offscreen into a directory"),
            Remedy::Reanalyze => f.write_str("analyse the sample again, or use the preset tong2002"),
            Remedy::KCoherenceSearch => f.write_str("use the k-coherence search"),
            Remedy::FewerLevels(n) => write!(f, "use {n} levels or fewer"),
            Remedy::Overwrite => f.write_str("allow overwriting to replace it"),
        }
    }
}

/// How [`Error::describe`] names parameters and remedies; [`Words`] is the library's own.
pub trait Vocabulary {
    /// `param`, set to `value` (empty where no one value is at fault), as the start of a
    /// message: "first face 12".
    fn param(&self, param: Param, value: &str) -> String;
    /// `remedy` as the clause a message ends with.
    fn remedy(&self, remedy: &Remedy) -> String;
}

/// The library's words ([`Param::name`], [`Remedy`]'s `Display`): what `Display` shows.
pub struct Words;

impl Vocabulary for Words {
    fn param(&self, param: Param, value: &str) -> String {
        match value {
            "" => param.name().to_string(),
            value => format!("{} {value}", param.name()),
        }
    }

    fn remedy(&self, remedy: &Remedy) -> String {
        remedy.to_string()
    }
}

/// Everything that can go wrong in btfsynth's library.
///
/// Messages stay on one line: line breaks and other control characters that a file name or
/// a quoted piece of a damaged file brings into them are shown escaped (`\n`).
#[derive(Debug)]
pub enum Error {
    /// The operating system refused to read or write a path.
    Io {
        /// The path read or written.
        path: PathBuf,
        /// What the operating system said.
        source: std::io::Error,
    },
    /// A file exists but its contents are not what it claims to be.
    Format {
        /// The file.
        path: PathBuf,
        /// What is wrong with its contents.
        message: String,
    },
    /// A value handed to a library function is out of its domain where no one [`Param`] is
    /// at fault: data of inconsistent sizes (pixels that do not fill the images said), a
    /// mesh that cannot be remeshed, a result that does not fit the analysis offered.
    InvalidArgument(String),
    /// A parameter's value is out of its domain, or does not fit the input at hand.
    OutOfRange {
        /// The parameter at fault.
        param: Param,
        /// Its value as given, or empty where the message says it.
        value: String,
        /// What is wrong with it, in the library's words.
        message: String,
        /// What to do instead, where the message does not say it.
        remedy: Option<Remedy>,
    },
    /// The work would need more than a limit allows: memory, vertices, atlas pages.
    TooLarge {
        /// What it would need and the limit, naming the input.
        message: String,
        /// How to ask for less.
        remedy: Remedy,
    },
    /// The work cannot be done the way it was asked for (no window, a colour model the GPU
    /// cannot decode, a file that was moved), but another way works.
    Unavailable {
        /// What is missing or impossible, naming the input.
        message: String,
        /// The way that works.
        remedy: Remedy,
    },
    /// An output exists and overwriting was not allowed.
    OutputExists(PathBuf),
    /// An output cannot go where it was asked: the path is a directory or a device where a
    /// file belongs (or the reverse), an input or another output, in a folder that is missing
    /// or cannot be written, or named with an extension of another format.
    OutputRefused {
        /// The output asked for.
        path: PathBuf,
        /// Why, naming the path.
        message: String,
    },
    /// A synthesis recipe (a preset, or one read from JSON) whose parts cannot run together
    /// or whose numbers are out of range.
    Recipe {
        /// The recipe's name.
        recipe: String,
        /// What is wrong, naming the level and pass where one is at fault.
        message: String,
    },
    /// The GPU refused: no adapter, a device that failed, a format or a window it cannot
    /// use, a readback that did not arrive.
    Gpu(String),
    /// A broken invariant of the library's own, which no input should reach (a bug if seen):
    /// an FFT handed buffers of the wrong length, an array laid out otherwise than it was
    /// made, a value serde cannot write.
    Internal(String),
    /// The preset cannot run with a full search: its adaptive passes take their
    /// candidates around the linked texels (k-coherence) only.
    IncompatibleSearch {
        /// The preset's name.
        preset: String,
    },
    /// An analysis is not the one a result was synthesized from: the fingerprints of their
    /// samples differ.
    AnalysisMismatch {
        /// The surface map or plane result.
        result: PathBuf,
        /// The analysis directory offered for it.
        analysis: PathBuf,
        /// The fingerprint the result records.
        recorded: String,
        /// The fingerprint of the offered analysis.
        found: String,
    },
}

/// Shorthand used throughout the library.
pub type Result<T, E = Error> = std::result::Result<T, E>;

impl Error {
    /// The operating system's refusal to read or write `path`.
    pub fn io(path: impl AsRef<Path>, source: std::io::Error) -> Self {
        Error::Io { path: path.as_ref().to_path_buf(), source }
    }

    /// `path`'s contents are wrong: `message` says how.
    pub fn format(path: impl AsRef<Path>, message: impl Into<String>) -> Self {
        Error::Format { path: path.as_ref().to_path_buf(), message: message.into() }
    }

    /// A value out of its domain that no one [`Param`] stands for.
    pub fn invalid(message: impl Into<String>) -> Self {
        Error::InvalidArgument(message.into())
    }

    /// `path` cannot be an output: `message` says why, naming it.
    pub fn output_refused(path: impl AsRef<Path>, message: impl Into<String>) -> Self {
        Error::OutputRefused { path: path.as_ref().to_path_buf(), message: message.into() }
    }

    /// The recipe called `recipe` is refused: `message` says why.
    pub fn recipe(recipe: impl Into<String>, message: impl Into<String>) -> Self {
        Error::Recipe { recipe: recipe.into(), message: message.into() }
    }

    /// The GPU refused: `message` says what.
    pub fn gpu(message: impl Into<String>) -> Self {
        Error::Gpu(message.into())
    }

    /// A broken invariant of the library's own: `message` says which.
    pub fn internal(message: impl Into<String>) -> Self {
        Error::Internal(message.into())
    }

    /// `param`, set to `value`, is wrong: `message` says how.
    pub fn out_of_range(param: Param, value: impl fmt::Display, message: impl Into<String>) -> Self {
        Error::OutOfRange { param, value: value.to_string(), message: message.into(), remedy: None }
    }

    /// The work needs more than a limit: `message` says what and which, `remedy` how to
    /// ask for less.
    pub fn too_large(message: impl Into<String>, remedy: Remedy) -> Self {
        Error::TooLarge { message: message.into(), remedy }
    }

    /// The work cannot be done as asked: `message` says why, `remedy` what works.
    pub fn unavailable(message: impl Into<String>, remedy: Remedy) -> Self {
        Error::Unavailable { message: message.into(), remedy }
    }

    /// The message on one line, naming parameters and remedies in `words` (`Display` is
    /// this with [`Words`]).
    pub fn describe(&self, words: &dyn Vocabulary) -> String {
        match self {
            Error::Io { path, source } => format!("{}: {}", OneLine(path.display()), OneLine(source)),
            Error::Format { path, message } => format!("{}: {}", OneLine(path.display()), OneLine(message)),
            Error::InvalidArgument(message) | Error::Gpu(message) => OneLine(message).to_string(),
            Error::OutputRefused { message, .. } => OneLine(message).to_string(),
            Error::Recipe { recipe, message } => {
                format!("recipe '{}': {}", OneLine(recipe), OneLine(message))
            }
            Error::Internal(message) => format!("internal error (please report it): {}", OneLine(message)),
            Error::OutOfRange { param, value, message, remedy } => {
                let subject = words.param(*param, &OneLine(value).to_string());
                match remedy {
                    Some(r) => format!("{subject}: {}; {}", OneLine(message), words.remedy(r)),
                    None => format!("{subject}: {}", OneLine(message)),
                }
            }
            Error::TooLarge { message, remedy } | Error::Unavailable { message, remedy } => {
                format!("{}; {}", OneLine(message), words.remedy(remedy))
            }
            Error::OutputExists(path) => {
                format!("{} already exists ({})", OneLine(path.display()), words.remedy(&Remedy::Overwrite))
            }
            Error::IncompatibleSearch { preset } => format!(
                "{}: preset '{}' takes its candidates around the linked texels (k-coherence) only; {}",
                words.param(Param::Search, "full"),
                OneLine(preset),
                words.remedy(&Remedy::KCoherenceSearch)
            ),
            Error::AnalysisMismatch { result, analysis, recorded, found } => format!(
                "{} was synthesized from an analysis of another sample ({recorded}), not from {} ({found})",
                OneLine(result.display()),
                OneLine(analysis.display())
            ),
        }
    }
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.describe(&Words))
    }
}

impl std::error::Error for Error {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            Error::Io { source, .. } => Some(source),
            _ => None,
        }
    }
}

/// Shows a value with its control characters escaped, so that a message stays on one line.
struct OneLine<T>(T);

impl<T: fmt::Display> fmt::Display for OneLine<T> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for c in self.0.to_string().chars() {
            if c.is_control() {
                write!(f, "{}", c.escape_default())?;
            } else {
                write!(f, "{c}")?;
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn messages_are_one_line_whatever_the_file_name() {
        let e = Error::format("/data/tl\n15.png", "cannot read 'tl\n15'");
        assert_eq!(e.to_string(), "/data/tl\\n15.png: cannot read 'tl\\n15'");
        let e = Error::out_of_range(Param::Mesh, "/data/a\nb.obj", "no such file");
        assert_eq!(e.to_string(), "mesh /data/a\\nb.obj: no such file");
        assert_eq!(
            Error::OutputExists("o\r".into()).to_string(),
            "o\\r already exists (allow overwriting to replace it)"
        );
    }

    /// A vocabulary that shows which of its names a message used.
    struct Marked;

    impl Vocabulary for Marked {
        fn param(&self, param: Param, value: &str) -> String {
            format!("<{}={value}>", param.name())
        }
        fn remedy(&self, remedy: &Remedy) -> String {
            format!("<{remedy:?}>")
        }
    }

    #[test]
    fn a_front_end_names_parameters_and_remedies_its_own_way() {
        let levels = Error::OutOfRange {
            param: Param::Levels,
            value: "5".into(),
            message: "the coarsest level would be 3x3 pixels".into(),
            remedy: Some(Remedy::FewerLevels(2)),
        };
        assert_eq!(
            levels.to_string(),
            "levels 5: the coarsest level would be 3x3 pixels; use 2 levels or fewer"
        );
        assert_eq!(
            levels.describe(&Marked),
            "<levels=5>: the coarsest level would be 3x3 pixels; <FewerLevels(2)>"
        );
        let search = Error::IncompatibleSearch { preset: "chen2008".into() };
        assert_eq!(
            search.describe(&Marked),
            "<search=full>: preset 'chen2008' takes its candidates around the linked texels (k-coherence) only; <KCoherenceSearch>"
        );
        let big = Error::too_large("a.btf: decoding it would take 9 GiB", Remedy::Crop);
        assert_eq!(
            big.to_string(),
            "a.btf: decoding it would take 9 GiB; decode a part of the stack (a crop)"
        );
        assert_eq!(Error::OutputExists("out".into()).describe(&Marked), "out already exists (<Overwrite>)");
    }

    /// A caller can tell the kinds of refusal apart by variant, not by text.
    #[test]
    fn refusals_come_as_their_own_variants() {
        let preset = crate::synth::Preset::by_name("nope").unwrap_err();
        assert!(matches!(preset, Error::OutOfRange { param: Param::Preset, .. }), "{preset:?}");
        assert!(preset.to_string().starts_with("preset 'nope': unknown preset"), "{preset}");
        let dir = std::env::temp_dir();
        let input = crate::fsutil::check_not_input("the output", &dir, &[&dir]).unwrap_err();
        assert!(matches!(&input, Error::OutputRefused { path, .. } if *path == dir), "{input:?}");
        let mut recipe = crate::synth::Preset::by_name("tong2002").unwrap();
        recipe.finer.passes.clear();
        let refused = recipe.validate().unwrap_err();
        assert!(matches!(&refused, Error::Recipe { recipe, .. } if recipe == "tong2002"), "{refused:?}");
        assert!(
            refused.to_string().starts_with("recipe 'tong2002': the finer level has no passes"),
            "{refused}"
        );
        let size = crate::btf::gen::GenParams { size: 3, ..Default::default() }.validate().unwrap_err();
        assert!(matches!(size, Error::OutOfRange { param: Param::SampleSize, .. }), "{size:?}");
        let internal = Error::internal("FFT: lengths\ndiffer");
        assert_eq!(internal.to_string(), "internal error (please report it): FFT: lengths\\ndiffer");
    }

    #[test]
    fn every_parameter_has_its_own_name() {
        let names: std::collections::BTreeSet<&str> = Param::ALL.iter().map(|p| p.name()).collect();
        assert_eq!(names.len(), Param::ALL.len(), "{names:?}");
        assert!(names.iter().all(|n| !n.is_empty() && !n.starts_with('-')), "{names:?}");
    }
}
