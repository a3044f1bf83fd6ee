//! Object File Format (OFF), ASCII: an `OFF` header (also `COFF`, `NOFF`, … whose extra
//! per-vertex values are skipped), the counts `vertices faces edges` (on the header line
//! or the next), one vertex per line, then one face per line as `n i₁ … iₙ` (anything
//! after the indices, such as a colour, is skipped). `#` starts a comment. Polygons are
//! fan-triangulated.

use super::Soup;
use crate::{Error, Result};
use std::path::Path;

/// Parses OFF text.
pub fn parse(bytes: &[u8], path: &Path) -> Result<Soup> {
    let text = std::str::from_utf8(bytes)
        .map_err(|_| Error::format(path, "not an OFF file: the text is not UTF-8"))?;
    let mut lines = Lines::new(text);
    let (nv, nf) = header(&mut lines, path)?;
    // Guard allocations against absurd counts in a damaged header.
    let mut soup = Soup {
        positions: Vec::with_capacity(nv.min(text.len())),
        triangles: Vec::with_capacity(nf.min(text.len())),
    };
    for i in 0..nv {
        soup.positions.push(vertex(&mut lines, i, nv, path)?);
    }
    for f in 0..nf {
        face(&mut lines, f, nf, &mut soup.triangles, path)?;
    }
    Ok(soup)
}

/// Non-empty lines with comments removed, and their 1-based line numbers for messages.
struct Lines<'a> {
    inner: std::iter::Enumerate<std::str::Lines<'a>>,
    number: usize,
}

impl<'a> Lines<'a> {
    fn new(text: &'a str) -> Self {
        Lines { inner: text.lines().enumerate(), number: 0 }
    }

    fn next(&mut self) -> Option<&'a str> {
        for (i, line) in self.inner.by_ref() {
            let content = line.split('#').next().unwrap_or("").trim();
            if !content.is_empty() {
                self.number = i + 1;
                return Some(content);
            }
        }
        None
    }

    fn error(&self, path: &Path, message: String) -> Error {
        Error::format(path, format!("line {}: {message}", self.number))
    }
}

/// The vertex and face counts.
fn header(lines: &mut Lines, path: &Path) -> Result<(usize, usize)> {
    let first = lines.next().unwrap_or("");
    let mut words = first.split_whitespace();
    let keyword = words.next().unwrap_or("");
    if !keyword.ends_with("OFF") {
        return Err(Error::format(path, "not an OFF file: it does not start with 'OFF'"));
    }
    // 4OFF and nOFF have other than three coordinates per vertex.
    if keyword.starts_with('4') || keyword.starts_with('n') {
        return Err(Error::format(path, format!("'{keyword}' OFF variants are not supported")));
    }
    let mut rest: Vec<&str> = words.collect();
    if rest.first() == Some(&"BINARY") {
        return Err(Error::format(path, "binary OFF is not supported; convert it to ASCII or PLY"));
    }
    if rest.is_empty() {
        rest = lines.next().unwrap_or("").split_whitespace().collect();
    }
    let count = |k: usize, what: &str| -> Result<usize> {
        rest.get(k)
            .and_then(|w| w.parse().ok())
            .ok_or_else(|| lines.error(path, format!("expected the {what} count after 'OFF'")))
    };
    Ok((count(0, "vertex")?, count(1, "face")?))
}

fn vertex(lines: &mut Lines, i: usize, nv: usize, path: &Path) -> Result<[f64; 3]> {
    let line = lines
        .next()
        .ok_or_else(|| Error::format(path, format!("the file ends after {i} of {nv} vertices")))?;
    let mut xyz = [0.0; 3];
    let mut words = line.split_whitespace();
    for c in &mut xyz {
        *c = words
            .next()
            .and_then(|w| w.parse().ok())
            .ok_or_else(|| lines.error(path, format!("vertex {i} needs three numbers, found '{line}'")))?;
    }
    Ok(xyz)
}

fn face(lines: &mut Lines, f: usize, nf: usize, out: &mut Vec<[i64; 3]>, path: &Path) -> Result<()> {
    let line =
        lines.next().ok_or_else(|| Error::format(path, format!("the file ends after {f} of {nf} faces")))?;
    let bad = || lines.error(path, format!("face {f} is not 'n i1 … in': '{line}'"));
    let mut words = line.split_whitespace();
    let n: usize = words.next().and_then(|w| w.parse().ok()).ok_or_else(bad)?;
    let indices: Vec<i64> = words.take(n).map(|w| w.parse().ok()).collect::<Option<_>>().ok_or_else(bad)?;
    if indices.len() != n {
        return Err(bad());
    }
    Soup::fan_triangulate(&indices, out);
    if n < 3 {
        tracing::warn!("{}: face {f} has {n} vertices; skipped", path.display());
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::{load, test_meshes::shared, topology};

    fn parse_str(s: &str) -> Result<Soup> {
        parse(s.as_bytes(), Path::new("t.off"))
    }

    #[test]
    fn reads_comments_counts_on_the_header_line_and_polygons() {
        let s = parse_str(
            "# a square and a triangle\nOFF 5 2 0\n0 0 0\n1 0 0 # corner\n1 1 0\n0 1 0\n\n0.5 2 0\n\
             4 0 1 2 3\n3 3 2 4 255 0 0\n",
        )
        .expect("parses");
        assert_eq!(s.positions.len(), 5);
        assert_eq!(s.positions[1], [1.0, 0.0, 0.0]);
        assert_eq!(s.triangles, vec![[0, 1, 2], [0, 2, 3], [3, 2, 4]]);
    }

    #[test]
    fn coff_vertex_colours_are_skipped() {
        let s =
            parse_str("COFF\n3 1 0\n0 0 0 1 0 0 1\n1 0 0 1 0 0 1\n0 1 0 1 0 0 1\n3 0 1 2\n").expect("parses");
        assert_eq!(s.positions[2], [0.0, 1.0, 0.0]);
    }

    #[test]
    fn truncated_and_malformed_files_are_errors_with_a_line_number() {
        let e = parse_str("OFF\n3 1 0\n0 0 0\n1 0 0\n").unwrap_err().to_string();
        assert!(e.contains("t.off: the file ends after 2 of 3 vertices"), "{e}");
        let e = parse_str("OFF\n3 1 0\n0 0 0\n1 x 0\n0 1 0\n3 0 1 2\n").unwrap_err().to_string();
        assert!(e.contains("t.off: line 4: vertex 1 needs three numbers"), "{e}");
        let e = parse_str("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1\n").unwrap_err().to_string();
        assert!(e.contains("line 6: face 0"), "{e}");
        assert!(parse_str("PLY\n").unwrap_err().to_string().contains("not an OFF file"));
        assert!(parse_str("OFF\nthree 1 0\n").is_err());
    }

    #[test]
    fn nan_vertex_fails_in_validation_naming_the_file() {
        let dir = tempfile::tempdir().expect("temp dir");
        let path = dir.path().join("nan.off");
        std::fs::write(&path, "OFF\n3 1 0\n0 0 0\nnan 0 0\n0 1 0\n3 0 1 2\n").expect("write");
        let e = load(&path).unwrap_err().to_string();
        assert!(e.contains("nan.off: vertex 1 has a non-finite coordinate"), "{e}");
        assert_eq!(e.lines().count(), 1);
    }

    #[test]
    fn out_of_range_index_fails_naming_the_file() {
        let dir = tempfile::tempdir().expect("temp dir");
        let path = dir.path().join("range.off");
        std::fs::write(&path, "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n").expect("write");
        let e = load(&path).unwrap_err().to_string();
        assert!(e.contains("range.off: face 0 refers to vertex 3"), "{e}");
        assert_eq!(e.lines().count(), 1);
    }

    #[test]
    fn bunny_37k_loads_closed() {
        let Some(path) = shared("bunny_37k_loads_closed", "bunny-37k.off") else { return };
        let s = topology::summary(&load(&path).expect("loads"));
        assert_eq!((s.vertices, s.faces, s.boundary_edges), (37706, 75408, 0));
    }
}
