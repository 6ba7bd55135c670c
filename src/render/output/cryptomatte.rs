//! ID mattes in Psyop's Cryptomatte convention (specification 1.1.0), so a compositor's
//! Cryptomatte node (Nuke, Fusion, Blender) picks pieces of the cloud by name.
//!
//! Names: the caller gives one name per matte and each blob's matte ([`Mattes`]; the scene
//! names one per aggregation cluster or morph/diffusion category). ID: the name's
//! MurmurHash3_x86_32 (seed 0, `murmur3_32`) as the bits of an f32 whose exponent is clamped
//! to `[1, 254]` (`hash_to_float`: never a NaN, an infinity or a denormal).
//!
//! Coverage: each march sample's share of the pixel's opacity, `T·(1 − e^{−σh})` (what it adds
//! to alpha), goes to the matte of the blob whose field term dominates the density there
//! ([`crate::render::Medium::label`]); a pixel's weights are summed over all its rays in a small fixed
//! array (`Coverage`, no allocation) and divided by the number of rays, so a pixel's
//! coverages sum to its alpha (1 where the cloud is opaque), as the spec's ranking filter with
//! non-refractive transparency does. They are ranked by coverage (largest first, ties by
//! matte) and the first [`RANKS`] kept.
//!
//! EXR layout (written by [`crate::render::output`]): channels `{layer}00.R/G/B/A`,
//! `{layer}01.R/G/B/A`, … — each RGBA holds two ranks as `(id, coverage, id, coverage)`, the
//! spec's default of 6 ranks in 3 channel sets; an empty rank is `(0, 0)`. Header:
//! `cryptomatte/<key>/name` (the layer), `/hash` = `MurmurHash3_32`, `/conversion` =
//! `uint32_to_float32` and `/manifest`, the JSON `{"name": "8 hex digits of the id's float
//! bits"}` of every matte of the shot (also those not seen in this frame), where `<key>` is the
//! first 7 hex digits of the layer name's hash.

use std::collections::BTreeMap;

/// Ranks of (id, coverage) written per pixel: the spec's default.
pub const RANKS: usize = 6;

/// Distinct mattes a pixel accumulates before further ones are dropped (their light is in the
/// beauty, not in any matte); the [`RANKS`] largest are written.
pub(crate) const SLOTS: usize = 16;

/// No matte (an empty rank; a blob that belongs to none): the medium's [`crate::render::medium::NO_PIECE`].
pub const NO_MATTE: u32 = crate::render::medium::NO_PIECE;

/// The layer name of object mattes.
pub(crate) const OBJECT_LAYER: &str = "CryptoObject";

/// The mattes asked for: their names, and each blob's matte (by index in the frame's blob
/// list; [`NO_MATTE`] or past the end: none).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Mattes {
    /// The Cryptomatte layer (type) name, e.g. `OBJECT_LAYER`.
    pub layer: String,
    /// Matte names; the matte's index is its position.
    pub names: Vec<String>,
    /// Matte of each blob.
    pub of_blob: Vec<u32>,
}

/// One rank of a pixel: a matte and its coverage.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rank {
    /// Index into the names ([`NO_MATTE`] for an empty rank).
    pub matte: u32,
    /// Share of the pixel, in `[0, 1]`.
    pub coverage: f32,
}

impl Rank {
    /// An empty rank.
    pub(crate) const EMPTY: Rank = Rank {
        matte: NO_MATTE,
        coverage: 0.0,
    };
}

/// A frame's ID mattes: the names and each pixel's ranks (row-major, like [`crate::render::Frame`]).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct IdMattes {
    /// The Cryptomatte layer name.
    pub layer: String,
    /// Matte names.
    pub names: Vec<String>,
    /// Per pixel, the ranks by decreasing coverage.
    pub ranks: Vec<[Rank; RANKS]>,
}

impl IdMattes {
    /// Empty ranks for `n` pixels of `mattes`.
    pub(crate) fn empty(mattes: &Mattes, n: usize) -> IdMattes {
        IdMattes {
            layer: mattes.layer.clone(),
            names: mattes.names.clone(),
            ranks: vec![[Rank::EMPTY; RANKS]; n],
        }
    }

    /// The float id of each matte ([`name_id`] of each name).
    pub fn ids(&self) -> Vec<f32> {
        self.names.iter().map(|n| name_id(n)).collect()
    }

    /// The matte a rank names, as the EXR writes it: its index into the names when it is one
    /// of them and covers something; `None` (the EXR's id 0) for an empty rank or one that
    /// covers nothing.
    pub fn named(&self, rank: Rank) -> Option<usize> {
        let m = rank.matte as usize;
        (m < self.names.len() && rank.coverage > 0.0).then_some(m)
    }

    /// The manifest of the header's `cryptomatte/<key>/manifest`: each name and the 8 hex
    /// digits of its id's float bits, for every matte of the shot (also those not seen).
    pub fn manifest(&self) -> BTreeMap<&str, String> {
        self.names
            .iter()
            .map(|n| (n.as_str(), format!("{:08x}", name_id(n).to_bits())))
            .collect()
    }

    /// The EXR channels of the pixels `pixels` (indices, in the file's order): `(name, values)`.
    pub(crate) fn channels(&self, pixels: &[usize]) -> Vec<(String, Vec<f32>)> {
        let ids = self.ids();
        let mut out = Vec::new();
        for set in 0..RANKS.div_ceil(2) {
            for (c, channel) in ["R", "G", "B", "A"].into_iter().enumerate() {
                let rank = 2 * set + c / 2;
                let values = pixels
                    .iter()
                    .map(|&i| {
                        let r = self.ranks[i].get(rank).copied().unwrap_or(Rank::EMPTY);
                        if c % 2 == 0 {
                            self.named(r).map_or(0.0, |m| ids[m])
                        } else {
                            r.coverage
                        }
                    })
                    .collect();
                out.push((format!("{}{set:02}.{channel}", self.layer), values));
            }
        }
        out
    }

    /// The header attributes `(name, value)`: `cryptomatte/<key>/name`, `/hash`,
    /// `/conversion` and `/manifest`.
    pub(crate) fn header(&self) -> Vec<(String, String)> {
        let key = layer_key(&self.layer);
        let manifest = self.manifest();
        let attr = |what: &str| format!("cryptomatte/{key}/{what}");
        vec![
            (attr("name"), self.layer.clone()),
            (attr("hash"), "MurmurHash3_32".into()),
            (attr("conversion"), "uint32_to_float32".into()),
            // A map of strings always serializes.
            (
                attr("manifest"),
                serde_json::to_string(&manifest).unwrap_or_default(),
            ),
        ]
    }
}

/// The metadata key of a Cryptomatte layer: the first 7 hex digits of its name's hash (the
/// spec's suggestion, and Blender's choice; any key up to 7 characters that stays the same
/// across frames and shots will do, readers look for the `name` under it).
pub fn layer_key(layer: &str) -> String {
    format!("{:08x}", murmur3_32(layer.as_bytes(), 0))[..7].to_string()
}

/// The float id of a matte name: `hash_to_float` of its `murmur3_32` with seed 0.
pub fn name_id(name: &str) -> f32 {
    hash_to_float(murmur3_32(name.as_bytes(), 0))
}

/// The spec's `uint32_to_float32`: the hash's bits as an f32 with the exponent clamped to
/// `[1, 254]` (sign and mantissa kept), so an id is never NaN, infinite or denormal.
pub(crate) fn hash_to_float(hash: u32) -> f32 {
    let mantissa = hash & ((1 << 23) - 1);
    let exponent = ((hash >> 23) & 0xff).clamp(1, 254);
    f32::from_bits((hash & (1 << 31)) | (exponent << 23) | mantissa)
}

/// MurmurHash3_x86_32 (Austin Appleby's, public domain) of `data` with `seed`.
pub(crate) fn murmur3_32(data: &[u8], seed: u32) -> u32 {
    const C1: u32 = 0xcc9e_2d51;
    const C2: u32 = 0x1b87_3593;
    let mix = |k: u32| k.wrapping_mul(C1).rotate_left(15).wrapping_mul(C2);
    let mut h = seed;
    let mut blocks = data.chunks_exact(4);
    for b in &mut blocks {
        let k = u32::from_le_bytes([b[0], b[1], b[2], b[3]]);
        h = (h ^ mix(k))
            .rotate_left(13)
            .wrapping_mul(5)
            .wrapping_add(0xe654_6b64);
    }
    let tail = blocks.remainder();
    if !tail.is_empty() {
        let k = tail
            .iter()
            .rev()
            .fold(0u32, |k, &byte| (k << 8) | byte as u32);
        h ^= mix(k);
    }
    h ^= data.len() as u32;
    h ^= h >> 16;
    h = h.wrapping_mul(0x85eb_ca6b);
    h ^= h >> 13;
    h = h.wrapping_mul(0xc2b2_ae35);
    h ^ (h >> 16)
}

/// One pixel's matte weights, summed over its rays (fixed size: no allocation per pixel).
#[derive(Clone, Debug)]
pub(crate) struct Coverage<'a> {
    of_blob: &'a [u32],
    mattes: [u32; SLOTS],
    weight: [f32; SLOTS],
    n: usize,
}

impl<'a> Coverage<'a> {
    /// No weights yet; blobs map to mattes through `of_blob`.
    pub(crate) fn new(of_blob: &'a [u32]) -> Coverage<'a> {
        Coverage {
            of_blob,
            mattes: [NO_MATTE; SLOTS],
            weight: [0.0; SLOTS],
            n: 0,
        }
    }

    /// Add opacity `w` of a sample whose density blob `blob` dominates.
    #[inline]
    pub(crate) fn add(&mut self, blob: u32, w: f32) {
        let matte = self.of_blob.get(blob as usize).copied().unwrap_or(NO_MATTE);
        if matte == NO_MATTE {
            return;
        }
        if let Some(k) = self.mattes[..self.n].iter().position(|&m| m == matte) {
            self.weight[k] += w;
        } else if self.n < SLOTS {
            self.mattes[self.n] = matte;
            self.weight[self.n] = w;
            self.n += 1;
        }
    }

    /// The ranks of the mean over `rays` rays: largest coverage first (ties: lower matte).
    pub(crate) fn ranks(&self, rays: u32) -> [Rank; RANKS] {
        let mut order: [usize; SLOTS] = std::array::from_fn(|k| k);
        let order = &mut order[..self.n];
        order.sort_by(|&a, &b| {
            self.weight[b]
                .total_cmp(&self.weight[a])
                .then(self.mattes[a].cmp(&self.mattes[b]))
        });
        let inv = 1.0 / rays.max(1) as f32;
        let mut out = [Rank::EMPTY; RANKS];
        for (slot, &k) in out.iter_mut().zip(order.iter()) {
            *slot = Rank {
                matte: self.mattes[k],
                coverage: self.weight[k] * inv,
            };
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn murmur3_matches_known_vectors() {
        // Reference MurmurHash3_x86_32 values (SMHasher's implementation).
        assert_eq!(murmur3_32(b"", 0), 0);
        assert_eq!(murmur3_32(b"", 1), 0x514e_28b7);
        assert_eq!(murmur3_32(b"", 0xffff_ffff), 0x81f1_6f39);
        assert_eq!(murmur3_32(&[0, 0, 0, 0], 0), 0x2362_f9de);
        assert_eq!(murmur3_32(b"aaaa", 0x9747_b28c), 0x5a97_808a);
        assert_eq!(murmur3_32(b"aaa", 0x9747_b28c), 0x283e_0130);
        assert_eq!(murmur3_32(b"aa", 0x9747_b28c), 0x5d21_1726);
        assert_eq!(murmur3_32(b"a", 0x9747_b28c), 0x7fa0_9ea6);
        assert_eq!(murmur3_32(b"Hello, world!", 0x9747_b28c), 0x2488_4cba);
        assert_eq!(
            murmur3_32(b"The quick brown fox jumps over the lazy dog", 0x9747_b28c),
            0x2fa8_26cd
        );
    }

    #[test]
    fn ids_and_keys_match_the_specification_examples() {
        // Cryptomatte specification 1.1.0: the manifest `{"bunny":"13851a76",
        // "default":"42c9679f"}`.
        assert_eq!(format!("{:08x}", name_id("bunny").to_bits()), "13851a76");
        assert_eq!(format!("{:08x}", name_id("default").to_bits()), "42c9679f");
        // The key only has to stay the same from frame to frame and shot to shot (the spec's
        // own examples are arbitrary): this pins ours, the start of the name's hash.
        assert_eq!(murmur3_32(b"CryptoObject", 0), 0x3ae3_9a58);
        assert_eq!(layer_key(OBJECT_LAYER), "3ae39a5");
        // The exponent is clamped, sign and mantissa kept.
        assert_eq!(hash_to_float(0).to_bits(), 1 << 23);
        assert_eq!(hash_to_float(0xffff_ffff).to_bits(), 0xff7f_ffff);
        assert_eq!(hash_to_float(0x3f80_0001), f32::from_bits(0x3f80_0001));
        for h in [0u32, 0x7f80_0000, 0x7fff_ffff, 0x8000_0000, 0xff80_0001] {
            assert!(hash_to_float(h).is_normal(), "{h:08x}");
        }
    }

    #[test]
    fn coverage_ranks_by_weight_and_averages_over_rays() {
        let of_blob = [0, 0, 1, 2, NO_MATTE];
        let mut c = Coverage::new(&of_blob);
        c.add(0, 0.2);
        c.add(2, 0.5);
        c.add(1, 0.1);
        c.add(4, 0.3); // no matte: dropped
        c.add(9, 0.3); // past the table: dropped
        c.add(3, 0.1);
        let r = c.ranks(2);
        assert_eq!((r[0].matte, r[0].coverage), (1, 0.25));
        assert_eq!(r[1].matte, 0);
        assert!((r[1].coverage - 0.15).abs() < 1e-7);
        assert_eq!((r[2].matte, r[2].coverage), (2, 0.05));
        assert_eq!(r[3], Rank::EMPTY);
        // More mattes than slots: the first SLOTS are kept.
        let of_blob: Vec<u32> = (0..40).collect();
        let mut c = Coverage::new(&of_blob);
        for b in 0..40 {
            c.add(b, 1.0 + b as f32);
        }
        let r = c.ranks(1);
        assert_eq!(r[0].matte, SLOTS as u32 - 1);
    }

    #[test]
    fn channels_hold_id_coverage_pairs_and_the_header_the_manifest() {
        let mattes = Mattes {
            layer: OBJECT_LAYER.into(),
            names: vec!["bunny".into(), "default".into()],
            of_blob: vec![0, 1],
        };
        let mut m = IdMattes::empty(&mattes, 2);
        m.ranks[1][0] = Rank {
            matte: 1,
            coverage: 0.75,
        };
        m.ranks[1][1] = Rank {
            matte: 0,
            coverage: 0.25,
        };
        let ch: BTreeMap<String, Vec<f32>> = m.channels(&[0, 1]).into_iter().collect();
        assert_eq!(ch.len(), 12);
        assert_eq!(ch["CryptoObject00.R"], [0.0, name_id("default")]);
        assert_eq!(ch["CryptoObject00.G"], [0.0, 0.75]);
        assert_eq!(ch["CryptoObject00.B"], [0.0, name_id("bunny")]);
        assert_eq!(ch["CryptoObject00.A"], [0.0, 0.25]);
        assert_eq!(ch["CryptoObject02.A"], [0.0, 0.0]);
        let h: BTreeMap<String, String> = m.header().into_iter().collect();
        assert_eq!(h["cryptomatte/3ae39a5/name"], "CryptoObject");
        assert_eq!(h["cryptomatte/3ae39a5/hash"], "MurmurHash3_32");
        assert_eq!(h["cryptomatte/3ae39a5/conversion"], "uint32_to_float32");
        assert_eq!(
            h["cryptomatte/3ae39a5/manifest"],
            r#"{"bunny":"13851a76","default":"42c9679f"}"#
        );
    }
}
