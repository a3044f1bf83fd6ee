//! No import cycles between source files: a file that uses another is never used by it,
//! directly or through others. Shared vocabulary lives in leaf modules (`synth::state`,
//! `synth::slot`, `synth::flatten`), so each module can be read, tested and reused on its
//! own. Read from the `use` lines and `crate::`/`super::` paths of the code (comments and
//! test modules left out). A parent module's relative `use child::…` lines are not read: a
//! `mod.rs` composes its children, which may name the items it defines.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

const SRC: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/src");

/// Every source file's text, by its path under `src/`.
fn sources() -> BTreeMap<String, String> {
    let mut files = BTreeMap::new();
    let mut dirs = vec![Path::new(SRC).to_path_buf()];
    while let Some(dir) = dirs.pop() {
        for entry in std::fs::read_dir(&dir).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                dirs.push(path);
            } else if path.extension().is_some_and(|e| e == "rs") {
                let name = path.strip_prefix(SRC).unwrap().to_string_lossy().replace('\\', "/");
                files.insert(name, std::fs::read_to_string(&path).unwrap());
            }
        }
    }
    files
}

/// The module path of a file: `synth/engine.rs` is `synth::engine`, `synth/mod.rs` is `synth`.
fn module_of(file: &str) -> Vec<String> {
    let mut parts: Vec<String> = file.trim_end_matches(".rs").split('/').map(str::to_string).collect();
    if matches!(parts.last().map(String::as_str), Some("mod" | "lib" | "main")) {
        parts.pop();
    }
    parts
}

/// The code of a file without comments and without its test module, with the spaces
/// inside path groups removed (`super::{a, b}` becomes `super::{a,b}`).
fn code(text: &str) -> String {
    let lines: Vec<&str> = text.lines().filter(|l| !l.trim_start().starts_with("//")).collect();
    let joined = lines.join("\n");
    let end =
        joined.find("#[cfg(test)]\nmod tests").or_else(|| joined.find("#[cfg(test)]\npub(crate) mod tests"));
    let mut code = String::new();
    for c in joined[..end.unwrap_or(joined.len())].chars() {
        if !(c.is_whitespace() && code.ends_with([',', '{', ':'])) {
            code.push(c);
        }
    }
    code
}

/// The paths a file names: `crate::a::b`, `super::a`, `self::a`, and the members of
/// `crate::{a, b}` / `super::{a, b}` groups, as absolute module paths (items included).
fn named_paths(file: &str, code: &str) -> Vec<Vec<String>> {
    let me = module_of(file);
    let path_char = |c: char| c.is_alphanumeric() || c == '_' || c == ':';
    let mut paths = Vec::new();
    for root in ["crate::", "super::", "self::"] {
        for (at, _) in code.match_indices(root) {
            if code[..at].chars().next_back().is_some_and(path_char) {
                continue;
            }
            let rest: String =
                code[at + root.len()..].chars().take_while(|&c| path_char(c) || "{},".contains(c)).collect();
            let mut base: Vec<String> = match root {
                "crate::" => Vec::new(),
                "self::" => me.clone(),
                _ => me[..me.len().saturating_sub(1)].to_vec(),
            };
            let mut rest = rest.as_str();
            while let Some(r) = rest.strip_prefix("super::") {
                base.pop();
                rest = r;
            }
            let (prefix, group) = match rest.split_once('{') {
                Some((p, g)) => (p, Some(g)),
                None => (rest, None),
            };
            let segments = |s: &str| -> Vec<String> {
                s.split("::")
                    .filter(|s| !s.is_empty())
                    .map(|s| s.trim_matches(|c| "{},".contains(c)).to_string())
                    .collect()
            };
            let mut stem = base.clone();
            stem.extend(segments(prefix));
            match group {
                Some(group) => {
                    for member in group.split(',').filter(|m| !m.is_empty()) {
                        let mut path = stem.clone();
                        path.extend(segments(member.split('{').next().unwrap_or_default()));
                        paths.push(path);
                    }
                }
                None => paths.push(stem),
            }
        }
    }
    paths
}

/// File → the other files it uses.
fn imports(files: &BTreeMap<String, String>) -> BTreeMap<String, BTreeSet<String>> {
    let modules: BTreeMap<Vec<String>, String> = files.keys().map(|f| (module_of(f), f.clone())).collect();
    let resolve = |path: &[String]| (1..=path.len()).rev().find_map(|n| modules.get(&path[..n]).cloned());
    files
        .iter()
        .map(|(file, text)| {
            let used = named_paths(file, &code(text))
                .iter()
                .filter_map(|p| resolve(p))
                .filter(|f| f != file)
                .collect();
            (file.clone(), used)
        })
        .collect()
}

/// The groups of files that reach each other (strongly connected, more than one file).
fn cycles(graph: &BTreeMap<String, BTreeSet<String>>) -> BTreeSet<Vec<String>> {
    let reach = |from: &String| {
        let (mut seen, mut stack) = (BTreeSet::new(), vec![from.clone()]);
        while let Some(f) = stack.pop() {
            for g in &graph[&f] {
                if seen.insert(g.clone()) {
                    stack.push(g.clone());
                }
            }
        }
        seen
    };
    let reached: BTreeMap<&String, BTreeSet<String>> = graph.keys().map(|f| (f, reach(f))).collect();
    graph
        .keys()
        .filter(|f| reached[f].contains(*f))
        .map(|f| {
            graph.keys().filter(|g| reached[f].contains(*g) && reached[g].contains(f)).cloned().collect()
        })
        .collect()
}

#[test]
fn no_source_file_is_used_by_a_file_it_uses() {
    let found = cycles(&imports(&sources()));
    assert!(
        found.is_empty(),
        "import cycles between files (move what they share into a leaf module): {found:?}"
    );
}

#[test]
fn the_cycle_check_sees_a_cycle_through_super_and_crate_paths() {
    let files: BTreeMap<String, String> = [
        ("a/mod.rs", "pub mod b;\npub mod c;\n"),
        ("a/b.rs", "use super::c::Thing;\n// use super::d::Ignored;\n"),
        ("a/c.rs", "pub struct Thing;\nfn f() { crate::a::b::g() }\n"),
        ("a/d.rs", "use super::{b, c::Thing};\n#[cfg(test)]\nmod tests {\n    use crate::a::d;\n}\n"),
    ]
    .iter()
    .map(|(f, t)| (f.to_string(), t.to_string()))
    .collect();
    let graph = imports(&files);
    assert_eq!(graph["a/d.rs"], ["a/b.rs".to_string(), "a/c.rs".to_string()].into_iter().collect());
    assert_eq!(cycles(&graph), [vec!["a/b.rs".to_string(), "a/c.rs".to_string()]].into_iter().collect());
}

/// `file:line` of every flag name (`--` and a lowercase letter) in the library's files:
/// everything outside `cli/` and the binary's `main.rs`, comments included, clap
/// attributes (`#[arg(…)]`, `#[command(…)]`) left out. The library names parameters in its
/// own words; only the command line knows its flags (`cli/hints.rs`).
fn flag_names(files: &BTreeMap<String, String>) -> Vec<String> {
    let mut found = Vec::new();
    for (file, text) in files.iter().filter(|(f, _)| !f.starts_with("cli/") && *f != "main.rs") {
        for (n, line) in text.lines().enumerate() {
            let attribute = ["#[arg(", "#[command("].iter().any(|a| line.trim_start().starts_with(a));
            let flag = line
                .match_indices("--")
                .any(|(at, _)| line[at + 2..].chars().next().is_some_and(|c| c.is_ascii_lowercase()));
            if flag && !attribute {
                found.push(format!("{file}:{}: {}", n + 1, line.trim()));
            }
        }
    }
    found
}

#[test]
fn library_files_name_no_command_line_flag() {
    let found = flag_names(&sources());
    assert!(found.is_empty(), "flag names outside src/cli (say the parameter, see error::Param): {found:#?}");
}

#[test]
fn the_flag_check_sees_flags_in_messages_and_comments_but_not_in_the_cli() {
    let files: BTreeMap<String, String> = [
        ("a.rs", "// lower --scale\nlet x = 1; // a -- b, --7\n"),
        ("b.rs", "Err(Error::invalid(\"use --crop\"))\n#[arg(long = \"x\", help = \"--y\")]\n"),
        ("cli/c.rs", "usage(\"--plane\")\n"),
    ]
    .iter()
    .map(|(f, t)| (f.to_string(), t.to_string()))
    .collect();
    assert_eq!(
        flag_names(&files),
        ["a.rs:1: // lower --scale", "b.rs:1: Err(Error::invalid(\"use --crop\"))"]
    );
}
