//! The documentation a reader meets: a README short enough to read at once, and links that
//! lead somewhere (a moved section or a renamed picture breaks no link silently).

use std::path::{Path, PathBuf};

const ROOT: &str = env!("CARGO_MANIFEST_DIR");

/// The front page stays a front page: the reference lives in docs/.
const README_MAX_LINES: usize = 300;

fn markdown_files() -> Vec<PathBuf> {
    let mut files = vec![Path::new(ROOT).join("README.md")];
    for entry in std::fs::read_dir(Path::new(ROOT).join("docs")).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "md") {
            files.push(path);
        }
    }
    files
}

/// The targets of `](target)` links and images, without their `#anchor`.
fn relative_links(text: &str) -> Vec<String> {
    text.split("](")
        .skip(1)
        .filter_map(|rest| rest.split(')').next())
        .filter(|t| !t.contains("://") && !t.starts_with('#') && !t.starts_with("mailto:"))
        .map(|t| t.split('#').next().unwrap_or_default().to_string())
        .filter(|t| !t.is_empty())
        .collect()
}

#[test]
fn the_readme_fits_on_a_few_screens() {
    let lines = std::fs::read_to_string(Path::new(ROOT).join("README.md")).unwrap().lines().count();
    assert!(lines <= README_MAX_LINES, "README.md has {lines} lines; move reference text into docs/");
}

#[test]
fn every_relative_link_of_the_docs_names_a_file_of_the_repository() {
    for file in markdown_files() {
        let text = std::fs::read_to_string(&file).unwrap();
        let dir = file.parent().unwrap();
        for link in relative_links(&text) {
            assert!(dir.join(&link).exists(), "{}: the link {link} names no file", file.display());
        }
    }
}

#[test]
fn links_are_found_in_text_and_images() {
    let text = "see [a](docs/a.md#x), ![p](b.png) and [web](https://x.org/c) or [here](#y)";
    assert_eq!(relative_links(text), ["docs/a.md", "b.png"]);
}

/// The lines of the first fenced block of `text` that opens with ` ```{fence}`.
fn fenced_block(text: &str, fence: &str) -> Vec<String> {
    let mut lines = text.lines().skip_while(|l| l.trim() != format!("```{fence}")).skip(1);
    lines.by_ref().take_while(|l| l.trim() != "```").map(str::to_string).collect()
}

#[test]
fn the_readmes_library_example_is_the_crate_doctest() {
    let readme = std::fs::read_to_string(Path::new(ROOT).join("README.md")).unwrap();
    let lib = std::fs::read_to_string(Path::new(ROOT).join("src/lib.rs")).unwrap();
    let doc: String = lib
        .lines()
        .filter_map(|l| l.strip_prefix("//!"))
        .map(|l| l.strip_prefix(' ').unwrap_or(l))
        .collect::<Vec<_>>()
        .join("\n");
    let doctest: Vec<String> = fenced_block(&doc, "").into_iter().filter(|l| !l.starts_with("# ")).collect();
    assert!(!doctest.is_empty(), "the crate doc has no example");
    assert_eq!(fenced_block(&readme, "rust"), doctest, "README's snippet drifted from src/lib.rs's doctest");
}
