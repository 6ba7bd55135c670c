//! The animation's natural ID mattes: which named piece of the shot each blob belongs to, for
//! the Cryptomatte layer of the render passes (`crate::render::output::cryptomatte`).
//!
//! - **Aggregation**: one matte per cluster, `cluster_00`, `cluster_01`, … in the clusters'
//!   region order ([`super::AggregationPlan::clusters`]).
//! - **Diffusion**: the paper's three categories, `category_I` (the first blob), `category_II`
//!   (the blobs that grow out one by one) and `category_III` (the detail that arrives last).
//! - **Morph**: `paired` (a source blob travelling into its target partner), `split` (a target
//!   blob growing out of a paired one) and `merged` (a surplus source blob shrinking away).
//!
//! - **Story**: each blob's matte is its piece in the beat that brought it in, numbered by
//!   target: `target1_category_II` (grown while the first target formed), `target2_split`
//!   (grown out of the cloud while it turned into the second target).
//!
//! Blobs dead in the target (and so never shown) belong to no matte. The names are the same
//! for every frame of a shot, so a compositor's selection holds across the sequence.

use super::Plan;

/// A blob that belongs to no matte.
pub const NO_MATTE: u32 = u32::MAX;

/// Matte names and each blob's matte (index into `names`, or [`NO_MATTE`]), by blob index.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct MatteNames {
    /// The names, each used by at least one blob.
    pub names: Vec<String>,
    /// Each blob's matte (the frame's blob list: same length, same order).
    pub of_blob: Vec<u32>,
}

impl MatteNames {
    /// Mattes from each blob's piece name (`None`: no matte), names in order of first use.
    fn from_pieces(pieces: Vec<Option<String>>) -> MatteNames {
        let mut m = MatteNames::default();
        for piece in pieces {
            let id = match piece {
                None => NO_MATTE,
                Some(name) => match m.names.iter().position(|n| *n == name) {
                    Some(k) => k as u32,
                    None => {
                        m.names.push(name);
                        (m.names.len() - 1) as u32
                    }
                },
            };
            m.of_blob.push(id);
        }
        m
    }
}

impl Plan {
    /// The shot's ID mattes (see the module doc), for the frames' blob lists.
    pub fn mattes(&self) -> MatteNames {
        match self {
            Plan::Aggregation(p) => {
                let clusters = p.clusters();
                let digits = clusters.len().saturating_sub(1).to_string().len().max(2);
                let mut of_blob = vec![NO_MATTE; p.keyframes().last().map_or(0, Vec::len)];
                for (c, cluster) in clusters.iter().enumerate() {
                    for &i in &cluster.members {
                        of_blob[i] = c as u32;
                    }
                }
                MatteNames {
                    names: (0..clusters.len())
                        .map(|c| format!("cluster_{c:0digits$}"))
                        .collect(),
                    of_blob,
                }
            }
            Plan::Diffusion(p) => {
                let n = p.frame(0).len();
                let mut pieces = vec![None; n];
                let ii = p.category_ii_len();
                for (pos, &i) in p.order().iter().enumerate() {
                    let category = match pos {
                        0 => "category_I",
                        _ if pos <= ii => "category_II",
                        _ => "category_III",
                    };
                    pieces[i] = Some(category.to_string());
                }
                MatteNames::from_pieces(pieces)
            }
            Plan::Morph(p) => MatteNames::from_pieces(
                p.roles()
                    .into_iter()
                    .map(|r| r.map(str::to_string))
                    .collect(),
            ),
            Plan::Story(p) => {
                let mut pieces: Vec<Option<String>> = vec![None; p.slots()];
                let mut named = vec![false; p.slots()];
                for beat in 0..p.beats() {
                    let m = p.beat(beat).0.mattes();
                    for (&slot, &id) in p.beat_slots(beat).iter().zip(&m.of_blob) {
                        if named[slot] {
                            continue;
                        }
                        named[slot] = true;
                        pieces[slot] = (id != NO_MATTE)
                            .then(|| format!("target{}_{}", beat + 1, m.names[id as usize]));
                    }
                }
                MatteNames::from_pieces(pieces)
            }
        }
    }
}
