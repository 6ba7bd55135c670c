//! The majorant the tracking samples against: `σ̄ ≥ σ_t` everywhere the medium may hold
//! density, 0 elsewhere.
//!
//! Where: the medium's own intervals along each ray ([`crate::render::Medium::intervals`]: for
//! the blob cloud the exact spans of the blob supports the ray crosses), so empty space costs
//! nothing and no coarse grid's cells overhang the cloud. How much: the medium's bound
//! [`crate::render::Medium::max_extinction`] (the cloud's `σ`: the noise and the soft edge only
//! thin the density, the cumulus base only fades it). A per-cell grid of maxima was weighed and
//! left out: the cloud's core is at `σ`, so every cell the cloud touches would hold `σ` too
//! (the grid would only tighten the fade under a cumulus base), and the supports' spans are
//! tighter than its cells. Inside the core the tracking then meets only real collisions.

use crate::render::medium::Medium;

/// A ray's majorant: `sigma` on the medium's intervals.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Majorant {
    /// The bound (per world unit).
    pub(crate) sigma: f32,
}

impl Majorant {
    /// The majorant of `medium`: its extinction bound (0 for an empty or non-finite one, which
    /// the tracking treats as empty).
    pub(crate) fn of<M: Medium>(medium: &M) -> Majorant {
        let sigma = medium.max_extinction();
        Majorant {
            sigma: if sigma.is_finite() && sigma > 0.0 {
                sigma
            } else {
                0.0
            },
        }
    }
}
