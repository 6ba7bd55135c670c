//! Obstacle points in a spatially sorted structure-of-arrays, cut into small chunks with
//! bounding boxes, and the pruned "first obstacle touched" search of the growth stages.
//!
//! In: obstacle positions. Out: for a one-parameter family of nested regions, the smallest
//! parameter at which an obstacle enters, and that obstacle. Chunks are visited nearest first
//! (per seed) and skipped when their box misses the bounding box of the current best region,
//! which is exact because every family is nested in the parameter (see `grow`).

use glam::DVec3;

use crate::geometry::Aabb;

/// Obstacles per chunk.
const CHUNK: usize = 48;

/// Bits per axis of the Morton code used to sort obstacles.
const MORTON_BITS: u32 = 10;

/// A contiguous run of sorted obstacles and its bounding box.
#[derive(Clone, Copy, Debug)]
struct Chunk {
    start: u32,
    end: u32,
    bounds: Aabb,
}

/// Obstacles sorted along a Morton curve, as SoA coordinates, with chunk boxes.
#[derive(Clone, Debug)]
pub struct ObstacleSet {
    xs: Vec<f64>,
    ys: Vec<f64>,
    zs: Vec<f64>,
    normals: Vec<DVec3>,
    chunks: Vec<Chunk>,
}

/// Spread the low 10 bits of `v` to every third bit.
fn spread_bits(v: u32) -> u64 {
    let mut x = u64::from(v) & 0x3ff;
    x = (x | (x << 16)) & 0x0300_00ff;
    x = (x | (x << 8)) & 0x0300_f00f;
    x = (x | (x << 4)) & 0x030c_30c3;
    (x | (x << 2)) & 0x0924_9249
}

impl ObstacleSet {
    /// Sort `points` (with their unit `normals`, same length) along a Morton curve (ties by
    /// input order) and cut them into chunks.
    pub fn new(points: &[DVec3], normals: &[DVec3]) -> ObstacleSet {
        assert_eq!(points.len(), normals.len(), "one normal per obstacle");
        let bounds = Aabb::from_points(points);
        let size = bounds.size().max(DVec3::splat(1e-300));
        let cells = f64::from((1u32 << MORTON_BITS) - 1);
        let mut keyed: Vec<(u64, u32)> = points
            .iter()
            .enumerate()
            .map(|(i, p)| {
                let g = ((*p - bounds.min) / size * cells).clamp(DVec3::ZERO, DVec3::splat(cells));
                let code = spread_bits(g.x as u32)
                    | (spread_bits(g.y as u32) << 1)
                    | (spread_bits(g.z as u32) << 2);
                (code, i as u32)
            })
            .collect();
        keyed.sort_unstable();
        let pick = |f: fn(&DVec3) -> f64| -> Vec<f64> {
            keyed.iter().map(|&(_, i)| f(&points[i as usize])).collect()
        };
        let (xs, ys, zs) = (pick(|p| p.x), pick(|p| p.y), pick(|p| p.z));
        let normals = keyed.iter().map(|&(_, i)| normals[i as usize]).collect();
        let chunks = (0..keyed.len())
            .step_by(CHUNK)
            .map(|start| {
                let end = (start + CHUNK).min(keyed.len());
                let bounds =
                    (start..end).fold(Aabb::EMPTY, |b, i| b.grown(DVec3::new(xs[i], ys[i], zs[i])));
                Chunk {
                    start: start as u32,
                    end: end as u32,
                    bounds,
                }
            })
            .collect();
        ObstacleSet {
            xs,
            ys,
            zs,
            normals,
            chunks,
        }
    }

    /// Number of obstacles.
    pub fn len(&self) -> usize {
        self.xs.len()
    }

    /// True when there are no obstacles.
    pub fn is_empty(&self) -> bool {
        self.xs.is_empty()
    }

    /// Position of (sorted) obstacle `i`.
    pub fn position(&self, i: u32) -> DVec3 {
        let i = i as usize;
        DVec3::new(self.xs[i], self.ys[i], self.zs[i])
    }

    /// Unit normal of (sorted) obstacle `i` (the smooth normal of its sample).
    pub fn normal(&self, i: u32) -> DVec3 {
        self.normals[i as usize]
    }

    /// Fill `order` with every chunk index, nearest chunk box to `p` first (ties by index).
    pub fn chunks_by_distance(&self, p: DVec3, order: &mut Vec<(f64, u32)>) {
        order.clear();
        order.extend(self.chunks.iter().enumerate().map(|(k, c)| {
            let d = (c.bounds.min - p).max(p - c.bounds.max).max(DVec3::ZERO);
            (d.length_squared(), k as u32)
        }));
        order.sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    }

    /// Smallest `ratio(x − origin)` below `limit` over obstacles not in `skip`, and its
    /// obstacle. `ratio` returns `+∞` for obstacles the family never reaches. `region(t)` must
    /// bound (in world space) every obstacle whose ratio is below `t`; chunks outside the
    /// current region are skipped. Ties keep the first obstacle met (deterministic).
    pub fn first_touch(
        &self,
        order: &[(f64, u32)],
        origin: DVec3,
        limit: f64,
        skip: [u32; 2],
        region: impl Fn(f64) -> Option<Aabb>,
        ratio: impl Fn(f64, f64, f64) -> f64,
    ) -> (f64, Option<u32>) {
        let mut best = limit;
        let mut arg = None;
        let Some(mut bounds) = region(best) else {
            return (best, None);
        };
        for &(_, k) in order {
            let chunk = &self.chunks[k as usize];
            if !chunk.bounds.overlaps(&bounds) {
                continue;
            }
            let improved_from = best;
            let (s, e) = (chunk.start as usize, chunk.end as usize);
            let (xs, ys, zs) = (&self.xs[s..e], &self.ys[s..e], &self.zs[s..e]);
            for j in 0..xs.len() {
                let r = ratio(xs[j] - origin.x, ys[j] - origin.y, zs[j] - origin.z);
                if r < best {
                    let i = (s + j) as u32;
                    if i != skip[0] && i != skip[1] {
                        best = r;
                        arg = Some(i);
                    }
                }
            }
            if best < improved_from
                && let Some(b) = region(best)
            {
                bounds = b;
            }
        }
        (best, arg)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pruned_search_equals_brute_force() {
        let pts: Vec<DVec3> = (0..5000)
            .map(|i| {
                let f = i as f64;
                DVec3::new(
                    (f * 0.731).sin(),
                    (f * 1.917).cos(),
                    (f * 0.377).sin() * 0.5,
                )
            })
            .collect();
        let set = ObstacleSet::new(&pts, &vec![DVec3::Z; pts.len()]);
        assert_eq!(set.len(), pts.len());
        let mut order = Vec::new();
        for (t, &o) in pts.iter().step_by(500).enumerate() {
            let o = o * 0.3 + DVec3::splat(0.01 * t as f64);
            set.chunks_by_distance(o, &mut order);
            // Family: balls around `o`, parameter = squared distance.
            let (best, arg) = set.first_touch(
                &order,
                o,
                f64::INFINITY,
                [u32::MAX; 2],
                |t| {
                    Some(Aabb {
                        min: o - DVec3::splat(t.sqrt()),
                        max: o + DVec3::splat(t.sqrt()),
                    })
                },
                |x, y, z| x * x + y * y + z * z,
            );
            let brute = pts
                .iter()
                .map(|p| p.distance_squared(o))
                .fold(f64::INFINITY, f64::min);
            assert_eq!(best, brute);
            assert_eq!(set.position(arg.unwrap()).distance_squared(o), brute);
        }
    }
}
