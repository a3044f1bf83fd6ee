//! `render`: the identity map reproduces the sample, shadows fall where geometry puts them,
//! a sequence is written in full, and bad input is refused with nothing written.

use crate::common;

use btfsynth::btf::{DirectionPair, DirectionSet};
use btfsynth::mesh::frames::Frames;
use btfsynth::mesh::Mesh;
use btfsynth::render::ambient::{Ambient, AmbientCache, AmbientLight, CellVisibility};
use btfsynth::render::cpu::{render, RenderOptions, Tracer};
use btfsynth::render::environment::cell_solid_angle;
use btfsynth::render::scene::Shadows;
use btfsynth::render::shadow_map::{shadow_map_size, ShadowCaster};
use btfsynth::render::{Camera, Environment, Material, Mode, Projection, Scene, Shot};
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
    Scene::new(mesh, frames, uv, vec![0; n], 1.0)
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
            let image = material.image(i as u32);
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
    let scene = Scene::new(mesh, frames, vec![Vec2::ZERO; n], vec![0; n], 1.0);
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
    let bunny = common::BUNNY;
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
    common::assert_usage_error(&btfsynth(&["render", ply, "--frames", "0", "-o", out]), "--frames");
    for bad in [["--spp", "3"], ["--env", "nowhere.hdr"], ["--ambient", "-0.5"]] {
        let r = btfsynth(&[&["render", ply, "-o", out][..], &bad].concat());
        let stderr = String::from_utf8_lossy(&r.stderr);
        assert!(
            !r.status.success() && stderr.lines().count() == 1 && stderr.contains(bad[1]),
            "{bad:?}: {stderr}"
        );
    }
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
    let relighter = btfsynth::render::scene::Relighter::new(&scene, &material, &camera, None);
    for (theta, phi) in [(10.0, 0.0), (50.0, 100.0), (80.0, 250.0), (120.0, 10.0)] {
        let light = btfsynth::render::camera::world_direction(theta, phi);
        let blends = scene.vertex_blends(&material, &Shot { camera, light });
        let expected = scene.vertex_colours(&material, &blends, None);
        let got = relighter.colours(&material, light, Shadows::None);
        for (a, b) in got.iter().zip(&expected) {
            assert!((*a - *b).length() < 1e-5, "light {theta},{phi}: {a} vs {b}");
        }
    }
}

/// A ubo81 material of `w × h` whose images are ρ × cos θ_light, as a measured BTF's are
/// (ρ random per image and texel).
fn cosine_material(w: usize, h: usize) -> Material {
    let pairs = DirectionSet::Ubo81.pairs();
    let rho: Vec<f32> =
        (0..pairs.len() * w * h * 3).map(|i| btfsynth::seeded::unit(11, i as i64, 0, 0)).collect();
    let pixels = rho.iter().enumerate().map(|(i, r)| r * pairs[i / (w * h * 3)].light.unit().z).collect();
    Material::new(w, h, pixels, pairs).unwrap()
}

/// Renders `scene` from `camera` lit by `environment` alone (no directional light).
fn render_environment(
    scene: &Scene,
    material: &Material,
    camera: Camera,
    environment: Environment,
    mode: Mode,
) -> btfsynth::render::Frame {
    let tracer = Tracer::new(&scene.mesh);
    let mut cache = AmbientCache::new(scene, material, environment, true);
    let (ambient, _) = cache.for_camera((scene, material), &camera, Some(&tracer));
    let options = RenderOptions { mode, spp: 1, sun: 0.0, ..RenderOptions::default() };
    render(scene, material, &tracer, &Shot { camera, light: Vec3::Y }, options, Some(ambient))
}

#[test]
fn a_uniform_sky_renders_a_flat_sample_as_the_cosine_weighted_mean_of_its_images() {
    let (w, h) = (9, 6);
    let material = cosine_material(w, h);
    let scene = identity_grid((-1, w as i32), (-1, h as i32));
    let frame = render_environment(
        &scene,
        &material,
        camera_above(w as u32, h as u32),
        Environment::uniform(Vec3::ONE),
        Mode::Pixel,
    );
    // Independently: the solid angle of each light's Voronoi cell (beyond 75°, weighted by the
    // cosine ratio the model documents), by brute force over a jittered 512 × 2048 grid.
    let lights = material.light_index();
    let (rows, columns) = (512, 2048);
    let mut cells = vec![0.0f64; lights.len()];
    for y in 0..rows {
        let step = std::f64::consts::FRAC_PI_2 / rows as f64;
        let (z0, z1) = ((step * y as f64).cos(), (step * (y + 1) as f64).cos());
        for x in 0..columns {
            let (u, v) =
                (btfsynth::seeded::unit(12, y, x, 0) as f64, btfsynth::seeded::unit(12, y, x, 1) as f64);
            let z = z0 - u * (z0 - z1);
            let phi = std::f64::consts::TAU * (x as f64 + v) / columns as f64;
            let r = (1.0 - z * z).sqrt();
            let q = Vec3::new((r * phi.cos()) as f32, (r * phi.sin()) as f32, z as f32);
            let nearest = (0..lights.len())
                .max_by(|&a, &b| q.dot(lights.units()[a]).total_cmp(&q.dot(lights.units()[b])))
                .unwrap();
            let ratio = (z / 75f64.to_radians().cos()).min(1.0);
            cells[nearest] += std::f64::consts::TAU / columns as f64 * (z0 - z1) * ratio;
        }
    }
    // The view straight down is view 0 of the dome.
    let images: Vec<Vec<f32>> =
        (0..lights.len()).map(|l| material.image(material.image_of(0, l as u32).unwrap())).collect();
    let mut worst = 0.0f64;
    for k in 0..w * h * 3 {
        let expected: f64 = images
            .iter()
            .zip(&cells)
            .map(|(image, cell)| image[k] as f64 * cell / std::f64::consts::PI)
            .sum();
        let got = frame.rgba[(k / 3) * 4 + k % 3] as f64;
        worst = worst.max((got - expected).abs());
    }
    eprintln!("largest difference from Σ image × cell / π: {worst:.2e}");
    assert!(worst < 1e-3, "largest difference from Σ image × cell / π: {worst}");
    // For a Lambertian sample (ρ the same under every light) that is the cosine-weighted
    // mean of ρ: the cells' Σ cos θ Ω / π comes within a few percent of 1.
    let cosine_sum: f64 =
        (0..lights.len()).map(|l| lights.units()[l].z as f64 * cells[l]).sum::<f64>() / std::f64::consts::PI;
    eprintln!("Σ cos θ Ω / π = {cosine_sum:.4}");
    assert!((cosine_sum - 1.0).abs() < 0.03, "Σ cos θ Ω / π = {cosine_sum}");
}

#[test]
fn an_environment_lit_from_one_measured_direction_reproduces_that_directional_render() {
    let (w, h) = (9, 6);
    let material = cosine_material(w, h);
    let scene = identity_grid((-1, w as i32), (-1, h as i32));
    let camera = camera_above(w as u32, h as u32);
    // Light θ = 45°, φ = 0 in the quad's frame (s = +X, t = −Z, n = +Y) is the world
    // direction θ = 45°, φ = 90°: the centre of pixel (1, 1) of a 6 × 6 equirectangular map.
    let (cols, rows) = (6, 6);
    let local = btfsynth::btf::Direction::new(45.0, 0.0).unwrap().unit();
    let world = Vec3::new(local.x, local.z, -local.y);
    assert!((world - btfsynth::render::camera::world_direction(45.0, 90.0)).length() < 1e-6);
    let mut map = vec![Vec3::ZERO; cols * rows];
    // Power π from there: what a directional light of strength 1 delivers.
    map[cols + 1] = Vec3::splat(std::f32::consts::PI / cell_solid_angle(1, cols, rows));
    let environment = Environment::from_equirect(cols, rows, &map).unwrap();
    for mode in [Mode::Pixel, Mode::Vertex] {
        let lit = render_environment(&scene, &material, camera, environment.clone(), mode);
        let tracer = Tracer::new(&scene.mesh);
        let options = RenderOptions { mode, spp: 1, ..RenderOptions::default() };
        let direct = render(&scene, &material, &tracer, &Shot { camera, light: world }, options, None);
        let worst = lit.rgba.iter().zip(&direct.rgba).map(|(a, b)| (a - b).abs()).fold(0.0, f32::max);
        let brightest = direct.rgba.chunks_exact(4).flat_map(|p| p[..3].to_vec()).fold(0.0, f32::max);
        eprintln!("{mode:?}: largest difference {worst:.2e}, brightest {brightest}");
        assert!(brightest > 0.1 && worst < 1e-4, "{mode:?}: largest difference {worst}");
    }
}

#[test]
fn an_environment_below_a_surface_lights_none_of_it() {
    let (w, h) = (5, 4);
    let material = cosine_material(w, h);
    let scene = identity_grid((-1, w as i32), (-1, h as i32));
    // A sky that is black above the horizon and bright below it.
    let environment =
        Environment::from_function((32, 16), |d| if d.y < 0.0 { Vec3::splat(3.0) } else { Vec3::ZERO });
    let frame =
        render_environment(&scene, &material, camera_above(w as u32, h as u32), environment, Mode::Pixel);
    assert!(frame.rgba.chunks_exact(4).all(|p| p[..3] == [0.0; 3] && p[3] == 1.0));
}

/// Mean absolute RGBA difference over the pixels where `reference`'s coverage is partial
/// (the silhouette) or its colour changes sharply (shadow edges).
fn edge_error(frame: &btfsynth::render::Frame, reference: &btfsynth::render::Frame) -> f64 {
    let (w, h) = (reference.width, reference.height);
    let mut edges = Vec::new();
    for y in 1..h - 1 {
        for x in 1..w - 1 {
            let p = reference.pixel(x, y);
            let jump = [(1, 0), (0, 1)].iter().any(|&(dx, dy)| {
                let (a, b) = (reference.pixel(x - dx, y - dy), reference.pixel(x + dx, y + dy));
                (a[0] - b[0]).abs() > 0.2
            });
            if (p[3] > 0.0 && p[3] < 1.0) || jump {
                edges.push((x, y));
            }
        }
    }
    assert!(edges.len() > 50, "{} edge pixels", edges.len());
    let sum: f64 = edges
        .iter()
        .map(|&(x, y)| {
            (0..4).map(|c| (frame.pixel(x, y)[c] - reference.pixel(x, y)[c]).abs() as f64).sum::<f64>()
        })
        .sum();
    sum / (4 * edges.len()) as f64
}

#[test]
fn four_samples_per_pixel_bring_edges_closer_to_a_64_sample_reference_than_one() {
    let (mut positions, mut triangles) = (Vec::new(), Vec::new());
    add_sphere(&mut positions, &mut triangles, Vec3::new(0.0, 3.0, 0.0), 2.0);
    let plane = identity_grid((-6, 6), (-6, 6));
    let base = positions.len() as u32;
    positions.extend_from_slice(plane.mesh.positions());
    triangles.extend(plane.mesh.triangles().iter().map(|t| t.map(|v| v + base)));
    let mesh = Mesh::new(positions, triangles).unwrap().with_normals();
    let n = mesh.vertex_count();
    let frames = Frames::from_directions(mesh.normals().unwrap(), &vec![Vec3::X; n]);
    let scene = Scene::new(mesh, frames, vec![Vec2::ZERO; n], vec![0; n], 1.0);
    let white =
        DirectionPair { light: btfsynth::btf::Direction::NORMAL, view: btfsynth::btf::Direction::NORMAL };
    let material = Material::new(1, 1, vec![0.8; 3], vec![white]).unwrap();
    let tracer = Tracer::new(&scene.mesh);
    let camera = Camera::framing(Vec3::new(0.0, 1.0, 0.0), 7.0, Vec3::new(0.3, 0.8, 1.0), false, (96, 96));
    let shot = Shot { camera, light: btfsynth::render::camera::world_direction(40.0, 60.0) };
    let at = |spp| {
        render(&scene, &material, &tracer, &shot, RenderOptions { spp, ..RenderOptions::default() }, None)
    };
    let reference = at(64);
    let (one, four) = (edge_error(&at(1), &reference), edge_error(&at(4), &reference));
    eprintln!("edge error against 64 spp: {one:.4} at 1 spp, {four:.4} at 4 spp");
    assert!(four < 0.7 * one, "4 spp: {four}, 1 spp: {one}");
}

#[test]
fn relight_shows_a_measured_pair_as_its_image_and_refuses_bad_angles() {
    let dir = tempfile::tempdir().unwrap();
    let stack = dir.path().join("stack");
    let r = btfsynth(&[
        "-q",
        "gen",
        "pebbles",
        "--size",
        "16",
        "--directions",
        "grid:9",
        "--spp",
        "1",
        "-o",
        stack.to_str().unwrap(),
    ]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let btf = btfsynth::btf::load(&stack, &Default::default(), &btfsynth::progress::Silent).unwrap();
    let i = 40;
    let pair = btf.pairs()[i];
    let out = dir.path().join("relit.exr");
    let (view, light) = (
        format!("{},{}", pair.view.theta, pair.view.phi),
        format!("{},{}", pair.light.theta, pair.light.phi),
    );
    let r = btfsynth(&[
        "-q",
        "relight",
        stack.to_str().unwrap(),
        "--view",
        &view,
        "--light",
        &light,
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let image = image::open(&out).unwrap().into_rgba32f();
    assert_eq!(image.dimensions(), (16, 16));
    for (k, p) in image.pixels().enumerate() {
        let expected = btf.rgb(i, k % 16, k / 16);
        assert!((0..3).all(|c| (p[c] - expected[c]).abs() < 1e-6), "pixel {k}: {p:?} vs {expected:?}");
    }
    // Under the sky as well (its sun along --light): brighter than the sun alone.
    let sky = dir.path().join("sky.png");
    let r = btfsynth(&[
        "-q",
        "relight",
        stack.to_str().unwrap(),
        "--view",
        &view,
        "--light",
        &light,
        "--env",
        "sky",
        "-o",
        sky.to_str().unwrap(),
    ]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let before = entries(dir.path());
    let bad = dir.path().join("bad.png");
    let bad = bad.to_str().unwrap();
    let s = stack.to_str().unwrap();
    for args in [
        vec!["relight", s, "--view", "95,0", "--light", "0,0", "-o", bad],
        vec!["relight", s, "--view", "0,0", "--light", "abc", "-o", bad],
        vec!["relight", s, "--view", "0,0", "--light", "0,0", "--ambient", "-1", "-o", bad],
    ] {
        let r = btfsynth(&args);
        assert_eq!(r.status.code(), Some(2), "{args:?}");
        assert_eq!(String::from_utf8_lossy(&r.stderr).lines().count(), 1);
    }
    // Nothing to light the sample, or an output of no image format: command-line mistakes.
    common::assert_usage_error(&btfsynth(&["relight", s, "--view", "0,0", "-o", bad]), "--light");
    assert_one_line_error(
        &btfsynth(&["relight", s, "--view", "0,0", "--light", "0,0", "-o", out.to_str().unwrap()]),
        "already exists",
    );
    common::assert_usage_error(
        &btfsynth(&["relight", s, "--view", "0,0", "--light", "0,0", "-o", &bad.replace(".png", ".bmp")]),
        ".png or .exr",
    );
    let missing = dir.path().join("none.hdr");
    assert_one_line_error(
        &btfsynth(&["relight", s, "--view", "0,0", "--env", missing.to_str().unwrap(), "-o", bad]),
        "none.hdr",
    );
    assert_eq!(entries(dir.path()), before, "nothing written by the failed runs");
}

#[test]
fn relighting_only_what_the_camera_can_see_keeps_every_visible_triangle_and_its_shadows() {
    let plane = identity_grid((-20, 20), (-20, 20));
    let (mut positions, mut triangles) = (plane.mesh.positions().to_vec(), plane.mesh.triangles().to_vec());
    add_sphere(&mut positions, &mut triangles, Vec3::new(0.0, 8.0, 0.0), 5.0);
    let mesh = Mesh::new(positions, triangles).unwrap().with_normals();
    let n = mesh.vertex_count();
    let frames = Frames::from_directions(mesh.normals().unwrap(), &vec![Vec3::X; n]);
    let uv = (0..n).map(|v| Vec2::new((v % 5) as f32, (v / 5 % 4) as f32)).collect();
    let scene = Scene::new(mesh, frames, uv, vec![0; n], 1.0);
    let (w, h) = (5, 4);
    let pairs = DirectionSet::Grid(16).pairs();
    let pixels = (0..pairs.len() * w * h * 3).map(|i| btfsynth::seeded::unit(13, i as i64, 0, 0)).collect();
    let material = Material::new(w, h, pixels, pairs).unwrap();
    let tracer = Tracer::new(&scene.mesh);
    let camera = Camera::framing(Vec3::new(0.0, 4.0, 0.0), 25.0, Vec3::new(0.2, 0.5, 1.0), false, (128, 128));
    let relighter = btfsynth::render::scene::Relighter::new(&scene, &material, &camera, Some(&tracer));
    assert!(relighter.relit() < n * 3 / 4, "{} of {n} vertices relit", relighter.relit());
    let needed = scene.seen_triangle_corners(&camera, &tracer);
    // Every triangle a pixel shows has all its corners relit.
    for y in 0..128 {
        for x in 0..128 {
            let (origin, direction) = camera.ray(x as f32 + 0.5, y as f32 + 0.5);
            if let Some(hit) = tracer.closest(origin, direction) {
                let corners = scene.mesh.triangles()[hit.triangle];
                assert!(corners.iter().all(|&v| needed[v as usize]), "pixel ({x}, {y}) shows {corners:?}");
            }
        }
    }
    // The relit vertices have the colours of full vertex shading with shadow rays.
    for light in [
        btfsynth::render::camera::world_direction(30.0, 20.0),
        btfsynth::render::camera::world_direction(60.0, 200.0),
    ] {
        let shot = Shot { camera, light };
        let lit = btfsynth::render::cpu::vertex_lit(&scene, &tracer, light);
        let expected = scene.vertex_colours(&material, &scene.vertex_blends(&material, &shot), Some(&lit));
        let got = relighter.colours(&material, light, Shadows::Rays(&tracer));
        let shadowed =
            (0..n).filter(|&v| needed[v] && scene.normals()[v].dot(light) > 0.0 && !lit[v]).count();
        assert!(shadowed > 20, "{shadowed} relit vertices in shadow");
        for v in (0..n).filter(|&v| needed[v]) {
            assert!((got[v] - expected[v]).length() < 1e-5, "vertex {v}: {} vs {}", got[v], expected[v]);
        }
        // A shadow map instead of rays: the same but for vertices within a texel of the
        // sphere's shadow edge (where the light grazes the sphere: miss distance = radius).
        let map = ShadowCaster::new(&scene.mesh).map(light, shadow_map_size(n));
        let by_map = relighter.colours(&material, light, Shadows::Map(&map));
        let differ: Vec<usize> =
            (0..n).filter(|&v| (by_map[v] == Vec3::ZERO) != (got[v] == Vec3::ZERO)).collect();
        for &v in &differ {
            let to_centre = Vec3::new(0.0, 8.0, 0.0) - scene.mesh.positions()[v];
            let miss = (to_centre - light * to_centre.dot(light)).length();
            assert!((miss - 5.0).abs() < map.texel(), "vertex {v}: {miss} from the sphere's centre");
        }
        assert!(differ.len() * 10 < shadowed, "{} vertices differ, {shadowed} in shadow", differ.len());
    }
}

#[test]
fn shading_the_environment_only_where_the_camera_may_look_changes_no_pixel() {
    let plane = identity_grid((-12, 12), (-12, 12));
    let (mut positions, mut triangles) = (plane.mesh.positions().to_vec(), plane.mesh.triangles().to_vec());
    add_sphere(&mut positions, &mut triangles, Vec3::new(0.0, 6.0, 0.0), 4.0);
    let mesh = Mesh::new(positions, triangles).unwrap().with_normals();
    let n = mesh.vertex_count();
    let frames = Frames::from_directions(mesh.normals().unwrap(), &vec![Vec3::X; n]);
    let uv = (0..n).map(|v| Vec2::new((v % 5) as f32 + 0.25, (v / 5 % 4) as f32)).collect();
    let scene = Scene::new(mesh, frames, uv, vec![0; n], 1.0);
    let material = cosine_material(5, 4);
    let tracer = Tracer::new(&scene.mesh);
    let camera = Camera::framing(Vec3::new(0.0, 3.0, 0.0), 15.0, Vec3::new(0.3, 0.6, 1.0), false, (96, 96));
    let shot = Shot { camera, light: btfsynth::render::camera::world_direction(50.0, 30.0) };
    let mut cache = AmbientCache::new(&scene, &material, Environment::sky(), true);
    let (culled, _) = cache.for_camera((&scene, &material), &camera, Some(&tracer));
    let light = AmbientLight::new(&material, Environment::sky());
    let mut visibility = CellVisibility::new(n, material.light_index().len());
    visibility.trace(&scene, &material, &tracer, &vec![true; n]);
    let full = Ambient::compute(&scene, &material, &light, &camera, (Some(&visibility), None));
    assert!(culled.texels().iter().filter(|t| **t == Vec3::ZERO).count() > full.texels().len() / 4);
    let options = RenderOptions::default();
    let a = render(&scene, &material, &tracer, &shot, options, Some(culled));
    let b = render(&scene, &material, &tracer, &shot, options, Some(&full));
    assert!(a.rgba.iter().any(|&c| c > 0.0));
    assert_eq!(a, b, "the same frame");
}
