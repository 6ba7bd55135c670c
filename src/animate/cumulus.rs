//! `builtin:cumulus`: a procedural cumulus cloud as a blob set — a flat base of wide, thin
//! blobs and a heaped, billowy top of round puffs, larger and higher toward the middle. Usable
//! wherever a model is (`Model("builtin:cumulus")`), e.g. as a morph's `from`.
//!
//! Units: about 2 wide, 1 tall, base at `y = 0`. Every blob has `A = 1`, `B = (1+A)/A`, so
//! alone it fills its ellipsoid. Deterministic (a fixed seed).

use glam::{DQuat, DVec3};
use rand::RngExt;

use crate::blobby::{Blob, BlobModel, THRESHOLD};
use crate::rng::{Stream, item_rng};

/// The name after `builtin:`.
pub const NAME: &str = "cumulus";

/// Puffs of the heaped top.
const PUFFS: usize = 60;

/// The cumulus blob model.
pub fn cumulus() -> BlobModel {
    let mut blobs = Vec::new();
    let blob = |center: DVec3, semi_axes: DVec3, spin: f64| Blob {
        center,
        rotation: DQuat::from_rotation_y(spin),
        semi_axes,
        a: 1.0,
        b: 2.0,
    };
    // Flat base: a ring and a centre of wide, thin ellipsoids just above y = 0.
    blobs.push(blob(
        DVec3::new(0.0, 0.12, 0.0),
        DVec3::new(0.6, 0.12, 0.5),
        0.0,
    ));
    for k in 0..10 {
        let a = k as f64 * std::f64::consts::TAU / 10.0;
        let c = DVec3::new(0.65 * a.cos(), 0.12, 0.45 * a.sin());
        blobs.push(blob(c, DVec3::new(0.38, 0.11, 0.28), a));
    }
    // Heaped top: puffs in a dome, bigger and higher toward the middle.
    for k in 0..PUFFS {
        let mut rng = item_rng(0xC0C0, Stream::Animate, k as u64);
        let r = rng.random::<f64>().sqrt() * 0.85;
        let phi = rng.random::<f64>() * std::f64::consts::TAU;
        let falloff = 1.0 - (r / 0.95).powi(2);
        let y = 0.2 + 0.65 * falloff * (0.5 + 0.5 * rng.random::<f64>());
        let size = 0.14 + 0.16 * falloff * (0.6 + 0.4 * rng.random::<f64>());
        let c = DVec3::new(r * phi.cos(), y, 0.75 * r * phi.sin());
        blobs.push(blob(c, DVec3::new(size, size * 0.9, size), phi));
    }
    // Largest first, like a decomposition's selection order.
    blobs.sort_by(|a, b| {
        b.semi_axes
            .element_product()
            .total_cmp(&a.semi_axes.element_product())
    });
    BlobModel::from_blobs(&format!("builtin:{NAME}"), THRESHOLD, 0, blobs)
}

/// The builtin blob model called `name` (after `builtin:`), if there is one.
pub fn builtin_model(name: &str) -> Option<BlobModel> {
    (name == NAME).then(cumulus)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::animate::stats::{Lattice, visible_volume};

    #[test]
    fn cumulus_is_one_flat_based_piece_wider_than_tall() {
        let m = cumulus();
        let b = super::super::blob_bounds(&m.blobs);
        let size = b.size();
        assert!(size.x > 1.5 * size.y, "{size}");
        assert!(b.min.y.abs() < 0.05, "flat base at y = 0: {}", b.min.y);
        let v = visible_volume(&m.blobs, m.threshold, Lattice::for_target(&b, 0.01));
        assert_eq!(v.components, 1, "{v:?}");
        assert_eq!(m, cumulus(), "deterministic");
    }
}
