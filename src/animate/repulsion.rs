//! Pairwise blob repulsion for aggregation keyframes, through a uniform grid (sorted cell keys,
//! no per-blob allocation), so 1000-blob models cost about as much as 100-blob ones per blob.
//!
//! Each step is a Jacobi update (every blob reads the previous positions), computed in
//! parallel and independent of the thread count.

use glam::DVec3;
use rayon::prelude::*;

use crate::blobby::Blob;
use crate::geometry::Aabb;
use crate::rng::mix64;

/// Blobs that belong to no cluster (dead blobs): they neither move nor push.
pub(crate) const NO_CLUSTER: usize = usize::MAX;

/// Push apart blobs whose centres are closer than `factor · (r_i + r_j)` (`r` = equivalent
/// radius), for `steps` steps; after each step blob `i`'s centre is clamped into
/// `boxes[owner[i]]`. Blobs with `owner[i] == NO_CLUSTER` take no part. Blobs with equal
/// centres are separated along a hashed direction.
pub(crate) fn repel(
    blobs: &mut [Blob],
    owner: &[usize],
    boxes: &[Aabb],
    factor: f64,
    steps: usize,
) {
    // Compact arrays over the blobs that take part.
    let active: Vec<usize> = (0..blobs.len())
        .filter(|&i| owner[i] != NO_CLUSTER)
        .collect();
    let n = active.len();
    if n < 2 {
        return;
    }
    let radius: Vec<f64> = active
        .iter()
        .map(|&i| blobs[i].equivalent_radius() * factor)
        .collect();
    let r_max = radius.iter().copied().fold(0.0, f64::max);
    if r_max <= 0.0 {
        return;
    }
    // Any interacting pair is closer than 2 r_max, so neighbours lie in the 27 adjacent cells.
    let cell = 2.0 * r_max;
    let mut pos: Vec<DVec3> = active.iter().map(|&i| blobs[i].center).collect();
    let mut order: Vec<u32> = (0..n as u32).collect();
    let mut keys: Vec<(i64, i64, i64)> = vec![(0, 0, 0); n];
    for _ in 0..steps {
        let cell_of = |p: DVec3| {
            let c = (p / cell).floor();
            (c.x as i64, c.y as i64, c.z as i64)
        };
        for (k, p) in keys.iter_mut().zip(&pos) {
            *k = cell_of(*p);
        }
        order.sort_unstable_by_key(|&a| (keys[a as usize], a));
        let sorted: Vec<(i64, i64, i64)> = order.iter().map(|&a| keys[a as usize]).collect();
        let next: Vec<DVec3> = (0..n)
            .into_par_iter()
            .map(|a| {
                let (cx, cy, cz) = keys[a];
                let mut push = DVec3::ZERO;
                for dz in -1..=1 {
                    for dy in -1..=1 {
                        for dx in -1..=1 {
                            let key = (cx + dx, cy + dy, cz + dz);
                            let start = sorted.partition_point(|k| *k < key);
                            for (&k, &b) in sorted[start..].iter().zip(&order[start..]) {
                                if k != key {
                                    break;
                                }
                                let b = b as usize;
                                if b != a {
                                    let reach = radius[a] + radius[b];
                                    push += pair_push(pos[a], pos[b], reach, active[a], active[b]);
                                }
                            }
                        }
                    }
                }
                let bx = &boxes[owner[active[a]]];
                (pos[a] + 0.5 * push).clamp(bx.min, bx.max)
            })
            .collect();
        pos = next;
    }
    for (&i, p) in active.iter().zip(pos) {
        blobs[i].center = p;
    }
}

/// Half the overlap of `i` with `j` along the line of centres, pushing `i` away from `j`.
#[inline]
fn pair_push(pi: DVec3, pj: DVec3, reach: f64, i: usize, j: usize) -> DVec3 {
    let d = pi - pj;
    let dist = d.length();
    if dist >= reach {
        return DVec3::ZERO;
    }
    let dir = if dist > 1e-12 * reach {
        d / dist
    } else {
        // Coincident centres: a direction hashed from the unordered pair, opposite for i and j.
        let (lo, hi) = (i.min(j) as u64, i.max(j) as u64);
        let h = mix64(lo << 32 ^ hi);
        let a = (h & 0xffff) as f64 / 65536.0 * std::f64::consts::TAU;
        let z = ((h >> 16) & 0xffff) as f64 / 32768.0 - 1.0;
        let r = (1.0 - z * z).max(0.0).sqrt();
        let v = DVec3::new(r * a.cos(), z, r * a.sin());
        if i < j { v } else { -v }
    };
    dir * (0.5 * (reach - dist))
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DQuat;

    fn ball(center: DVec3, r: f64) -> Blob {
        Blob {
            center,
            rotation: DQuat::IDENTITY,
            semi_axes: DVec3::splat(r),
            a: 1.0,
            b: 2.0,
        }
    }

    #[test]
    fn overlapping_pair_separates_and_stays_in_box() {
        let mut blobs = vec![ball(DVec3::ZERO, 1.0), ball(DVec3::new(0.5, 0.0, 0.0), 1.0)];
        let boxes = [Aabb {
            min: DVec3::splat(-2.0),
            max: DVec3::splat(2.0),
        }];
        repel(&mut blobs, &[0, 0], &boxes, 1.0, 20);
        let d = (blobs[0].center - blobs[1].center).length();
        assert!(d > 1.9 && d <= 2.0 + 1e-9, "distance {d}");
        // Symmetric push about the midpoint.
        assert!((blobs[0].center + blobs[1].center - DVec3::new(0.5, 0.0, 0.0)).length() < 1e-9);
        // Coincident centres separate too.
        let mut same = vec![ball(DVec3::ZERO, 1.0), ball(DVec3::ZERO, 1.0)];
        repel(&mut same, &[0, 0], &boxes, 1.0, 20);
        assert!((same[0].center - same[1].center).length() > 1.9);
    }
}
