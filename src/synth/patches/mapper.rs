//! What the mapping reads (the surface, its clusters and their flattenings, the fitter, the
//! parameters) and what it writes (the texture on the faces), apart from how it proceeds,
//! so that the relaxation can read both without depending on the mapping.

use super::chart::Flattening;
use super::fit::Fitter;
use super::graph::{SurfaceGraph, NONE};
use super::hierarchy::Hierarchy;
use super::SolerParams;
use glam::Vec2;
use std::collections::HashSet;

/// The texture on the graph's faces.
#[derive(Clone, Debug)]
pub struct Mapping {
    /// Per graph face, the cluster that textured it (`NONE` until one does).
    pub mapped_by: Vec<u32>,
    /// Per graph face, the sample coordinate (texels, centres at integers) of each corner.
    pub face_uv: Vec<[Vec2; 3]>,
    /// The connected pieces of the surface (level-0 clusters) where a patch has been placed.
    pub(super) started_pieces: HashSet<u32>,
}

impl Mapping {
    pub(super) fn new(faces: usize) -> Mapping {
        Mapping {
            mapped_by: vec![NONE; faces],
            face_uv: vec![[Vec2::ZERO; 3]; faces],
            started_pieces: HashSet::new(),
        }
    }
}

/// Everything one mapping reads.
pub(super) struct Mapper<'a> {
    pub graph: &'a SurfaceGraph,
    pub hierarchy: &'a Hierarchy,
    pub flattening: &'a Flattening,
    pub fitter: &'a Fitter,
    pub params: &'a SolerParams,
    /// The graph face the first patch must hold (`SolerParams::first_face`).
    pub first_face: Option<u32>,
}
