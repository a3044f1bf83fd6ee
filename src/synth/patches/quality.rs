//! How visible the seams of a texture-mapped surface are: the project's patch energy
//! (mean squared difference of a 7×7 window to its nearest 7×7 patch of the sample, sRGB)
//! of windows resampled on the surface itself, split into windows that straddle a border
//! between patches and windows inside one patch.
//!
//! A window is centred on a face's centroid, aligned with that face's texture and one
//! sample texel per pixel; the faces around are unfolded rigidly into its plane, and each
//! pixel takes the texture of the face it falls in. Inside a patch the windows measure the
//! mapping's distortion (a rigid, undistorted patch scores 0); across a border, its seam.

use super::chart::unfold;
use super::fit::FitImage;
use super::graph::{SurfaceGraph, NONE};
use super::mapping::raster;
use crate::eval::picture::{nearest_patch_energy, PATCH_SIDE};
use crate::eval::Picture;
use crate::Result;
use glam::{Vec2, Vec3};
use rand::seq::SliceRandom;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use std::collections::{HashMap, VecDeque};
use std::path::Path;

/// Patch energies of border and interior windows.
#[derive(Clone, Copy, Debug, serde::Serialize)]
pub struct SeamQuality {
    /// Mean patch energy of windows with texels of two or more patches.
    pub border: f64,
    /// Mean patch energy of windows inside one patch.
    pub interior: f64,
    pub border_windows: usize,
    pub interior_windows: usize,
}

/// Measures the mapping `corner_uv` (per file face, per corner, sample texels) with its
/// per-face `cluster` on the mesh `positions`/`triangles` against `sample` (the image the
/// coordinates index), at `texels_per_unit`, from at most `windows` faces drawn with `seed`.
#[allow(clippy::too_many_arguments)]
pub fn seam_quality(
    positions: &[Vec3],
    triangles: &[[u32; 3]],
    corner_uv: &[[Vec2; 3]],
    cluster: &[u32],
    sample: &Picture,
    tileable: bool,
    texels_per_unit: f32,
    (windows, seed): (usize, u64),
) -> Result<SeamQuality> {
    let graph = SurfaceGraph::new(positions, triangles, Path::new("<mapped mesh>"))?;
    // Per graph face, its coordinates in its own corner order.
    let uv: Vec<[Vec2; 3]> = (0..graph.face_count())
        .map(|g| {
            let f = graph.file_face[g] as usize;
            let order = graph.file_corner[g];
            [0, 1, 2].map(|k| corner_uv[f][order[k] as usize])
        })
        .collect();
    let owner: Vec<u32> = graph.file_face.iter().map(|&f| cluster[f as usize]).collect();
    let mut faces: Vec<u32> =
        (0..graph.face_count() as u32).filter(|&g| graph.area[g as usize] > 0.0).collect();
    faces.shuffle(&mut ChaCha8Rng::seed_from_u64(seed));
    faces.truncate(windows);
    let side = PATCH_SIDE;
    let half = (side / 2) as f32;
    let (mut border, mut interior) = (Vec::new(), Vec::new());
    for &f in &faces {
        let Some((values, clusters)) =
            window(&graph, &uv, &owner, f, sample, tileable, texels_per_unit, half)
        else {
            continue;
        };
        if clusters > 1 {
            border.extend(values);
        } else {
            interior.extend(values);
        }
    }
    let dims = side * side * 3;
    let energy = |values: Vec<f32>| {
        let rows = values.len() / dims;
        match ndarray::Array2::from_shape_vec((rows, dims), values) {
            Ok(q) if rows > 0 => nearest_patch_energy(&q, sample, tileable),
            _ => f64::NAN,
        }
    };
    let (border_windows, interior_windows) = (border.len() / dims, interior.len() / dims);
    Ok(SeamQuality { border: energy(border), interior: energy(interior), border_windows, interior_windows })
}

/// The jump in texture across patch borders: at 9 points along every edge between faces
/// of two patches, the squared difference between the two sides' texture in `sample` (the
/// fitting space), as a fraction of two random texels' (2 in that space). Returns the mean
/// and the number of points; NaN without a border. Unlike [`seam_quality`]'s windows, this
/// looks at the border alone, so the sample's own edges (a pebble's outline) do not hide it.
pub fn border_discontinuity(
    positions: &[Vec3],
    triangles: &[[u32; 3]],
    corner_uv: &[[Vec2; 3]],
    cluster: &[u32],
    sample: &FitImage,
) -> Result<(f64, usize)> {
    let graph = SurfaceGraph::new(positions, triangles, Path::new("<mapped mesh>"))?;
    let (mut total, mut n) = (0f64, 0usize);
    let (mut a, mut b) = (vec![0f32; sample.channels], vec![0f32; sample.channels]);
    // The coordinate of graph vertex `v` in graph face `g`, from the file face's corners.
    let uv_of = |g: usize, v: u32| {
        let k = graph.corner_of(g as u32, v).unwrap_or(0);
        corner_uv[graph.file_face[g] as usize][graph.file_corner[g][k] as usize]
    };
    for f in 0..graph.face_count() {
        for k in 0..3 {
            let g = graph.across[f][k];
            if g == NONE || (g as usize) < f {
                continue;
            }
            let g = g as usize;
            if cluster[graph.file_face[f] as usize] == cluster[graph.file_face[g] as usize] {
                continue;
            }
            let (va, vb) = (graph.corners[f][k], graph.corners[f][(k + 1) % 3]);
            let (pa, pb, qa, qb) = (uv_of(f, va), uv_of(f, vb), uv_of(g, va), uv_of(g, vb));
            for i in 0..=8 {
                let t = i as f32 / 8.0;
                sample.sample(pa.lerp(pb, t), &mut a);
                sample.sample(qa.lerp(qb, t), &mut b);
                total += a.iter().zip(&b).map(|(x, y)| f64::from((x - y) * (x - y))).sum::<f64>() / 2.0;
                n += 1;
            }
        }
    }
    Ok((if n > 0 { total / n as f64 } else { f64::NAN }, n))
}

/// The window around face `f`: its 7×7×3 sRGB values and how many patches it shows; None
/// if part of it lies off the surface.
#[allow(clippy::too_many_arguments)]
fn window(
    graph: &SurfaceGraph,
    uv: &[[Vec2; 3]],
    owner: &[u32],
    f: u32,
    sample: &Picture,
    tileable: bool,
    scale: f32,
    half: f32,
) -> Option<(Vec<f32>, usize)> {
    let side = PATCH_SIDE;
    let t = graph.corners[f as usize];
    let centre = (uv[f as usize][0] + uv[f as usize][1] + uv[f as usize][2]) / 3.0;
    // The window's frame: face f's own texture coordinates, then its neighbours unfolded.
    let mut placed: HashMap<u32, Vec2> = (0..3).map(|k| (t[k], uv[f as usize][k])).collect();
    let mut faces: Vec<(u32, [Vec2; 3])> = vec![(f, uv[f as usize])];
    let mut seen: HashMap<u32, ()> = HashMap::from([(f, ())]);
    let mut queue: VecDeque<u32> = graph.across[f as usize].iter().copied().filter(|&g| g != NONE).collect();
    queue.iter().for_each(|&g| {
        seen.insert(g, ());
    });
    let reach = 2.0 * half + 2.0;
    while let Some(g) = queue.pop_front() {
        let c = graph.corners[g as usize];
        let known: Vec<bool> = c.iter().map(|v| placed.contains_key(v)).collect();
        if known.iter().filter(|&&k| k).count() == 2 {
            let k = (0..3).find(|&k| known[k] && known[(k + 1) % 3]).unwrap_or(0);
            let (a, b, apex) = (c[k], c[(k + 1) % 3], c[(k + 2) % 3]);
            let p = |v: u32| graph.positions[v as usize];
            let at = unfold(
                placed[&a],
                placed[&b],
                p(a).distance(p(apex)) * scale,
                p(b).distance(p(apex)) * scale,
            );
            placed.insert(apex, at);
        } else if known.iter().any(|&k| !k) {
            continue;
        }
        let corners = c.map(|v| placed[&v]);
        faces.push((g, corners));
        if corners.iter().all(|p| p.distance(centre) > reach) {
            continue;
        }
        for &n in &graph.across[g as usize] {
            if n != NONE && seen.insert(n, ()).is_none() {
                queue.push_back(n);
            }
        }
    }
    let origin = centre - Vec2::splat(half);
    let mut values = vec![f32::NAN; side * side * 3];
    let mut patches: Vec<u32> = Vec::new();
    for (g, corners) in &faces {
        let p = corners.map(|c| c - origin);
        let tex = uv[*g as usize];
        raster(&p, side, side, |x, y, b| {
            let o = (y * side + x) * 3;
            if !values[o].is_nan() {
                return;
            }
            let s = b[0] * tex[0] + b[1] * tex[1] + b[2] * tex[2];
            let rgb = bilinear(sample, s, tileable);
            values[o..o + 3].copy_from_slice(&rgb);
            if !patches.contains(&owner[*g as usize]) {
                patches.push(owner[*g as usize]);
            }
        });
    }
    if values.iter().any(|v| v.is_nan()) {
        return None;
    }
    Some((values, patches.len()))
}

fn bilinear(picture: &Picture, s: Vec2, tileable: bool) -> [f32; 3] {
    let (w, h) = (picture.width as i64, picture.height as i64);
    let at = |x: i64, y: i64| {
        let (x, y) = if tileable {
            (x.rem_euclid(w), y.rem_euclid(h))
        } else {
            (x.clamp(0, w - 1), y.clamp(0, h - 1))
        };
        picture.rgb[y as usize * picture.width + x as usize]
    };
    let (x0, y0) = (s.x.floor(), s.y.floor());
    let (fx, fy) = (s.x - x0, s.y - y0);
    let (x0, y0) = (x0 as i64, y0 as i64);
    let mut out = [0f32; 3];
    for (dx, dy, w) in
        [(0, 0, (1.0 - fx) * (1.0 - fy)), (1, 0, fx * (1.0 - fy)), (0, 1, (1.0 - fx) * fy), (1, 1, fx * fy)]
    {
        let p = at(x0 + dx, y0 + dy);
        for c in 0..3 {
            out[c] += w * p[c];
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::super::fit::{ColourSpace, FitImage};
    use super::super::{map_mesh, SolerParams};
    use super::*;
    use crate::btf::image_io::srgb_to_linear;

    /// A real photograph on the bunny: matching each patch to its neighbours leaves seams
    /// far fainter than placing the patches at random, and not far above the patches' own
    /// distortion.
    ///
    /// "Fainter" is the jump across the borders ([`border_discontinuity`]): the windows'
    /// patch energy hardly tells the two apart (0.0082 matched, 0.0086 random, jumps 0.30
    /// and 0.82), because a pebble photograph's own outlines look like seams to it and
    /// random placement, never refused for a poor fit, keeps larger patches and so puts its
    /// windows elsewhere (346 border windows against 585).
    #[test]
    fn matched_seams_on_a_photograph_are_fainter_than_random_ones() {
        let test = "matched_seams_on_a_photograph_are_fainter_than_random_ones";
        let Some(photo) = crate::testdata::shared_data(test, "textures/sh3d-pebbles.jpg") else { return };
        let image = image::open(&photo).expect("photo").to_rgb32f();
        let side = 128usize;
        let at = |x: usize, y: usize| image.get_pixel(x as u32, y as u32).0;
        let sample = Picture {
            width: side,
            height: side,
            rgb: (0..side * side).map(|i| at(i % side, i / side)).collect(),
        };
        let fit =
            FitImage::from_rgb(side, side, |x, y| at(x, y).map(srgb_to_linear), ColourSpace::Lab, false)
                .expect("fit image");
        let path = crate::mesh::test_meshes::bundled("bunny-1k8.obj");
        let mesh = crate::mesh::textured::load_textured(&path).expect("bunny");
        let (lo, hi) = crate::mesh::bounds_of(&mesh.positions);
        let scale = 4.0 * side as f32 / (hi - lo).max_element();
        let measure = |matching: bool| {
            let params = SolerParams { texels_per_unit: scale, matching, ..SolerParams::default() };
            let m = map_mesh(
                &mesh.positions,
                &mesh.triangles,
                &path,
                fit.clone(),
                &params,
                &crate::progress::Silent,
            )
            .expect("mapped");
            let q = seam_quality(
                &mesh.positions,
                &mesh.triangles,
                &m.corner_uv,
                &m.cluster,
                &sample,
                false,
                scale,
                (3000, 1),
            )
            .expect("measured");
            let jump = border_discontinuity(&mesh.positions, &mesh.triangles, &m.corner_uv, &m.cluster, &fit)
                .expect("measured");
            (q, jump, m.report)
        };
        let (matched, matched_jump, report) = measure(true);
        let (random, random_jump, _) = measure(false);
        let mapped: Vec<usize> = report.levels.iter().map(|l| l.mapped).collect();
        eprintln!(
            "matched {matched:?} jump {matched_jump:?}\nrandom  {random:?} jump {random_jump:?}\nmapped per level {mapped:?}"
        );
        assert!(matched.border_windows > 100 && matched.interior_windows > 100, "{matched:?}");
        assert!(matched_jump.1 > 1000 && random_jump.1 > 1000, "{matched_jump:?} {random_jump:?}");
        assert!(matched_jump.0 < 0.5 * random_jump.0, "matched {matched_jump:?} random {random_jump:?}");
        assert!(matched.border < 3.0 * matched.interior, "{matched:?}");
    }
}
