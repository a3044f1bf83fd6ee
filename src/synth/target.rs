//! The target side of synthesis: the vertices of one level, their neighbourhood templates
//! (surface textons as 6-tuples, Tong §5.1), the patch vertices used for forward shifts
//! (§5.2), and the links to the next coarser level.

/// Marks a template pixel outside the patch: it holds the default texton.
pub const OUTSIDE: u32 = u32::MAX;

/// One template pixel: s = Σ wₐ t(vertexₐ), the 6-tuple (w0, w1, w2, t0, t1, t2) of Tong
/// §5.1 with the textons looked up from the vertices at synthesis time. A pixel outside the
/// patch has `vertices[0] == OUTSIDE`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Slot {
    pub vertices: [u32; 3],
    pub weights: [f32; 3],
}

impl Slot {
    /// Outside a surface patch: the default texton (Tong §5.1).
    pub const DEFAULT: Slot = Slot { vertices: [OUTSIDE; 3], weights: [1.0, 0.0, 0.0] };
    /// Not compared at all: past the edge of a plane, where nothing exists to match.
    pub const NONE: Slot = Slot { vertices: [OUTSIDE; 3], weights: [0.0; 3] };

    /// A template pixel that falls exactly on one vertex.
    pub fn at(vertex: u32) -> Slot {
        Slot { vertices: [vertex, vertex, vertex], weights: [1.0, 0.0, 0.0] }
    }
}

/// How a vertex inherits from the coarser level (Tong §5.1, first pass): its sample
/// coordinate is 2 × that of coarse `vertex` plus `offset`, in this level's texels. (Copied
/// coordinates jump across patch seams, so they are taken from one vertex, never averaged.)
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ParentLink {
    pub vertex: u32,
    pub offset: [f32; 2],
}

/// One level of the target: a square template of `template × template` slots per vertex,
/// the patch vertices with their offsets, and (below the coarsest level) parent links and
/// the parent neighbourhood's slots.
#[derive(Clone, Debug, Default)]
pub struct TargetLevel {
    pub vertices: usize,
    /// Side of the template (odd).
    pub template: usize,
    /// `vertices × template²` slots, row-major within a template; pixel (i, j) sits at offset
    /// (i − r, j − r) texels from the vertex.
    pub slots: Vec<Slot>,
    /// CSR: the patch vertices of vertex v are `shifts[shift_start[v]..shift_start[v + 1]]`,
    /// each with its offset from v in texels (v itself included at offset 0).
    pub shift_start: Vec<u32>,
    pub shifts: Vec<(u32, [f32; 2])>,
    /// Per vertex, where it sits on the next coarser level (empty on the coarsest level).
    pub parents: Vec<ParentLink>,
    /// Side of the parent template, and `vertices × parent_template²` slots over coarser
    /// vertices around each vertex's parent point.
    pub parent_template: usize,
    pub parent_slots: Vec<Slot>,
}

impl TargetLevel {
    /// The template slots of vertex v.
    pub fn slots_of(&self, v: usize) -> &[Slot] {
        let n = self.template * self.template;
        &self.slots[v * n..(v + 1) * n]
    }

    /// The parent-neighbourhood slots of vertex v (empty on the coarsest level).
    pub fn parent_slots_of(&self, v: usize) -> &[Slot] {
        let n = self.parent_template * self.parent_template;
        self.parent_slots.get(v * n..(v + 1) * n).unwrap_or(&[])
    }

    /// The patch vertices of v with their offsets.
    pub fn shifts_of(&self, v: usize) -> &[(u32, [f32; 2])] {
        &self.shifts[self.shift_start[v] as usize..self.shift_start[v + 1] as usize]
    }
}

/// The levels of a regular `width × height` grid (plane mode): each coarser grid halves
/// both sides; the template of a vertex is the grid itself around it, and template pixels
/// past the grid's edge are not compared (as in 2D texture synthesis).
pub fn grid_levels(
    width: usize,
    height: usize,
    levels: usize,
    template: usize,
    parent_template: usize,
) -> Vec<TargetLevel> {
    let sizes: Vec<(usize, usize)> =
        std::iter::successors(Some((width, height)), |&(w, h)| Some((w.div_ceil(2), h.div_ceil(2))))
            .take(levels)
            .collect();
    (0..levels)
        .map(|l| {
            let (w, h) = sizes[l];
            let mut level = TargetLevel { vertices: w * h, template, ..TargetLevel::default() };
            level.slots = grid_slots(w, h, template);
            let r = (template / 2) as i64;
            level.shift_start.push(0);
            for y in 0..h as i64 {
                for x in 0..w as i64 {
                    for dy in -r..=r {
                        for dx in -r..=r {
                            if (0..w as i64).contains(&(x + dx)) && (0..h as i64).contains(&(y + dy)) {
                                level
                                    .shifts
                                    .push((((y + dy) * w as i64 + x + dx) as u32, [dx as f32, dy as f32]));
                            }
                        }
                    }
                    level.shift_start.push(level.shifts.len() as u32);
                }
            }
            if let Some(&(pw, ph)) = sizes.get(l + 1) {
                level.parents = (0..w * h)
                    .map(|v| {
                        let (x, y) = (v % w, v / w);
                        let p = ((y / 2).min(ph - 1) * pw + (x / 2).min(pw - 1)) as u32;
                        ParentLink { vertex: p, offset: [(x % 2) as f32, (y % 2) as f32] }
                    })
                    .collect();
                level.parent_template = parent_template;
                let parent_grid = grid_slots(pw, ph, parent_template);
                let n = parent_template * parent_template;
                level.parent_slots = (0..w * h)
                    .flat_map(|v| {
                        let (x, y) = ((v % w / 2).min(pw - 1), (v / w / 2).min(ph - 1));
                        parent_grid[(y * pw + x) * n..(y * pw + x + 1) * n].to_vec()
                    })
                    .collect();
            }
            level
        })
        .collect()
}

/// Template slots of every vertex of a w × h grid.
fn grid_slots(w: usize, h: usize, template: usize) -> Vec<Slot> {
    let r = (template / 2) as i64;
    let mut slots = Vec::with_capacity(w * h * template * template);
    for y in 0..h {
        for x in 0..w {
            for dy in -r..=r {
                for dx in -r..=r {
                    let (sx, sy) = (x as i64 + dx, y as i64 + dy);
                    slots.push(if (0..w as i64).contains(&sx) && (0..h as i64).contains(&sy) {
                        Slot::at((sy * w as i64 + sx) as u32)
                    } else {
                        Slot::NONE
                    });
                }
            }
        }
    }
    slots
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grid_templates_shifts_and_parents() {
        let levels = grid_levels(6, 4, 2, 3, 3);
        let l0 = &levels[0];
        assert_eq!((l0.vertices, levels[1].vertices), (24, 6));
        // Vertex (0, 0): the template's top-left pixels fall off the grid.
        assert_eq!(l0.slots_of(0)[0], Slot::NONE);
        assert_eq!(l0.slots_of(0)[4], Slot::at(0));
        assert_eq!(l0.slots_of(0)[8], Slot::at(7));
        // Vertex (1, 1) sees all 9 grid neighbours, itself at offset 0.
        assert_eq!(l0.shifts_of(7).len(), 9);
        assert!(l0.shifts_of(7).contains(&(7, [0.0, 0.0])));
        assert!(l0.shifts_of(7).contains(&(0, [-1.0, -1.0])));
        // Vertex (3, 1) inherits from coarse vertex (1, 0) with offset (1, 1).
        assert_eq!(l0.parents[9].vertex, 1);
        assert_eq!(l0.parents[9].offset, [1.0, 1.0]);
        assert_eq!(l0.parent_slots_of(9)[4], Slot::at(1));
        assert!(levels[1].parents.is_empty());
    }
}
