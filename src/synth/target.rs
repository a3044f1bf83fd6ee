//! The target side of synthesis: the vertices of one level, their neighbourhood templates
//! (surface textons as 6-tuples, Tong §5.1), the patch vertices used for forward shifts
//! (§5.2), and the links to the next coarser level.

pub use super::slot::{Slot, OUTSIDE};

/// How a vertex inherits from the coarser level (Tong §5.1, first pass): its sample
/// coordinate is 2 × that of coarse `vertex` plus `offset`, in this level's texels. (Copied
/// coordinates jump across patch seams, so they are taken from one vertex, never averaged.)
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ParentLink {
    /// The coarse level's vertex the coordinate is copied from.
    pub vertex: u32,
    /// Offset added to twice that vertex's coordinate, in this level's texels.
    pub offset: [f32; 2],
}

/// A patch vertex and its offset from the centre vertex, in texels.
pub type Shift = (u32, [f32; 2]);

/// The neighbourhoods of a level's vertices: per vertex a square template of slots (row-major;
/// pixel (i, j) sits at offset (i − r, j − r) texels from the vertex) and its patch vertices
/// with their offsets, for forward shifts.
#[derive(Clone, Debug, PartialEq)]
pub enum Neighbourhoods {
    /// A regular `width × height` grid (plane mode): computed on demand, since they are the
    /// grid itself around each vertex. Template pixels past the grid's edge are not compared,
    /// unless the grid `wraps` (a tileable output): then its left edge continues its right
    /// edge and its top its bottom, so the result repeats without a seam.
    Grid {
        /// Columns of the grid.
        width: usize,
        /// Rows of the grid.
        height: usize,
        /// Side of the square template in pixels (odd).
        template: usize,
        /// Whether the grid's edges wrap (a tileable output).
        wraps: bool,
    },
    /// A mesh: resampled from flattened patches and stored.
    Mesh {
        /// Side of the square template in texels (odd).
        template: usize,
        /// `vertices × template²` slots.
        slots: Vec<Slot>,
        /// CSR: the patch vertices of v are `shifts[shift_start[v]..shift_start[v + 1]]`.
        shift_start: Vec<u32>,
        /// Every vertex's patch vertices with their offsets, vertex after vertex.
        shifts: Vec<Shift>,
    },
}

impl Neighbourhoods {
    /// Side of the templates.
    pub fn template(&self) -> usize {
        match self {
            Neighbourhoods::Grid { template, .. } | Neighbourhoods::Mesh { template, .. } => *template,
        }
    }

    /// The template slots of vertex v (computed into `scratch` on a grid).
    pub fn slots<'a>(&'a self, v: usize, scratch: &'a mut Vec<Slot>) -> &'a [Slot] {
        match self {
            Neighbourhoods::Mesh { template, slots, .. } => {
                let n = template * template;
                &slots[v * n..(v + 1) * n]
            }
            &Neighbourhoods::Grid { width, height, template, wraps } => {
                scratch.clear();
                scratch.reserve(template * template);
                for_grid_window(v, (width, height), template, wraps, |_, p| {
                    scratch.push(p.map_or(Slot::NONE, Slot::at))
                });
                scratch
            }
        }
    }

    /// The patch vertices of v with their offsets (computed into `scratch` on a grid).
    pub fn shifts<'a>(&'a self, v: usize, scratch: &'a mut Vec<Shift>) -> &'a [Shift] {
        match self {
            Neighbourhoods::Mesh { shift_start, shifts, .. } => {
                &shifts[shift_start[v] as usize..shift_start[v + 1] as usize]
            }
            &Neighbourhoods::Grid { width, height, template, wraps } => {
                scratch.clear();
                scratch.reserve(template * template);
                for_grid_window(v, (width, height), template, wraps, |[dx, dy], p| {
                    if let Some(p) = p {
                        scratch.push((p, [dx as f32, dy as f32]));
                    }
                });
                scratch
            }
        }
    }
}

/// Calls `visit` with the offset (dx, dy) and grid vertex of each pixel of v's `template ×
/// template` window, row-major; `None` past the edge of a grid that does not wrap. Plain
/// loops rather than an iterator chain: every visit of a plane pass builds two windows, and
/// the flattened iterator was a tenth of a 1024² synthesis.
fn for_grid_window(
    v: usize,
    (width, height): (usize, usize),
    template: usize,
    wraps: bool,
    mut visit: impl FnMut([i64; 2], Option<u32>),
) {
    let r = (template / 2) as i64;
    let (w, h) = (width as i64, height as i64);
    let (x, y) = ((v % width) as i64, (v / width) as i64);
    for dy in -r..=r {
        let sy = if wraps { (y + dy).rem_euclid(h) } else { y + dy };
        let row_inside = (0..h).contains(&sy);
        for dx in -r..=r {
            let sx = if wraps { (x + dx).rem_euclid(w) } else { x + dx };
            visit([dx, dy], (row_inside && (0..w).contains(&sx)).then(|| (sy * w + sx) as u32));
        }
    }
}

/// One level of the target: its vertices' neighbourhoods and, below the coarsest level,
/// their links to the coarser level and the coarser level's templates for two-level
/// neighbourhoods.
#[derive(Clone, Debug, PartialEq)]
pub struct TargetLevel {
    /// Number of vertices (pixels, in plane mode) on the level.
    pub vertices: usize,
    /// Side of the template (odd).
    pub template: usize,
    /// The templates of the level's vertices, or the grid they come from.
    pub neighbourhoods: Neighbourhoods,
    /// Per vertex, where it sits on the next coarser level (empty on the coarsest level).
    pub parents: Vec<ParentLink>,
    /// Side of the parent template.
    pub parent_template: usize,
    /// Templates of the coarser level's vertices, `parent_template` wide: a vertex's parent
    /// neighbourhood is its parent vertex's.
    pub parent_neighbourhoods: Option<Neighbourhoods>,
    /// On a mesh, the round neighbourhoods' marching and start points, built only for
    /// presets that match round neighbourhoods (grids compute theirs on demand).
    pub round: Option<super::round::MarchedLevel>,
}

impl TargetLevel {
    /// A level with no links to a coarser one.
    pub fn new(vertices: usize, neighbourhoods: Neighbourhoods) -> Self {
        TargetLevel {
            vertices,
            template: neighbourhoods.template(),
            neighbourhoods,
            parents: Vec::new(),
            parent_template: 0,
            parent_neighbourhoods: None,
            round: None,
        }
    }

    /// The template slots of vertex v.
    pub fn slots_of<'a>(&'a self, v: usize, scratch: &'a mut Vec<Slot>) -> &'a [Slot] {
        self.neighbourhoods.slots(v, scratch)
    }

    /// The parent-neighbourhood slots of vertex v (empty on the coarsest level).
    pub fn parent_slots_of<'a>(&'a self, v: usize, scratch: &'a mut Vec<Slot>) -> &'a [Slot] {
        match (&self.parent_neighbourhoods, self.parents.get(v)) {
            (Some(n), Some(link)) => n.slots(link.vertex as usize, scratch),
            _ => &[],
        }
    }

    /// The patch vertices of v with their offsets.
    pub fn shifts_of<'a>(&'a self, v: usize, scratch: &'a mut Vec<Shift>) -> &'a [Shift] {
        self.neighbourhoods.shifts(v, scratch)
    }

    /// How far inside a sample that does not tile its candidate texels stay, for
    /// neighbourhoods that reach `reach` texels: [`PLANE_EDGE_MARGIN`] on a grid, `reach` on
    /// a mesh. Texels nearer the edge read the sample's border (its edge repeated) for the
    /// part of their neighbourhood that lies outside.
    pub fn candidate_margin(&self, reach: usize) -> usize {
        match self.neighbourhoods {
            Neighbourhoods::Grid { .. } => reach.min(PLANE_EDGE_MARGIN),
            Neighbourhoods::Mesh { .. } => reach,
        }
    }
}

/// The candidate margin on a plane ([`TargetLevel::candidate_margin`]). A margin of the
/// whole template radius keeps 3 texels at each edge out of every level, 12 texels of the
/// finest level under a coarsest level a quarter of the sample's side: on a 256×166 brick
/// sample that band holds two of its three mortar courses, and the results lost them (19%
/// grey in the sample, 8% in the patches; luma contrast 0.70–0.74 of the sample's, colour
/// χ² 0.029–0.035). With 1: contrast 0.93–0.95 and χ² 0.004–0.008 there, and over 21
/// photographs 50²–256² colour χ² 0.0075 → 0.0042 and organic repetition 0.0143 → 0.0134
/// (docs/quality.md, "The sample's edges"). With 0 a candidate on the edge reads three
/// columns of repeated edge texels, and a pine board's dark edge came in as broken bars
/// (patch energy 3–5×).
/// A mesh keeps the whole radius: its templates are resampled, never an exact copy, and the
/// border's repeated texels are the smooth neighbourhoods they match too well (the export
/// test's cracked stone smeared 9.1% of its windows at 1, 8.7% at the radius).
pub const PLANE_EDGE_MARGIN: usize = 1;

/// The levels of a regular `width × height` grid (plane mode): each coarser grid halves
/// both sides (rounding up); a vertex's parent is the coarse vertex under it.
pub fn grid_levels(
    width: usize,
    height: usize,
    levels: usize,
    template: usize,
    parent_template: usize,
) -> Vec<TargetLevel> {
    wrapping_grid_levels(width, height, levels, template, parent_template, false)
}

/// [`grid_levels`], on grids that wrap around when `wraps` (every level, so that the coarse
/// structure repeats too; an odd side makes the coarser wrap half a texel off, which the
/// finer levels mend).
pub fn wrapping_grid_levels(
    width: usize,
    height: usize,
    levels: usize,
    template: usize,
    parent_template: usize,
    wraps: bool,
) -> Vec<TargetLevel> {
    let sizes: Vec<(usize, usize)> =
        std::iter::successors(Some((width, height)), |&(w, h)| Some((w.div_ceil(2), h.div_ceil(2))))
            .take(levels)
            .collect();
    (0..levels)
        .map(|l| {
            let (w, h) = sizes[l];
            let mut level =
                TargetLevel::new(w * h, Neighbourhoods::Grid { width: w, height: h, template, wraps });
            if let Some(&(pw, ph)) = sizes.get(l + 1) {
                level.parents = (0..w * h)
                    .map(|v| {
                        let (x, y) = (v % w, v / w);
                        let p = ((y / 2).min(ph - 1) * pw + (x / 2).min(pw - 1)) as u32;
                        ParentLink { vertex: p, offset: [(x % 2) as f32, (y % 2) as f32] }
                    })
                    .collect();
                level.parent_template = parent_template;
                level.parent_neighbourhoods =
                    Some(Neighbourhoods::Grid { width: pw, height: ph, template: parent_template, wraps });
            }
            level
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grid_templates_shifts_and_parents() {
        let levels = grid_levels(6, 4, 2, 3, 3);
        let l0 = &levels[0];
        let (mut slots, mut shifts) = (Vec::new(), Vec::new());
        assert_eq!((l0.vertices, levels[1].vertices), (24, 6));
        // Vertex (0, 0): the template's top-left pixels fall off the grid.
        assert_eq!(l0.slots_of(0, &mut slots)[0], Slot::NONE);
        assert_eq!(l0.slots_of(0, &mut slots)[4], Slot::at(0));
        assert_eq!(l0.slots_of(0, &mut slots)[8], Slot::at(7));
        // Vertex (1, 1) sees all 9 grid neighbours, itself at offset 0.
        assert_eq!(l0.shifts_of(7, &mut shifts).len(), 9);
        assert!(l0.shifts_of(7, &mut shifts).contains(&(7, [0.0, 0.0])));
        assert!(l0.shifts_of(7, &mut shifts).contains(&(0, [-1.0, -1.0])));
        // Vertex (3, 1) inherits from coarse vertex (1, 0) with offset (1, 1).
        assert_eq!(l0.parents[9].vertex, 1);
        assert_eq!(l0.parents[9].offset, [1.0, 1.0]);
        assert_eq!(l0.parent_slots_of(9, &mut slots)[4], Slot::at(1));
        assert!(levels[1].parents.is_empty());
    }

    #[test]
    fn wrapping_grids_continue_across_their_edges() {
        let levels = wrapping_grid_levels(6, 4, 2, 3, 3, true);
        let (mut slots, mut shifts) = (Vec::new(), Vec::new());
        // Vertex (0, 0): up-left is (5, 3), the last vertex; every pixel is on the grid.
        let corner = levels[0].slots_of(0, &mut slots).to_vec();
        assert_eq!(corner[0], Slot::at(23));
        assert_eq!(corner[3], Slot::at(5));
        assert!(corner.iter().all(|&s| s != Slot::NONE));
        assert_eq!(levels[0].shifts_of(0, &mut shifts).len(), 9);
        assert!(levels[0].shifts_of(0, &mut shifts).contains(&(23, [-1.0, -1.0])));
        // The coarse level and the parents' templates wrap too.
        assert_eq!(levels[1].slots_of(0, &mut slots)[0], Slot::at(5));
        assert_eq!(levels[0].parent_slots_of(0, &mut slots)[0], Slot::at(5));
    }
}
