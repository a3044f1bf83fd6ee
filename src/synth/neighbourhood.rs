//! What a pass compares and by which distance. Recipes on disk name four flat parts per pass
//! ([`Stencil`], [`Mask`], [`ParentNeighbourhood`], [`MetricKind`]), most of whose
//! combinations the engine cannot run; a [`Neighbourhood`] holds only the ones it can, so
//! the engine dispatches on it without run-time refusals. [`Neighbourhood::from_parts`] is
//! the one place a flat combination is checked; [`Neighbourhood::parts`] writes it back.

use super::round::RoundStencil;

/// The circles a mesh level is marched for under [`Stencil::Isotropic`]: its two rings.
pub const ISOTROPIC_MARCHED: RoundStencil = RoundStencil { circles: 2 };

/// The neighbourhood distance a pass matches with.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum MetricKind {
    /// Surface textons through Γ (Tong §5.1).
    Gamma,
    /// Appearance vectors by SSD (Lefebvre and Hoppe 2006); needs an analysis that stores
    /// them. For a photograph they are its colour neighbourhoods reduced by PCA, the
    /// nearest the engine has to Turk's colour SSD.
    Appearance,
    /// Turk's colour SSD: the sample's linear RGB per texel, compared by plain SSD. For a
    /// BTF, the mean of the analysis' selected images; every level's colours are that mean
    /// taken down the analysis' own pyramid, centred and scaled to unit variance like the
    /// appearance vectors (so that levels weigh alike in two-level distances). Built only
    /// when a recipe uses it ([`super::Sample::load_colours`]).
    Colour,
    /// Chen and Dong 2008 §5: round neighbourhoods of appearance vectors compared by the
    /// adaptive metric ([`super::adaptive`], [`super::round_pass`]). Such a pass has no
    /// parent neighbourhood (the linked pixels enter through the inherited texels'
    /// candidates); choosy selection and the coherence bias weigh its distances.
    Adaptive,
}

pub use super::round::MAX_CIRCLES;

/// The shape of a pass's own-level neighbourhood: which offsets around a vertex it reads.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub enum Stencil {
    /// The square template of Tong, Turk and Wei–Levoy: `SynthParams::neighborhood` texels a
    /// side (default 7), every offset weighted alike. The pass's [`Mask`] shapes it: `Full` the
    /// whole square, `Visited` the causal part, `Half` Turk's half square, `Off` none of it.
    /// Matched by the `Gamma`, `Appearance` and `Colour` metrics. A recipe that names no
    /// stencil (one recorded before the field existed) means this one.
    #[default]
    Square,
    /// Chen and Dong's round neighbourhood (2008 §4): the centre and `circles` concentric
    /// circles one texel apart (circle c holds 8c points), grown circle by circle by the
    /// `Adaptive` metric, which alone matches it. Chen and Dong use 3 (the 7×7 square's
    /// reach); 1 to [`MAX_CIRCLES`], and each candidate keeps a border of `circles + 1`
    /// texels, which the coarsest sample level in use must hold unless it tiles.
    Round {
        /// Concentric circles around the centre, one texel apart.
        circles: usize,
    },
    /// Castellanos and Williams' isotropic neighbourhood (§3.12, [`super::isotropic`]): 12
    /// points one texel from the vertex and 24 two texels away, centre excluded, weighted
    /// by proximity (Eq. 7), and compared with the sample's neighbourhood turned by 0°, 60°
    /// and 120°, the least distance counting. Matched by the `Colour` and `Appearance`
    /// metrics, on one level (no parent neighbourhood); mesh levels are marched for it as
    /// for round neighbourhoods of 2 circles.
    Isotropic,
}

/// Which of the level's own template pixels a pass compares.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum Mask {
    /// Every pixel: Turk's full square F(n, 0), Tong's template.
    Full,
    /// Only pixels of vertices already visited in this pass (Wei and Levoy's causal
    /// neighbourhood on any visiting order).
    Visited,
    /// Turk's half square H(n, 0): only the columns upstream of the vertex along the
    /// texture direction (template x < 0), the side a sweep has already coloured; forward
    /// shifts are taken from those columns too.
    Half,
    /// None of them: the pass matches on the parent neighbourhood alone (Turk's
    /// extrapolating F(n, 1)).
    Off,
}

/// The coarser level's neighbourhood joining a pass's distance.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum ParentNeighbourhood {
    /// No parent neighbourhood.
    None,
    /// The narrow parent template (`parent_size(n)`: 3 for n = 7), matched with two-level
    /// kNN lists: Tong's two-level neighbourhood, Turk's F(3, 1).
    Narrow,
    /// The parent vertex's own full-size template on the coarser level: Turk's F(n, 1).
    Wide,
}

impl Stencil {
    /// The round neighbourhood, for a round stencil.
    pub fn round(&self) -> Option<RoundStencil> {
        match *self {
            Stencil::Round { circles } => Some(RoundStencil { circles }),
            Stencil::Square | Stencil::Isotropic => None,
        }
    }

    /// The circles a mesh level is marched for: a round stencil's, or the isotropic
    /// stencil's two.
    pub fn marching(&self) -> Option<RoundStencil> {
        match *self {
            Stencil::Isotropic => Some(ISOTROPIC_MARCHED),
            _ => self.round(),
        }
    }
}

/// A pass's neighbourhood with the distance that matches it: only combinations the engine
/// runs. Written to recipes as its flat [`Neighbourhood::parts`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Neighbourhood {
    /// The square template of Tong, Turk and Wei–Levoy ([`Stencil::Square`]).
    Square {
        /// The distance over the template's pixels.
        metric: SquareMetric,
        /// Which own-level pixels and which parent template join the distance.
        template: SquareTemplate,
    },
    /// Chen and Dong's round neighbourhood ([`Stencil::Round`]), matched by the adaptive
    /// metric ([`MetricKind::Adaptive`]) on one level.
    Round {
        /// Concentric circles around the centre, one texel apart (1 to [`MAX_CIRCLES`]).
        circles: usize,
        /// Which vertices' points are compared.
        compared: Compared,
    },
    /// Castellanos and Williams' isotropic neighbourhood ([`Stencil::Isotropic`]) on one
    /// level.
    Isotropic {
        /// The per-texel vectors compared at its points.
        metric: PointMetric,
        /// Which vertices' points are compared.
        compared: Compared,
    },
}

/// The distances a square template is matched by.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SquareMetric {
    /// [`MetricKind::Gamma`].
    Gamma,
    /// [`MetricKind::Appearance`].
    Appearance,
    /// [`MetricKind::Colour`].
    Colour,
}

/// The vectors an isotropic neighbourhood compares at its points.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PointMetric {
    /// Appearance vectors ([`MetricKind::Appearance`]).
    Appearance,
    /// Colours ([`MetricKind::Colour`]).
    Colour,
}

/// Which of a square template's pixels join the distance: the own level's, the parent
/// level's, or both, but never neither.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SquareTemplate {
    /// The own level's pixels only.
    Own(OwnPixels),
    /// The own level's pixels and the parent level's template.
    OwnAndParent(OwnPixels, ParentTemplate),
    /// The parent level's template alone (Turk's extrapolating F(n, 1), [`Mask::Off`]).
    ParentOnly(ParentTemplate),
}

/// The own-level pixels of a square template that are compared ([`Mask`] but `Off`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OwnPixels {
    /// [`Mask::Full`].
    Full,
    /// [`Mask::Visited`].
    Visited,
    /// [`Mask::Half`].
    Half,
}

/// The coarser level's template joining a square template ([`ParentNeighbourhood`] but
/// `None`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ParentTemplate {
    /// [`ParentNeighbourhood::Narrow`].
    Narrow,
    /// [`ParentNeighbourhood::Wide`].
    Wide,
}

/// The vertices whose points a round or isotropic neighbourhood compares.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Compared {
    /// Every vertex's ([`Mask::Full`]).
    Full,
    /// Those already visited in the pass ([`Mask::Visited`]).
    Visited,
}

impl Neighbourhood {
    /// The neighbourhood a recipe's flat parts name, or why the engine cannot run them.
    pub fn from_parts(
        stencil: Stencil,
        mask: Mask,
        parent: ParentNeighbourhood,
        metric: MetricKind,
    ) -> Result<Self, String> {
        let one_level = |what: &str| match (parent, mask) {
            (ParentNeighbourhood::None, Mask::Full) => Ok(Compared::Full),
            (ParentNeighbourhood::None, Mask::Visited) => Ok(Compared::Visited),
            (ParentNeighbourhood::None, _) => {
                Err(format!("{what} pass compares visited vertices or all of them (mask Visited or Full)"))
            }
            _ => Err(format!("{what} pass matches one level (parent must be None)")),
        };
        let square = |metric| Ok(Neighbourhood::Square { metric, template: square_template(mask, parent)? });
        let isotropic =
            |metric| Ok(Neighbourhood::Isotropic { metric, compared: one_level("an Isotropic")? });
        match (stencil, metric) {
            (Stencil::Square, MetricKind::Gamma) => square(SquareMetric::Gamma),
            (Stencil::Square, MetricKind::Appearance) => square(SquareMetric::Appearance),
            (Stencil::Square, MetricKind::Colour) => square(SquareMetric::Colour),
            (Stencil::Square, MetricKind::Adaptive) => Err(
                "the Adaptive metric matches round neighbourhoods (stencil {\"Round\": {\"circles\": 3}}), not Square"
                    .into(),
            ),
            (Stencil::Round { circles }, MetricKind::Adaptive) => {
                Ok(Neighbourhood::Round { circles, compared: one_level("a Round")? })
            }
            (Stencil::Round { .. }, metric) => Err(format!(
                "the {metric:?} metric matches square templates (stencil Square); round neighbourhoods need the Adaptive metric"
            )),
            (Stencil::Isotropic, MetricKind::Colour) => isotropic(PointMetric::Colour),
            (Stencil::Isotropic, MetricKind::Appearance) => isotropic(PointMetric::Appearance),
            (Stencil::Isotropic, metric) => Err(format!(
                "the isotropic stencil compares colours or appearance vectors (metric Colour or Appearance), not {metric:?}"
            )),
        }
    }

    /// The flat parts a recipe writes: stencil, mask, parent and metric.
    pub fn parts(&self) -> (Stencil, Mask, ParentNeighbourhood, MetricKind) {
        (self.stencil(), self.mask(), self.parent(), self.metric())
    }

    /// The neighbourhood's shape.
    pub fn stencil(&self) -> Stencil {
        match *self {
            Neighbourhood::Square { .. } => Stencil::Square,
            Neighbourhood::Round { circles, .. } => Stencil::Round { circles },
            Neighbourhood::Isotropic { .. } => Stencil::Isotropic,
        }
    }

    /// The own-level pixels compared, as a mask.
    pub fn mask(&self) -> Mask {
        match *self {
            Neighbourhood::Square { template, .. } => template.mask(),
            Neighbourhood::Round { compared, .. } | Neighbourhood::Isotropic { compared, .. } => {
                compared.mask()
            }
        }
    }

    /// The parent neighbourhood joining the distance.
    pub fn parent(&self) -> ParentNeighbourhood {
        match *self {
            Neighbourhood::Square { template, .. } => {
                template.parent().map_or(ParentNeighbourhood::None, ParentTemplate::neighbourhood)
            }
            _ => ParentNeighbourhood::None,
        }
    }

    /// The distance the neighbourhood is matched by.
    pub fn metric(&self) -> MetricKind {
        match *self {
            Neighbourhood::Square { metric: SquareMetric::Gamma, .. } => MetricKind::Gamma,
            Neighbourhood::Square { metric: SquareMetric::Appearance, .. }
            | Neighbourhood::Isotropic { metric: PointMetric::Appearance, .. } => MetricKind::Appearance,
            Neighbourhood::Square { metric: SquareMetric::Colour, .. }
            | Neighbourhood::Isotropic { metric: PointMetric::Colour, .. } => MetricKind::Colour,
            Neighbourhood::Round { .. } => MetricKind::Adaptive,
        }
    }
}

fn square_template(mask: Mask, parent: ParentNeighbourhood) -> Result<SquareTemplate, String> {
    let parent = match parent {
        ParentNeighbourhood::None => None,
        ParentNeighbourhood::Narrow => Some(ParentTemplate::Narrow),
        ParentNeighbourhood::Wide => Some(ParentTemplate::Wide),
    };
    let own = match mask {
        Mask::Full => Some(OwnPixels::Full),
        Mask::Visited => Some(OwnPixels::Visited),
        Mask::Half => Some(OwnPixels::Half),
        Mask::Off => None,
    };
    match (own, parent) {
        (Some(own), None) => Ok(SquareTemplate::Own(own)),
        (Some(own), Some(parent)) => Ok(SquareTemplate::OwnAndParent(own, parent)),
        (None, Some(parent)) => Ok(SquareTemplate::ParentOnly(parent)),
        (None, None) => Err("mask Off compares nothing without a parent neighbourhood".into()),
    }
}

impl SquareTemplate {
    /// The own-level pixels compared, as a mask ([`Mask::Off`] for none).
    pub fn mask(self) -> Mask {
        match self {
            SquareTemplate::Own(own) | SquareTemplate::OwnAndParent(own, _) => own.mask(),
            SquareTemplate::ParentOnly(_) => Mask::Off,
        }
    }

    /// The parent level's template, if one joins.
    pub fn parent(self) -> Option<ParentTemplate> {
        match self {
            SquareTemplate::Own(_) => None,
            SquareTemplate::OwnAndParent(_, parent) | SquareTemplate::ParentOnly(parent) => Some(parent),
        }
    }
}

impl OwnPixels {
    /// As a mask.
    pub fn mask(self) -> Mask {
        match self {
            OwnPixels::Full => Mask::Full,
            OwnPixels::Visited => Mask::Visited,
            OwnPixels::Half => Mask::Half,
        }
    }
}

impl Compared {
    /// As a mask.
    pub fn mask(self) -> Mask {
        match self {
            Compared::Full => Mask::Full,
            Compared::Visited => Mask::Visited,
        }
    }
}

impl ParentTemplate {
    /// As a parent neighbourhood.
    pub fn neighbourhood(self) -> ParentNeighbourhood {
        match self {
            ParentTemplate::Narrow => ParentNeighbourhood::Narrow,
            ParentTemplate::Wide => ParentNeighbourhood::Wide,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every flat combination either names a neighbourhood that writes it back unchanged or
    /// is refused; the engine's neighbourhoods are exactly the accepted ones.
    #[test]
    fn every_flat_combination_reads_back_or_is_refused() {
        let stencils = [Stencil::Square, Stencil::Round { circles: 3 }, Stencil::Isotropic];
        let masks = [Mask::Full, Mask::Visited, Mask::Half, Mask::Off];
        let parents = [ParentNeighbourhood::None, ParentNeighbourhood::Narrow, ParentNeighbourhood::Wide];
        let metrics = [MetricKind::Gamma, MetricKind::Appearance, MetricKind::Colour, MetricKind::Adaptive];
        let mut accepted = 0;
        for stencil in stencils {
            for mask in masks {
                for parent in parents {
                    for metric in metrics {
                        if let Ok(n) = Neighbourhood::from_parts(stencil, mask, parent, metric) {
                            assert_eq!(n.parts(), (stencil, mask, parent, metric));
                            accepted += 1;
                        }
                    }
                }
            }
        }
        // Square: 3 metrics × (3 own-only + 3 × 2 with a parent + 2 parent-only); round: 2;
        // isotropic: 2 metrics × 2.
        assert_eq!(accepted, 3 * (3 + 6 + 2) + 2 + 4);
    }
}
