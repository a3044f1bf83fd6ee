//! Quality of the coordinate map itself (which sample texel every output vertex copies):
//! collapse, smear, copy and coherence. They need no images, so they apply alike to planes,
//! surfaces, photographs and BTFs.

use crate::synth::engine::State;
use crate::synth::target::TargetLevel;
use serde::Serialize;

/// Neighbours closer than this (in texels) count as adjacent: a grid's 8 neighbours, a
/// mesh's one-ring at one-texel edges.
const ADJACENT: f32 = 1.5;

/// Whether an offset between adjacent vertices spans a whole texel along s or t, so that
/// even a perfect copy, rounding each vertex to its nearest texel, gives them different
/// texels. Mesh vertices 0.9 texels apart diagonally may rightly share one.
fn spans_a_texel([dx, dy]: [f32; 2]) -> bool {
    dx.abs().max(dy.abs()) >= 1.0 - 1e-4
}

/// What the coordinate map says about the result.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct CoordQuality {
    /// Share of the output copied from the most-used 1% of sample texels. A tiled copy gives
    /// 0.01; above 0.05 a few texels are stamped everywhere (visible as repeated blobs or
    /// flat areas).
    pub collapse: f64,
    /// Share of adjacent output pairs (a whole texel or more apart along s or t) that copy
    /// the very same texel. A coherent copy gives 0; anything above 0.01 shows as one-colour streaks
    /// or blocks.
    pub smear: f64,
    /// The largest patch copied contiguously, as a share of the sample's area: around 1 or
    /// more means the sample was copied whole (a tiling, not a synthesis).
    pub copy: f64,
    /// Mean number of output vertices per contiguously copied patch.
    pub coherence: f64,
}

/// Every coordinate measure of `state` on `level`, copying from a `width × height` sample.
pub fn coord_quality(
    level: &TargetLevel,
    state: &State,
    (width, height): (usize, usize),
    tileable: bool,
) -> CoordQuality {
    let patches = Patches::of(level, state, (width, height), tileable);
    CoordQuality {
        collapse: collapse(&state.uv, (width, height)),
        smear: smear(level, state),
        copy: patches.largest as f64 / (width * height).max(1) as f64,
        coherence: level.vertices as f64 / patches.count.max(1) as f64,
    }
}

/// Share of `uv` taken by the most-used 1% (at least one) of the sample's texels.
pub fn collapse(uv: &[[i32; 2]], (width, height): (usize, usize)) -> f64 {
    let mut uses = vec![0u32; width * height];
    for &[x, y] in uv {
        if (0..width as i32).contains(&x) && (0..height as i32).contains(&y) {
            uses[y as usize * width + x as usize] += 1;
        }
    }
    let top = (width * height).div_ceil(100).max(1);
    uses.select_nth_unstable_by(top - 1, |a, b| b.cmp(a));
    uses[..top].iter().map(|&u| u as f64).sum::<f64>() / uv.len().max(1) as f64
}

/// Share of adjacent pairs a whole texel or more apart along s or t (each direction
/// counted) with identical coordinates.
pub fn smear(level: &TargetLevel, state: &State) -> f64 {
    let (mut pairs, mut same, mut scratch) = (0usize, 0usize, Vec::new());
    for v in 0..level.vertices {
        for &(u, [dx, dy]) in level.shifts_of(v, &mut scratch) {
            if u as usize != v && dx.hypot(dy) <= ADJACENT && spans_a_texel([dx, dy]) {
                pairs += 1;
                same += usize::from(state.uv[u as usize] == state.uv[v]);
            }
        }
    }
    same as f64 / pairs.max(1) as f64
}

/// The contiguously copied patches: adjacent vertices whose coordinates differ by their
/// offset to within a texel belong to one (differences wrap on tileable samples).
struct Patches {
    count: usize,
    largest: usize,
}

impl Patches {
    fn of(level: &TargetLevel, state: &State, (width, height): (usize, usize), tileable: bool) -> Patches {
        let mut parent: Vec<usize> = (0..level.vertices).collect();
        let wrap = |d: i32, n: usize| {
            if tileable {
                (d + n as i32 / 2).rem_euclid(n as i32) - n as i32 / 2
            } else {
                d
            }
        };
        let mut scratch = Vec::new();
        for v in 0..level.vertices {
            for &(u, [dx, dy]) in level.shifts_of(v, &mut scratch) {
                let u = u as usize;
                if u == v || dx.hypot(dy) > ADJACENT {
                    continue;
                }
                let ex = wrap(state.uv[u][0] - state.uv[v][0], width) as f32 - dx;
                let ey = wrap(state.uv[u][1] - state.uv[v][1], height) as f32 - dy;
                if ex.abs() < 1.0 && ey.abs() < 1.0 {
                    let (a, b) = (root(&mut parent, v), root(&mut parent, u));
                    parent[a.max(b)] = a.min(b);
                }
            }
        }
        let mut sizes = vec![0usize; level.vertices];
        for v in 0..level.vertices {
            sizes[root(&mut parent, v)] += 1;
        }
        Patches {
            count: sizes.iter().filter(|&&s| s > 0).count(),
            largest: sizes.into_iter().max().unwrap_or(0),
        }
    }
}

fn root(parent: &mut [usize], mut v: usize) -> usize {
    while parent[v] != v {
        parent[v] = parent[parent[v]];
        v = parent[v];
    }
    v
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::target::grid_levels;

    fn grid_state(w: usize, h: usize, f: impl Fn(usize, usize) -> [i32; 2]) -> State {
        let uv: Vec<[i32; 2]> = (0..w * h).map(|v| f(v % w, v / w)).collect();
        State::new(vec![0; uv.len()], uv)
    }

    #[test]
    fn a_verbatim_tiled_copy_is_flagged_by_copy_not_collapse() {
        let level = &grid_levels(64, 64, 1, 5, 3)[0];
        let tiled = grid_state(64, 64, |x, y| [(x % 32) as i32, (y % 32) as i32]);
        let q = coord_quality(level, &tiled, (32, 32), true);
        assert!(q.copy >= 1.0, "a tiling of a tileable sample is one patch: {q:?}");
        assert!((q.collapse - 0.01 * 11.0 / 10.24).abs() < 0.002, "{q:?}"); // 11 texels of 1024
        assert_eq!(q.smear, 0.0);
        // Not tileable: the wrap is a seam, and each tile is a whole copy.
        let q = coord_quality(level, &tiled, (32, 32), false);
        assert!((q.copy - 1.0).abs() < 1e-12, "{q:?}");
    }

    #[test]
    fn a_smeared_map_is_flagged() {
        let level = &grid_levels(32, 32, 1, 5, 3)[0];
        // Every texel stretched over 2×2 output pixels: each pixel's right or lower
        // neighbour shares its texel half the time.
        let stretched = grid_state(32, 32, |x, y| [(x / 2) as i32, (y / 2) as i32]);
        let q = coord_quality(level, &stretched, (32, 32), false);
        assert!(q.smear > 0.2, "{q:?}");
        // One texel everywhere: total collapse and smear.
        let stamp = grid_state(32, 32, |_, _| [5, 5]);
        let q = coord_quality(level, &stamp, (32, 32), false);
        assert_eq!((q.collapse, q.smear), (1.0, 1.0));
    }
}
