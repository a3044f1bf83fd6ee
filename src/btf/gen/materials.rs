//! Procedural height fields with albedo: the mesostructure that `btfsynth gen` ray-traces.
//!
//! Coordinates are in texels. Every field is periodic with the sample's size, so generated
//! samples tile seamlessly and the field continues naturally past the sample window (grazing
//! views look at a neighbouring copy, never at an edge).

use glam::Vec3;

/// A material's surface: height above the ground plane and diffuse colour, both periodic.
pub trait Material: Sync {
    /// Height in texels at (x, y).
    fn height(&self, x: f32, y: f32) -> f32;
    /// Linear diffuse albedo at (x, y).
    fn albedo(&self, x: f32, y: f32) -> Vec3;
    /// Strength of the glossy (Blinn-Phong) lobe at (x, y).
    fn gloss(&self, x: f32, y: f32) -> f32;
    /// Blinn-Phong exponent of the glossy lobe.
    fn shininess(&self) -> f32;
    /// An upper bound on `height`, used to size the traced field.
    fn max_height(&self) -> f32;
}

pub(crate) use crate::seeded::unit;

/// Smooth value noise on a lattice of `cells` per `period` texels, periodic in both axes.
fn value_noise(seed: u64, x: f32, y: f32, period: f32, cells: i64) -> f32 {
    let fx = x / period * cells as f32;
    let fy = y / period * cells as f32;
    let (ix, iy) = (fx.floor() as i64, fy.floor() as i64);
    let (tx, ty) = (smooth(fx - ix as f32), smooth(fy - iy as f32));
    let at = |i: i64, j: i64| unit(seed, i.rem_euclid(cells), j.rem_euclid(cells), 7);
    let top = at(ix, iy) * (1.0 - tx) + at(ix + 1, iy) * tx;
    let bottom = at(ix, iy + 1) * (1.0 - tx) + at(ix + 1, iy + 1) * tx;
    top * (1.0 - ty) + bottom * ty
}

fn smooth(t: f32) -> f32 {
    t * t * (3.0 - 2.0 * t)
}

/// Two octaves of value noise in [0, 1].
fn roughness(seed: u64, x: f32, y: f32, period: f32, cells: i64) -> f32 {
    (2.0 * value_noise(seed, x, y, period, cells) + value_noise(seed ^ 1, x, y, period, 2 * cells)) / 3.0
}

/// A whole number of features per period, at least `min`, rounded to `multiple`.
fn count(period: f32, feature: f32, min: i64, multiple: i64) -> i64 {
    let n = (period / feature).round() as i64;
    ((n.max(min) + multiple - 1) / multiple) * multiple
}

/// Rounded stones scattered on a sandy ground, one per cell of a jittered grid (Worley-like).
pub struct Pebbles {
    seed: u64,
    period: f32,
    cells: i64,
    cell: f32,
}

impl Pebbles {
    /// Pebbles tiling a `size`-texel square (cells of about 11 texels), laid out by `seed`.
    pub fn new(size: usize, seed: u64) -> Self {
        let period = size as f32;
        let cells = count(period, 11.0, 2, 1);
        Pebbles { seed, period, cells, cell: period / cells as f32 }
    }

    /// The stone of cell (i, j): centre, semi-axes, orientation, dome height.
    fn stone(&self, i: i64, j: i64) -> Stone {
        let (ci, cj) = (i.rem_euclid(self.cells), j.rem_euclid(self.cells));
        let u = |k| unit(self.seed, ci, cj, k);
        let r = self.cell * (0.36 + 0.16 * u(3));
        Stone {
            centre: [(i as f32 + 0.3 + 0.4 * u(1)) * self.cell, (j as f32 + 0.3 + 0.4 * u(2)) * self.cell],
            axes: [r, r * (0.6 + 0.35 * u(4))],
            angle: std::f32::consts::PI * u(5),
            height: r * (0.45 + 0.25 * u(6)),
            tint: u(8),
            id: [ci, cj],
        }
    }

    /// The stone whose surface is highest at (x, y), with that height.
    fn top_stone(&self, x: f32, y: f32) -> Option<(Stone, f32)> {
        let (i, j) = ((x / self.cell).floor() as i64, (y / self.cell).floor() as i64);
        let mut best: Option<(Stone, f32)> = None;
        for dj in -1..=1 {
            for di in -1..=1 {
                let s = self.stone(i + di, j + dj);
                if let Some(h) = s.height_at(x, y) {
                    if best.as_ref().is_none_or(|(_, b)| h > *b) {
                        best = Some((s, h));
                    }
                }
            }
        }
        best
    }

    fn ground(&self, x: f32, y: f32) -> f32 {
        0.6 * roughness(self.seed ^ 0xA5, x, y, self.period, self.cells * 3)
    }
}

struct Stone {
    centre: [f32; 2],
    axes: [f32; 2],
    angle: f32,
    height: f32,
    tint: f32,
    id: [i64; 2],
}

impl Stone {
    /// Height of this stone's dome at (x, y), if (x, y) is inside it.
    fn height_at(&self, x: f32, y: f32) -> Option<f32> {
        let (dx, dy) = (x - self.centre[0], y - self.centre[1]);
        let (s, c) = self.angle.sin_cos();
        let (u, v) = ((c * dx + s * dy) / self.axes[0], (-s * dx + c * dy) / self.axes[1]);
        let d2 = u * u + v * v;
        // A flattened dome: steep sides cast shadows, a rounded top catches highlights.
        (d2 < 1.0).then(|| self.height * (1.0 - d2).powf(0.4))
    }
}

impl Material for Pebbles {
    fn height(&self, x: f32, y: f32) -> f32 {
        let ground = self.ground(x, y);
        match self.top_stone(x, y) {
            Some((_, h)) => h.max(ground),
            None => ground,
        }
    }

    fn albedo(&self, x: f32, y: f32) -> Vec3 {
        let ground = self.ground(x, y);
        let speckle = value_noise(self.seed ^ 0x51, x, y, self.period, self.cells * 8);
        match self.top_stone(x, y) {
            Some((s, h)) if h > ground => {
                let base = Vec3::new(0.55, 0.5, 0.44).lerp(Vec3::new(0.3, 0.27, 0.25), s.tint);
                let warm = Vec3::new(0.12, 0.06, 0.0) * unit(self.seed, s.id[0], s.id[1], 9);
                (base + warm) * (0.8 + 0.4 * speckle)
            }
            _ => Vec3::new(0.32, 0.26, 0.18) * (0.7 + 0.6 * speckle),
        }
    }

    fn gloss(&self, x: f32, y: f32) -> f32 {
        if self.top_stone(x, y).is_some_and(|(_, h)| h > self.ground(x, y)) {
            0.25
        } else {
            0.02
        }
    }

    fn shininess(&self) -> f32 {
        40.0
    }

    fn max_height(&self) -> f32 {
        self.cell * 0.52 * 0.7 + 0.6
    }
}

/// A plain weave: warp threads along y and weft threads along x passing over and under
/// each other, with fibre streaks along each thread.
pub struct Weave {
    seed: u64,
    spacing: f32,
    threads: i64,
}

impl Weave {
    /// A weave tiling a `size`-texel square (an even number of threads, about 8 texels
    /// apart), laid out by `seed`.
    pub fn new(size: usize, seed: u64) -> Self {
        // An even thread count keeps the over/under alternation periodic.
        let threads = count(size as f32, 8.0, 2, 2);
        Weave { seed, spacing: size as f32 / threads as f32, threads }
    }

    /// Height of the thread surface of one family: `along` runs along the thread, `across`
    /// across it; `sign` = +1 for warp, -1 for weft.
    fn thread(&self, along: f32, across: f32, sign: f32) -> (f32, i64) {
        let s = self.spacing;
        let i = (across / s).floor() as i64;
        let d = across - (i as f32 + 0.5) * s;
        let parity = if i.rem_euclid(2) == 0 { 1.0 } else { -1.0 };
        let amplitude = 0.22 * s;
        let centre = sign * parity * amplitude * (std::f32::consts::PI * (along / s - 0.5)).cos();
        let radius = 0.46 * s;
        let bulge = (radius * radius - d * d).max(0.0).sqrt() * 0.7;
        (amplitude + centre + bulge, i.rem_euclid(self.threads))
    }

    fn warp_on_top(&self, x: f32, y: f32) -> (bool, f32, i64, f32) {
        let (hw, iw) = self.thread(y, x, 1.0);
        let (hf, jf) = self.thread(x, y, -1.0);
        if hw >= hf {
            (true, hw, iw, y)
        } else {
            (false, hf, jf, x)
        }
    }
}

impl Material for Weave {
    fn height(&self, x: f32, y: f32) -> f32 {
        self.warp_on_top(x, y).1
    }

    fn albedo(&self, x: f32, y: f32) -> Vec3 {
        let (warp, _, index, along) = self.warp_on_top(x, y);
        let base = if warp { Vec3::new(0.62, 0.12, 0.1) } else { Vec3::new(0.78, 0.7, 0.5) };
        let family = if warp { 1 } else { 2 };
        let thread = 0.85 + 0.3 * unit(self.seed, index, family, 11);
        // Twisted fibres: streaks slanted along the thread.
        let across = if warp { x } else { y };
        let twist = 0.5 + 0.5 * (6.0 * std::f32::consts::PI * (along + across) / self.spacing).sin();
        base * thread * (0.75 + 0.25 * twist)
    }

    fn gloss(&self, _x: f32, _y: f32) -> f32 {
        0.15
    }

    fn shininess(&self) -> f32 {
        12.0
    }

    fn max_height(&self) -> f32 {
        0.44 * self.spacing + 0.46 * 0.7 * self.spacing
    }
}

/// Running-bond bricks with bevelled edges, deep mortar grooves and a rough surface.
pub struct Bricks {
    seed: u64,
    period: f32,
    rows: i64,
    cols: i64,
    row_height: f32,
    brick_width: f32,
}

impl Bricks {
    /// Bricks tiling a `size`-texel square (an even number of courses, about 9 texels
    /// high), laid out by `seed`.
    pub fn new(size: usize, seed: u64) -> Self {
        let period = size as f32;
        // Even rows keep the half-brick offset periodic.
        let rows = count(period, 9.0, 2, 2);
        let row_height = period / rows as f32;
        let cols = count(period, 2.0 * row_height, 1, 1);
        Bricks { seed, period, rows, cols, row_height, brick_width: period / cols as f32 }
    }

    /// Brick indices and the distance from (x, y) to the nearest edge of its brick.
    fn brick(&self, x: f32, y: f32) -> (i64, i64, f32) {
        let row = (y / self.row_height).floor() as i64;
        let shift = if row.rem_euclid(2) == 1 { 0.5 * self.brick_width } else { 0.0 };
        let col = ((x - shift) / self.brick_width).floor() as i64;
        let u = x - shift - col as f32 * self.brick_width;
        let v = y - row as f32 * self.row_height;
        let edge = u.min(self.brick_width - u).min(v).min(self.row_height - v);
        (row.rem_euclid(self.rows), col.rem_euclid(self.cols), edge)
    }

    fn mortar(&self) -> f32 {
        0.09 * self.row_height
    }
}

impl Material for Bricks {
    fn height(&self, x: f32, y: f32) -> f32 {
        let (row, col, edge) = self.brick(x, y);
        let rough = roughness(self.seed ^ 0x33, x, y, self.period, self.cols * 12);
        let inset = edge - self.mortar();
        if inset <= 0.0 {
            return 0.3 * rough;
        }
        let top = self.row_height * (0.32 + 0.06 * unit(self.seed, row, col, 21));
        let bevel = (inset / (0.12 * self.row_height)).min(1.0);
        top * smooth(bevel).sqrt() + 0.5 * rough
    }

    fn albedo(&self, x: f32, y: f32) -> Vec3 {
        let (row, col, edge) = self.brick(x, y);
        let grain = value_noise(self.seed ^ 0x77, x, y, self.period, self.cols * 16);
        if edge <= self.mortar() {
            return Vec3::new(0.55, 0.53, 0.5) * (0.85 + 0.3 * grain);
        }
        let red = Vec3::new(0.5, 0.17, 0.1).lerp(Vec3::new(0.62, 0.33, 0.18), unit(self.seed, row, col, 22));
        red * (0.75 + 0.45 * grain)
    }

    fn gloss(&self, _x: f32, _y: f32) -> f32 {
        0.04
    }

    fn shininess(&self) -> f32 {
        8.0
    }

    fn max_height(&self) -> f32 {
        0.38 * self.row_height + 0.5
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn materials(size: usize) -> Vec<Box<dyn Material>> {
        vec![Box::new(Pebbles::new(size, 3)), Box::new(Weave::new(size, 3)), Box::new(Bricks::new(size, 3))]
    }

    #[test]
    fn fields_are_periodic_with_the_sample_size() {
        for size in [16usize, 48, 64] {
            for m in materials(size) {
                for (x, y) in [(0.3f32, 1.7f32), (5.25, 9.5), (11.0, 3.1)] {
                    let p = size as f32;
                    assert!((m.height(x, y) - m.height(x + p, y - p)).abs() < 1e-3);
                    assert!((m.albedo(x, y) - m.albedo(x - p, y + 2.0 * p)).length() < 1e-3);
                }
            }
        }
    }

    #[test]
    fn heights_stay_under_their_bound_and_vary() {
        for m in materials(32) {
            let hs: Vec<f32> =
                (0..64 * 64).map(|k| m.height((k % 64) as f32 * 0.5, (k / 64) as f32 * 0.5)).collect();
            let (lo, hi) = hs.iter().fold((f32::MAX, f32::MIN), |(a, b), &h| (a.min(h), b.max(h)));
            assert!(lo >= 0.0 && hi <= m.max_height(), "{lo} {hi} {}", m.max_height());
            assert!(hi - lo > 1.0, "relief of {} texels is too flat to cast shadows", hi - lo);
        }
    }
}
