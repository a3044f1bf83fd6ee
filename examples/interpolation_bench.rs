//! How well the shading core predicts images it was not given: a ubo81 stack is
//! subsampled (every second ring, or every second azimuth on each ring), and the dropped
//! (view, light) pairs are predicted from the rest, on the flat sample, by
//!
//! * **blend**: `Material::blend` (4 × 4 nearest, beyond the kept dome the outermost ring
//!   with the cosine ratio), as `render`, `view` and `relight` use it;
//! * **plain**: the same 4 × 4 inverse-distance weights without the beyond-dome model (how
//!   btfsynth blended before);
//! * **nearest**: the image of the nearest kept view and nearest kept light;
//! * **views²**: plain, with the view weights squared before normalising: a sharper view
//!   blend, the simplest guard against ghosting (parallax and highlights of different views
//!   superimposed) near the mirror direction, measured here against the others;
//!
//! and compared with the true images: PSNR over all pixels (peak 1, linear), for pairs with
//! both directions inside the kept dome's θ range, pairs with one beyond it, and pairs near
//! the mirror configuration (view within 20° of the light's reflection).
//!
//! `cargo run --release --example interpolation_bench -- STACK` where STACK is e.g.
//! `btfsynth gen pebbles --size 64 --directions ubo81 -o STACK`.

use btfsynth::btf::{Btf, DirectionPair};
use btfsynth::render::blend::angle;
use btfsynth::render::Material;
use glam::Vec3;

fn main() -> btfsynth::Result<()> {
    let path = std::env::args().nth(1).expect("usage: interpolation_bench STACK (a ubo81 stack)");
    let stack = btfsynth::btf::load(path.as_ref(), &Default::default(), &btfsynth::progress::Silent)?;
    println!("{} images of {}x{} from {path}", stack.len(), stack.width(), stack.height());
    let every_second_ring = |p: &DirectionPair| {
        [0.0, 30.0, 60.0].contains(&p.view.theta) && [0.0, 30.0, 60.0].contains(&p.light.theta)
    };
    let every_second_azimuth = |p: &DirectionPair| {
        kept_azimuth(p.view.theta, p.view.phi) && kept_azimuth(p.light.theta, p.light.phi)
    };
    for (name, keep) in [
        (
            "every second ring dropped (kept θ: 0, 30, 60°)",
            &every_second_ring as &dyn Fn(&DirectionPair) -> bool,
        ),
        ("every second azimuth dropped (kept θ up to 75°)", &every_second_azimuth),
    ] {
        report(&stack, name, keep)?;
    }
    Ok(())
}

/// Every second azimuth of a ring is kept (the pole always).
fn kept_azimuth(theta: f32, phi: f32) -> bool {
    let per_ring = [(0.0, 1), (15.0, 6), (30.0, 12), (45.0, 18), (60.0, 20), (75.0, 24)];
    let count = per_ring.iter().find(|r| r.0 == theta).map_or(1, |r| r.1);
    let k = (phi.rem_euclid(360.0) / (360.0 / count as f32)).round() as usize;
    count == 1 || k % 2 == 0
}

/// Squared error sums and pixel counts per class and predictor.
#[derive(Default)]
struct Tally {
    sums: [[f64; 4]; 3],
    counts: [usize; 3],
}

const CLASSES: [&str; 3] = ["inside the kept dome", "beyond it (view or light)", "near mirror (inside)"];
const PREDICTORS: [&str; 4] = ["blend", "plain", "nearest", "views²"];

fn report(stack: &Btf, name: &str, keep: &dyn Fn(&DirectionPair) -> bool) -> btfsynth::Result<()> {
    let kept: Vec<usize> = (0..stack.len()).filter(|&i| keep(&stack.pairs()[i])).collect();
    let (w, h) = (stack.width(), stack.height());
    let pixels: Vec<f32> = kept.iter().flat_map(|&i| stack.image(i).iter().map(|v| v.to_f32())).collect();
    let pairs: Vec<DirectionPair> = kept.iter().map(|&i| stack.pairs()[i]).collect();
    let material = Material::new(w, h, pixels, pairs)?;
    let theta_max = material.light_index().theta_max().max(material.view_index().theta_max());
    let mut tally = Tally::default();
    let dropped: Vec<usize> = (0..stack.len()).filter(|&i| !keep(&stack.pairs()[i])).collect();
    for &i in &dropped {
        let pair = stack.pairs()[i];
        let (view, light) = (pair.view.unit(), pair.light.unit());
        let beyond = view.z.acos().max(light.z.acos()) > theta_max + 1e-4;
        let mirror = Vec3::new(-light.x, -light.y, light.z);
        let classes: Vec<usize> = if beyond {
            vec![1]
        } else if angle(view, mirror) < 20f32.to_radians() {
            vec![0, 2]
        } else {
            vec![0]
        };
        let blend = material.blend(view, light);
        let plain = plain_blend(&material, view, light, 1.0);
        let sharp = plain_blend(&material, view, light, 2.0);
        let nearest =
            material.image_of(material.view_index().nearest(view), material.light_index().nearest(light));
        for t in 0..w * h {
            let (x, y) = ((t % w) as f32, (t / w) as f32);
            let truth = Vec3::from(stack.rgb(i, t % w, t / w));
            let predictions = [
                material.shade(&blend, x, y),
                shade_list(&material, &plain, x, y),
                nearest.map_or(Vec3::ZERO, |image| material.texel(image, x, y)),
                shade_list(&material, &sharp, x, y),
            ];
            for &c in &classes {
                for (p, prediction) in predictions.iter().enumerate() {
                    tally.sums[c][p] += (*prediction - truth).length_squared() as f64;
                }
                tally.counts[c] += 3;
            }
        }
    }
    println!("\n{name}: {} images kept, {} predicted", kept.len(), dropped.len());
    let header: String = PREDICTORS.iter().map(|p| format!(" {p:>8}")).collect();
    println!("  {:<28}{header}  (PSNR in dB, peak 1)", "pairs");
    for (c, class) in CLASSES.iter().enumerate() {
        if tally.counts[c] == 0 {
            continue;
        }
        let psnr: String = (0..PREDICTORS.len())
            .map(|p| format!(" {:>8.2}", -10.0 * (tally.sums[c][p] / tally.counts[c] as f64).log10()))
            .collect();
        println!("  {class:<28}{psnr}  ({} images)", tally.counts[c] / (3 * stack.width() * stack.height()));
    }
    Ok(())
}

/// The images and weights of the blend before the beyond-dome model: the 4 nearest views ×
/// 4 nearest lights by angle, each weighted 1/d − 1/d₅ (views: to the power `power`),
/// normalised.
fn plain_blend(material: &Material, view: Vec3, light: Vec3, power: f32) -> Vec<(u32, f32)> {
    let nearest4 = |units: &[Vec3], q: Vec3, power: f32| {
        let mut all: Vec<(f32, u32)> =
            units.iter().enumerate().map(|(i, u)| (angle(q, *u), i as u32)).collect();
        all.sort_by(|a, b| a.0.total_cmp(&b.0));
        if all[0].0 < 1e-5 {
            return vec![(all[0].1, 1.0)];
        }
        let floor = all.get(4).map_or(0.0, |a| 1.0 / a.0);
        let kept: Vec<(u32, f32)> =
            all.iter().take(4).map(|a| (a.1, (1.0 / a.0 - floor).max(0.0).powf(power))).collect();
        let sum: f32 = kept.iter().map(|k| k.1).sum();
        kept.into_iter().map(|(i, w)| (i, w / sum)).collect()
    };
    let views = nearest4(material.view_index().units(), view, power);
    let lights = nearest4(material.light_index().units(), light, 1.0);
    let mut out = Vec::new();
    for &(v, wv) in &views {
        for &(l, wl) in &lights {
            if let Some(image) = material.image_of(v, l) {
                out.push((image, wv * wl));
            }
        }
    }
    let sum: f32 = out.iter().map(|o| o.1).sum();
    out.into_iter().map(|(i, w)| (i, w / sum)).collect()
}

fn shade_list(material: &Material, list: &[(u32, f32)], x: f32, y: f32) -> Vec3 {
    list.iter().map(|&(image, w)| w * material.texel(image, x, y)).sum()
}
