//! A bounding-volume hierarchy over triangles for the nearest hit along a ray
//! ([`TriangleBvh::hit`]): binary, split at the median of the centroids along the longest axis
//! of their box, at most [`LEAF`] triangles a leaf, in `f32` (the camera's rays are); the
//! children visited nearer first, their boxes by the slab test, the triangles by Möller–Trumbore.
//! Built once per shot (the holdouts), cast from many threads.

use glam::{DVec3, Vec3A};

/// Most triangles in a leaf.
const LEAF: usize = 4;

/// Deepest traversal stack (a median split of 2³² triangles is 32 levels deep).
const STACK: usize = 64;

#[derive(Clone, Copy, Debug)]
struct Node {
    lo: Vec3A,
    hi: Vec3A,
    /// A leaf's first triangle, or an inner node's second child (its first is the next node).
    index: u32,
    /// A leaf's triangle count; 0 for an inner node.
    count: u32,
}

/// A triangle as Möller–Trumbore wants it: a corner and the two edges from it.
#[derive(Clone, Copy, Debug)]
struct Tri {
    v0: Vec3A,
    e1: Vec3A,
    e2: Vec3A,
}

/// The hierarchy (see the module doc).
#[derive(Clone, Debug, Default)]
pub(crate) struct TriangleBvh {
    nodes: Vec<Node>,
    tris: Vec<Tri>,
}

impl TriangleBvh {
    /// The hierarchy of `triangles` (indices into `positions`, which must be in range).
    pub(crate) fn new(positions: &[DVec3], triangles: &[[u32; 3]]) -> TriangleBvh {
        let corners: Vec<[Vec3A; 3]> = triangles
            .iter()
            .map(|t| t.map(|i| positions[i as usize].as_vec3a()))
            .collect();
        let centroids: Vec<Vec3A> = corners
            .iter()
            .map(|c| (c[0] + c[1] + c[2]) * (1.0 / 3.0))
            .collect();
        let mut order: Vec<u32> = (0..triangles.len() as u32).collect();
        let mut nodes = Vec::with_capacity(2 * triangles.len() / LEAF + 1);
        if !order.is_empty() {
            build(&corners, &centroids, &mut order, 0, &mut nodes);
        }
        let tris = order
            .iter()
            .map(|&i| {
                let [a, b, c] = corners[i as usize];
                Tri {
                    v0: a,
                    e1: b - a,
                    e2: c - a,
                }
            })
            .collect();
        TriangleBvh { nodes, tris }
    }

    /// Number of triangles.
    pub(crate) fn len(&self) -> usize {
        self.tris.len()
    }

    /// The nearest hit's distance `t ∈ (0, max]` along `origin + t·dir`.
    #[inline]
    pub(crate) fn hit(&self, origin: Vec3A, dir: Vec3A, max: f32) -> Option<f32> {
        self.traverse::<false>(origin, dir, max).map(|(t, _)| t)
    }

    /// The nearest hit's distance and the unit normal of the triangle hit, facing against
    /// `dir` (the side the ray sees).
    #[inline]
    pub(crate) fn hit_normal(&self, origin: Vec3A, dir: Vec3A, max: f32) -> Option<(f32, Vec3A)> {
        let (t, i) = self.traverse::<false>(origin, dir, max)?;
        let tri = &self.tris[i];
        let n = tri.e1.cross(tri.e2).normalize_or_zero();
        Some((t, if n.dot(dir) > 0.0 { -n } else { n }))
    }

    /// Whether any triangle lies on `origin + t·dir`, `t ∈ (0, max)` (the first hit found
    /// ends the search: shadow rays).
    #[inline]
    pub(crate) fn occluded(&self, origin: Vec3A, dir: Vec3A, max: f32) -> bool {
        self.traverse::<true>(origin, dir, max).is_some()
    }

    /// The nearest hit and its triangle, or with `ANY` the first found.
    #[inline]
    fn traverse<const ANY: bool>(
        &self,
        origin: Vec3A,
        dir: Vec3A,
        max: f32,
    ) -> Option<(f32, usize)> {
        if self.nodes.is_empty() {
            return None;
        }
        let inv = dir.recip();
        let mut best = max;
        let mut found = None;
        let mut stack = [0u32; STACK];
        let mut top = 0usize;
        let mut node = 0usize;
        loop {
            let n = &self.nodes[node];
            if n.count > 0 {
                let first = n.index as usize;
                for (i, tri) in self.tris[first..first + n.count as usize]
                    .iter()
                    .enumerate()
                {
                    if let Some(t) = intersect(tri, origin, dir, best) {
                        if ANY {
                            return Some((t, first + i));
                        }
                        best = t;
                        found = Some(first + i);
                    }
                }
            } else {
                let (a, b) = (node + 1, n.index as usize);
                let ta = slab(&self.nodes[a], origin, inv, best);
                let tb = slab(&self.nodes[b], origin, inv, best);
                match (ta, tb) {
                    (Some(ta), Some(tb)) => {
                        let (near, far) = if ta <= tb { (a, b) } else { (b, a) };
                        if top < STACK {
                            stack[top] = far as u32;
                            top += 1;
                        }
                        node = near;
                        continue;
                    }
                    (Some(_), None) => {
                        node = a;
                        continue;
                    }
                    (None, Some(_)) => {
                        node = b;
                        continue;
                    }
                    (None, None) => {}
                }
            }
            if top == 0 {
                break;
            }
            top -= 1;
            node = stack[top] as usize;
        }
        found.map(|i| (best, i))
    }
}

/// Build the subtree of `order` (triangle indices) into `nodes`; returns its root's index.
fn build(
    corners: &[[Vec3A; 3]],
    centroids: &[Vec3A],
    order: &mut [u32],
    offset: usize,
    nodes: &mut Vec<Node>,
) -> usize {
    let (mut lo, mut hi) = (Vec3A::splat(f32::INFINITY), Vec3A::splat(f32::NEG_INFINITY));
    let (mut clo, mut chi) = (lo, hi);
    for &i in order.iter() {
        for c in corners[i as usize] {
            lo = lo.min(c);
            hi = hi.max(c);
        }
        clo = clo.min(centroids[i as usize]);
        chi = chi.max(centroids[i as usize]);
    }
    let me = nodes.len();
    nodes.push(Node {
        lo,
        hi,
        index: offset as u32,
        count: order.len() as u32,
    });
    if order.len() <= LEAF {
        return me;
    }
    let extent = chi - clo;
    let axis = if extent.x >= extent.y && extent.x >= extent.z {
        0
    } else if extent.y >= extent.z {
        1
    } else {
        2
    };
    let mid = order.len() / 2;
    order.select_nth_unstable_by(mid, |&a, &b| {
        centroids[a as usize][axis].total_cmp(&centroids[b as usize][axis])
    });
    let (left, right) = order.split_at_mut(mid);
    build(corners, centroids, left, offset, nodes);
    let second = build(corners, centroids, right, offset + mid, nodes);
    nodes[me].index = second as u32;
    nodes[me].count = 0;
    me
}

/// Entry distance of the ray into the node's box if it enters before `max`.
#[inline]
fn slab(n: &Node, origin: Vec3A, inv: Vec3A, max: f32) -> Option<f32> {
    let t0 = (n.lo - origin) * inv;
    let t1 = (n.hi - origin) * inv;
    let near = t0.min(t1).max_element().max(0.0);
    let far = t0.max(t1).min_element().min(max);
    // NaN (a zero direction component on the box's face) fails the test: a miss.
    (near <= far).then_some(near)
}

/// Slack of the barycentric bounds: a ray through the edge two triangles share hits one of
/// them (no crack between them to see through).
const EDGE_SLACK: f32 = 1e-5;

/// Möller–Trumbore: the ray's distance to the triangle if in `(0, max)`.
#[inline]
fn intersect(tri: &Tri, origin: Vec3A, dir: Vec3A, max: f32) -> Option<f32> {
    let p = dir.cross(tri.e2);
    let det = tri.e1.dot(p);
    if det.abs() < 1e-20 {
        return None;
    }
    let inv = 1.0 / det;
    let s = origin - tri.v0;
    let u = s.dot(p) * inv;
    if !(-EDGE_SLACK..=1.0 + EDGE_SLACK).contains(&u) {
        return None;
    }
    let q = s.cross(tri.e1);
    let v = dir.dot(q) * inv;
    if v < -EDGE_SLACK || u + v > 1.0 + EDGE_SLACK {
        return None;
    }
    let t = tri.e2.dot(q) * inv;
    (t > 0.0 && t < max).then_some(t)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Against every triangle tested in turn, on a bumpy grid of triangles and random rays.
    #[test]
    fn nearest_hits_match_a_loop_over_the_triangles() {
        let n = 40usize;
        let mut positions = Vec::new();
        for j in 0..n {
            for i in 0..n {
                let (x, z) = (i as f64 / 10.0, j as f64 / 10.0);
                positions.push(DVec3::new(x, 0.3 * (3.0 * x).sin() * (2.0 * z).cos(), z));
            }
        }
        let mut triangles = Vec::new();
        for j in 0..n - 1 {
            for i in 0..n - 1 {
                let v = (j * n + i) as u32;
                triangles.push([v, v + n as u32, v + 1]);
                triangles.push([v + 1, v + n as u32, v + n as u32 + 1]);
            }
        }
        let bvh = TriangleBvh::new(&positions, &triangles);
        assert_eq!(bvh.len(), triangles.len());
        let mut state = 12345u64;
        let mut rand = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 40) as f32 / (1u64 << 24) as f32
        };
        let (mut hits, mut rays) = (0, 0);
        for _ in 0..2000 {
            let origin = Vec3A::new(4.0 * rand(), 1.0 + rand(), 4.0 * rand());
            let dir = Vec3A::new(rand() - 0.5, -rand() - 0.05, rand() - 0.5).normalize();
            let brute = bvh
                .tris
                .iter()
                .filter_map(|t| intersect(t, origin, dir, f32::MAX))
                .min_by(f32::total_cmp);
            let got = bvh.hit(origin, dir, f32::MAX);
            assert_eq!(got, brute);
            assert_eq!(bvh.occluded(origin, dir, f32::MAX), brute.is_some());
            hits += got.is_some() as usize;
            rays += 1;
        }
        assert!(hits > rays / 3, "{hits} of {rays}");
    }
}
