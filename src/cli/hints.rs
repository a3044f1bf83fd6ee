//! The command line's names for what the library's errors speak of: the one table from a
//! [`Param`] to its flag and from a [`Remedy`] to the flags that apply it. The library
//! says what is wrong in its own terms; this is where "use --crop x,y,w,h" comes from,
//! keyed on the error's variant, never on its text.

use btfsynth::error::Vocabulary;
use btfsynth::{Error, Param, Remedy};

/// The flag that sets `param`.
pub fn flag(param: Param) -> &'static str {
    match param {
        Param::Components => "--components",
        Param::Crop => "--crop",
        Param::AtlasSize | Param::FrameSize => "--size",
        Param::Padding => "--padding",
        Param::Light => "--light",
        Param::Mesh => "--mesh",
        Param::Analysis => "--analysis",
        Param::Upload => "--upload",
        Param::Rotations => "--rotations",
        Param::Band => "--band",
        Param::PatchOrientation => "--orientation",
        Param::FirstFace => "--first-face",
        Param::Scale => "--scale",
        Param::TexelsAcross => "--texels-across",
        Param::Vertices => "--vertices",
        Param::FrameOrientation => "--orient",
        Param::PlaneSize => "--plane",
        Param::Levels => "--levels",
        Param::Textons => "--textons",
        Param::SelectedImages => "--selected",
        Param::K => "--k",
        Param::BasisRank => "--basis",
        Param::AppearanceDims => "--appearance-dims",
        Param::Maps => "--maps",
        Param::SampleSize => "--size",
        Param::SamplesPerPixel => "--spp",
        Param::Directions => "--directions",
        Param::EdgeLength => "--edge",
        Param::ColourSpace => "--colour-space",
        Param::MaxDistortion => "--max-distortion",
        Param::FitThreshold => "--fit-threshold",
        Param::Neighbourhood => "--neighborhood",
        Param::Search => "--search",
        Param::Preset => "--preset",
    }
}

/// `remedy` as the flags that apply it.
pub fn hint(remedy: &Remedy) -> String {
    let text = match remedy {
        Remedy::Crop => "decode a part with --crop x,y,w,h",
        Remedy::LowerDensity => "lower --scale, --texels-across or --vertices",
        Remedy::LargerAtlas => "give a larger --size or a smaller --padding",
        Remedy::GenerateAtlas => "drop --keep-uvs to generate an atlas",
        Remedy::GiveMesh => "pass --mesh FILE",
        Remedy::GiveAnalysis => "pass --analysis DIR",
        Remedy::UploadFactors => "show the factors with --upload factors",
        Remedy::UploadImages => "view it with --upload images",
        Remedy::SmallerScene => "show a smaller sample or mesh, or a smaller --size",
        Remedy::Headless => "render offscreen with --headless -o DIR",
        Remedy::Reanalyze => "re-run analyze, or use --preset tong2002",
        Remedy::KCoherenceSearch => "use --search kcoherence",
        Remedy::FewerLevels(n) => return format!("use --levels {n} or fewer"),
        Remedy::Overwrite => "pass --force to replace it",
    };
    text.to_string()
}

/// The command line's [`Vocabulary`]: [`flag`] and [`hint`].
pub struct Flags;

impl Vocabulary for Flags {
    fn param(&self, param: Param, value: &str) -> String {
        match value {
            "" => flag(param).to_string(),
            value => format!("{} {value}", flag(param)),
        }
    }

    fn remedy(&self, remedy: &Remedy) -> String {
        hint(remedy)
    }
}

/// One error of a chain as the terminal shows it: a library error in flags, anything else
/// as it displays itself.
pub fn text(cause: &(dyn std::error::Error + 'static)) -> String {
    match cause.downcast_ref::<Error>() {
        Some(e) => e.describe(&Flags),
        None => cause.to_string(),
    }
}

/// A mismatched analysis, with the flag that uses it anyway.
pub fn with_force_hint(e: Error) -> anyhow::Error {
    match e {
        Error::AnalysisMismatch { .. } => anyhow::anyhow!("{e}; pass --force-analysis to use it anyway"),
        other => other.into(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::CommandFactory;
    use std::collections::BTreeSet;

    /// Every long flag of every subcommand, `--` included.
    fn known_flags() -> BTreeSet<String> {
        let mut flags = BTreeSet::new();
        let mut commands = vec![super::super::Cli::command()];
        while let Some(command) = commands.pop() {
            flags.extend(command.get_arguments().filter_map(|a| a.get_long()).map(|l| format!("--{l}")));
            commands.extend(command.get_subcommands().cloned());
        }
        flags
    }

    /// The flags a hint names.
    fn named_flags(text: &str) -> Vec<String> {
        text.split(|c: char| c.is_whitespace() || c == ',')
            .filter(|w| w.starts_with("--"))
            .map(str::to_string)
            .collect()
    }

    #[test]
    fn every_parameter_and_remedy_names_a_flag_the_command_line_has() {
        let known = known_flags();
        for &param in Param::ALL {
            assert!(known.contains(flag(param)), "{param:?}: {} is no flag", flag(param));
        }
        let remedies = [
            Remedy::Crop,
            Remedy::LowerDensity,
            Remedy::LargerAtlas,
            Remedy::GenerateAtlas,
            Remedy::GiveMesh,
            Remedy::GiveAnalysis,
            Remedy::UploadFactors,
            Remedy::UploadImages,
            Remedy::SmallerScene,
            Remedy::Headless,
            Remedy::Reanalyze,
            Remedy::KCoherenceSearch,
            Remedy::FewerLevels(2),
            Remedy::Overwrite,
        ];
        for remedy in &remedies {
            let named = named_flags(&hint(remedy));
            assert!(!named.is_empty(), "{remedy:?}: '{}' names no flag", hint(remedy));
            for f in named {
                // `--headless` exists only with the viewer compiled in.
                let optional = f == "--headless" && !cfg!(feature = "gpu");
                assert!(optional || known.contains(&f), "{remedy:?}: {f} is no flag");
            }
        }
    }

    #[test]
    fn library_errors_reach_the_terminal_naming_the_flag() {
        let levels = Error::OutOfRange {
            param: Param::Levels,
            value: "5".into(),
            message: "the coarsest level would be 3x3 pixels".into(),
            remedy: Some(Remedy::FewerLevels(2)),
        };
        assert_eq!(
            text(&levels),
            "--levels 5: the coarsest level would be 3x3 pixels; use --levels 2 or fewer"
        );
        let exists = Error::OutputExists("out.ply".into());
        assert_eq!(text(&exists), "out.ply already exists (pass --force to replace it)");
        let search = Error::IncompatibleSearch { preset: "chen2008".into() };
        let line = text(&search);
        assert!(
            line.starts_with("--search full: preset 'chen2008'") && line.ends_with("use --search kcoherence")
        );
        let other = std::io::Error::other("plain");
        assert_eq!(text(&other), "plain");
    }
}
