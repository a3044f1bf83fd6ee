//! `render`: the identity map reproduces the sample, shadows fall where geometry puts them,
//! a sequence is written in full, and bad input is refused with nothing written.

mod common;

use btfsynth::btf::{DirectionPair, DirectionSet};
use btfsynth::mesh::frames::Frames;
use btfsynth::mesh::Mesh;
use btfsynth::render::cpu::{render, RenderOptions, Tracer};
use btfsynth::render::{Camera, Material, Mode, Projection, Scene, Shot};
use common::{assert_one_line_error, btfsynth, entries};
use glam::{Vec2, Vec3};

/// A grid of vertices at (x, 0, z) for x in x0..=x1, z in z0..=z1 (+Y up, s = +X, rows of
/// the sample running towards +Z), each mapped to its own texel (u, v) = (x, z).
fn identity_grid(x: (i32, i32), z: (i32, i32)) -> Scene {
    let (w, h) = ((x.1 - x.0 + 1) as u32, (z.1 - z.0 + 1) as u32);
    let positions = (z.0..=z.1).flat_map(|j| (x.0..=x.1).map(move |i| Vec3::new(i as f32, 0.0, j as f32)));
    let mut triangles = Vec::new();
    for j in 0..h - 1 {
        for i in 0..w - 1 {
            let at = |a: u32, b: u32| b * w + a;
            triangles.push([at(i, j), at(i, j + 1), at(i + 1, j + 1)]);
            triangles.push([at(i, j), at(i + 1, j + 1), at(i + 1, j)]);
        }
    }
    let mesh = Mesh::new(positions.collect(), triangles).unwrap().with_normals();
    let n = mesh.vertex_count();
    let uv = mesh.positions().iter().map(|p| Vec2::new(p.x, p.z)).collect();
    let frames = Frames::from_directions(&vec![Vec3::Y; n], &vec![Vec3::X; n]);
    Scene { mesh, frames, uv, labels: vec![0; n], texel: 1.0 }
}

/// An orthographic camera straight down -Y whose pixel (i, j) centre falls on (i, 0, j)
/// (nudged by a hair so rays do not land exactly on vertices).
fn camera_above(w: u32, h: u32) -> Camera {
    let centre = Vec3::new((w as f32 - 1.0) * 0.5 + 2e-4, 0.0, (h as f32 - 1.0) * 0.5 + 3e-4);
    Camera {
        eye: centre + Vec3::Y * 10.0,
        target: centre,
        up: Vec3::NEG_Z,
        projection: Projection::Orthographic { half_height: h as f32 * 0.5 },
        width: w,
        height: h,
        near: 1.0,
        far: 20.0,
    }
}

#[test]
fn the_identity_map_on_a_flat_quad_reproduces_the_sample_image() {
    let (w, h) = (9, 6);
    let pairs = DirectionSet::Ubo81.pairs();
    let pixels: Vec<f32> =
        (0..pairs.len() * w * h * 3).map(|i| btfsynth::seeded::unit(5, i as i64, 0, 0)).collect();
    let material = Material::new(w, h, pixels, pairs.clone()).unwrap();
    let scene = identity_grid((-1, w as i32), (-1, h as i32));
    let tracer = Tracer::new(&scene.mesh);
    let camera = camera_above(w as u32, h as u32);
    for (i, pair) in pairs.iter().enumerate().filter(|(_, p)| p.view.theta == 0.0).step_by(7) {
        // The light in the quad's frame (s = +X, t = n × s = -Z, n = +Y), in world space.
        let l = pair.light.unit();
        let shot = Shot { camera, light: Vec3::new(l.x, l.z, -l.y) };
        for mode in [Mode::Pixel, Mode::Vertex] {
            let options = RenderOptions { mode, spp: 1, ..RenderOptions::default() };
            let frame = render(&scene, &material, &tracer, &shot, options, None);
            let image = &material.pixels()[i * w * h * 3..(i + 1) * w * h * 3];
            let worst = (0..w * h * 3)
                .map(|k| (frame.rgba[(k / 3) * 4 + k % 3] - image[k]).abs())
                .fold(0.0, f32::max);
            assert!(worst < 1e-3, "{pair} in {mode:?} mode: max abs error {worst}");
        }
    }
}

/// A UV sphere of radius `r` at `centre`, appended to `positions`/`triangles`.
fn add_sphere(positions: &mut Vec<Vec3>, triangles: &mut Vec<[u32; 3]>, centre: Vec3, r: f32) {
    let (rings, segments) = (32u32, 64u32);
    let base = positions.len() as u32;
    positions.push(centre + Vec3::Y * r);
    for i in 1..rings {
        let theta = std::f32::consts::PI * i as f32 / rings as f32;
        for j in 0..segments {
            let phi = std::f32::consts::TAU * j as f32 / segments as f32;
            positions
                .push(centre + r * Vec3::new(theta.sin() * phi.cos(), theta.cos(), theta.sin() * phi.sin()));
        }
    }
    positions.push(centre - Vec3::Y * r);
    let ring = |i: u32, j: u32| base + 1 + (i - 1) * segments + j % segments;
    let bottom = base + 1 + (rings - 1) * segments;
    for j in 0..segments {
        triangles.push([base, ring(1, j + 1), ring(1, j)]);
        triangles.push([bottom, ring(rings - 1, j), ring(rings - 1, j + 1)]);
        for i in 1..rings - 1 {
            triangles.push([ring(i, j), ring(i, j + 1), ring(i + 1, j + 1)]);
            triangles.push([ring(i, j), ring(i + 1, j + 1), ring(i + 1, j)]);
        }
    }
}

#[test]
fn a_sphere_above_a_plane_casts_its_shadow_where_geometry_says() {
    let plane = identity_grid((-20, 20), (-20, 20));
    let (mut positions, mut triangles) = (plane.mesh.positions().to_vec(), plane.mesh.triangles().to_vec());
    let (centre, radius) = (Vec3::new(0.0, 8.0, 0.0), 5.0);
    add_sphere(&mut positions, &mut triangles, centre, radius);
    let mesh = Mesh::new(positions, triangles).unwrap().with_normals();
    let n = mesh.vertex_count();
    let frames = Frames::from_directions(mesh.normals().unwrap(), &vec![Vec3::X; n]);
    let scene = Scene { mesh, frames, uv: vec![Vec2::ZERO; n], labels: vec![0; n], texel: 1.0 };
    let white =
        DirectionPair { light: btfsynth::btf::Direction::NORMAL, view: btfsynth::btf::Direction::NORMAL };
    let material = Material::new(1, 1, vec![1.0; 3], vec![white]).unwrap();
    let tracer = Tracer::new(&scene.mesh);
    // 81 × 81 pixels over x, z in [-20, 20], half a unit apart.
    let mut camera = camera_above(81, 81);
    camera.target = Vec3::new(2e-4, 0.0, 3e-4);
    camera.eye = camera.target + Vec3::Y * 30.0;
    camera.far = 40.0;
    camera.projection = Projection::Orthographic { half_height: 20.25 };
    let light = btfsynth::render::camera::world_direction(30.0, 0.0);
    let options = RenderOptions { spp: 1, ..RenderOptions::default() };
    let frame = render(&scene, &material, &tracer, &Shot { camera, light }, options, None);
    let (mut shadowed, mut lit) = (0, 0);
    // The outermost pixels fall a hair beyond the plane's edge.
    for j in 1..80 {
        for i in 1..80 {
            let p = Vec3::new(i as f32 * 0.5 - 20.0, 0.0, j as f32 * 0.5 - 20.0);
            let (dx, dz) = (p.x - centre.x, p.z - centre.z);
            if (dx * dx + dz * dz).sqrt() < radius + 0.5 {
                continue; // the camera sees the sphere here, not the plane
            }
            // Distance from the sphere's centre to the ray from p towards the light.
            let to_centre = centre - p;
            let miss = (to_centre - light * to_centre.dot(light)).length();
            let value = frame.pixel(i, j)[0];
            if miss < radius - 0.3 {
                assert_eq!(value, 0.0, "({}, {}) lies in the sphere's shadow", p.x, p.z);
                shadowed += 1;
            } else if miss > radius + 0.3 {
                assert!(
                    (value - light.y).abs() < 1e-4,
                    "({}, {}) is lit: n·l = {}, got {value}",
                    p.x,
                    p.z,
                    light.y
                );
                lit += 1;
            }
        }
    }
    assert!(shadowed > 40 && lit > 3000, "{shadowed} shadowed and {lit} lit pixels checked");
}

/// A small surface map of the bundled bunny from a gravel analysis (built once per run).
fn surface(dir: &std::path::Path) -> (std::path::PathBuf, std::path::PathBuf) {
    let analysis = common::analyze_gravel_crop(dir, "analysis");
    let out = dir.join("bunny.ply");
    let bunny = concat!(env!("CARGO_MANIFEST_DIR"), "/data/bunny-1k8.obj");
    let args =
        ["-q", "synth", analysis.to_str().unwrap(), bunny, "--vertices", "3000", "-o", out.to_str().unwrap()];
    let r = btfsynth(&args);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    (analysis, out)
}

#[test]
fn render_writes_a_sequence_and_refuses_bad_input() {
    let dir = tempfile::tempdir().unwrap();
    let (analysis, ply) = surface(dir.path());
    let (ply, frames) = (ply.to_str().unwrap(), dir.path().join("frames"));
    let o = frames.to_str().unwrap();
    let r = btfsynth(&["-q", "render", ply, "--size", "96x64", "--frames", "3", "--compare", "-o", o]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let mut names = entries(&frames);
    names.sort();
    assert_eq!(names, ["contact.png", "frame_0000.exr", "frame_0001.exr", "frame_0002.exr"]);
    let first = image::open(frames.join("frame_0000.exr")).unwrap().into_rgba32f();
    assert_eq!(first.dimensions(), (192, 64), "--compare puts the sample beside the frame");
    let covered = first.pixels().filter(|p| p[3] == 1.0 && p[0] > 0.0).count();
    assert!(covered > 500, "the model and the quad are visible and lit: {covered} pixels");
    let r = btfsynth(&["-q", "render", ply, "--mode", "vertex", "--format", "png", "-o", o]);
    assert_one_line_error(&r, "already exists");

    let before = entries(dir.path());
    let elsewhere = dir.path().join("elsewhere");
    std::fs::create_dir(&elsewhere).unwrap();
    let moved = elsewhere.join("bunny.ply");
    std::fs::copy(ply, &moved).unwrap();
    std::fs::rename(&analysis, dir.path().join("gone")).unwrap();
    let out = dir.path().join("out");
    let out = out.to_str().unwrap();
    assert_one_line_error(&btfsynth(&["render", moved.to_str().unwrap(), "-o", out]), "analysis");
    std::fs::rename(dir.path().join("gone"), &analysis).unwrap();
    let blocked = dir.path().join("a-file");
    std::fs::write(&blocked, b"not a directory").unwrap();
    let under_file = blocked.join("frames");
    assert_one_line_error(&btfsynth(&["render", ply, "-o", under_file.to_str().unwrap()]), "a-file");
    let r = btfsynth(&["render", ply, "--size", "0x0", "-o", out]);
    assert_eq!(r.status.code(), Some(2), "a usage error");
    let stderr = String::from_utf8_lossy(&r.stderr);
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(stderr.starts_with("error: ") && stderr.contains("0x0"), "{stderr}");
    assert_one_line_error(&btfsynth(&["render", ply, "--frames", "0", "-o", out]), "--frames");
    let mut after = entries(dir.path());
    after.retain(|e| e != "elsewhere" && e != "a-file");
    let mut before = before;
    before.sort();
    after.sort();
    assert_eq!(after, before, "nothing written by the failed runs");
}

#[test]
fn relighting_with_kept_views_equals_full_vertex_shading() {
    let (w, h) = (5, 4);
    let pairs = DirectionSet::Grid(9).pairs();
    let pixels = (0..pairs.len() * w * h * 3).map(|i| btfsynth::seeded::unit(8, i as i64, 0, 0)).collect();
    let material = Material::new(w, h, pixels, pairs).unwrap();
    let scene = identity_grid((0, w as i32 - 1), (0, h as i32 - 1));
    let camera = Camera::framing(Vec3::ZERO, 5.0, Vec3::new(0.3, 1.0, 0.5), false, (16, 16));
    let relighter = btfsynth::render::scene::Relighter::new(&scene, &material, &camera);
    for (theta, phi) in [(10.0, 0.0), (50.0, 100.0), (80.0, 250.0), (120.0, 10.0)] {
        let light = btfsynth::render::camera::world_direction(theta, phi);
        let blends = scene.vertex_blends(&material, &Shot { camera, light });
        let expected = scene.vertex_colours(&material, &blends, None);
        let got = relighter.colours(&material, light);
        for (a, b) in got.iter().zip(&expected) {
            assert!((*a - *b).length() < 1e-5, "light {theta},{phi}: {a} vs {b}");
        }
    }
}
