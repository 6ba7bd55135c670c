//! What a ray sees of the blob cloud: the tile's candidate blobs (frustum culling), the blobs a
//! ray crosses, sorted by entry, and their merged spans ([`BlobMedium::gather`], with the
//! tile's cache of the ray origin's coordinates), the active window of hits along the ray
//! ([`ActiveHits`]), and the [`Medium`] impl that samples the density through them.

use glam::{Mat3A, Vec3A};

use super::BlobMedium;
use crate::render::camera::{Frustum, Ray, ray_ellipsoid};
use crate::render::counters::{self, Counter};
use crate::render::medium::Medium;
use crate::render::medium::density::{Hit, density};

/// Per-thread scratch of [`BlobMedium`].
#[derive(Debug, Default)]
pub struct BlobScratch {
    pub(super) tile: Vec<u32>,
    pub(super) hits: Vec<Hit>,
    pub(super) intervals: Vec<[f32; 2]>,
    /// Seconds from the medium's time for the next rays (see [`Medium::set_time_offset`]).
    pub(super) dt: f32,
    /// The hits spanning the last sampled `t`, in `hits`' order (see [`ActiveHits`]).
    pub(super) active: ActiveHits,
    /// What the gather keeps between rays (see [`GatherBuffers`]).
    pub(super) gather: GatherBuffers,
}

/// What [`BlobMedium::gather`] keeps between a thread's rays.
#[derive(Debug, Default)]
pub(super) struct GatherBuffers {
    /// The tile's candidates' coordinates of one ray origin (see [`OriginCache`]).
    pub(super) origin: OriginCache,
    /// The buffers that sort a ray's hits (see [`HitSort`]).
    pub(super) sort: HitSort,
}

/// Sorts a ray's hits by entry through 8-byte keys (entry, then gathering order) and one copy
/// of each hit into place, instead of swapping the 112-byte hits themselves (their sort had
/// been a tenth of a preview frame). Equal entries keep the gathering order.
#[derive(Debug, Default)]
pub(super) struct HitSort {
    pub(super) keys: Vec<u64>,
    pub(super) spare: Vec<Hit>,
}

impl HitSort {
    /// Sort `hits` by `t0` in `f32::total_cmp`'s order, ties in their current order.
    pub(super) fn sort(&mut self, hits: &mut Vec<Hit>) {
        if hits.len() < 2 {
            return;
        }
        self.keys.clear();
        self.keys.extend(hits.iter().enumerate().map(|(k, h)| {
            // `total_cmp`'s order as an unsigned integer's: negatives' bits flipped, the
            // others' sign bit set.
            let b = h.t0.to_bits();
            let key = if b >> 31 == 1 { !b } else { b | 0x8000_0000 };
            (u64::from(key) << 32) | k as u64
        }));
        self.keys.sort_unstable();
        self.spare.clear();
        self.spare
            .extend(self.keys.iter().map(|&k| hits[(k & 0xffff_ffff) as usize]));
        std::mem::swap(hits, &mut self.spare);
    }
}

/// The unit-support and noise coordinates of one ray origin in each of the tile's candidates'
/// frames. A camera's rays all start at its eye, so a tile's rays share them: the first ray of
/// a tile fills the cache and the others reuse it, half of the gather's matrix products. Rays
/// from elsewhere (the light grid's columns) compute their own.
#[derive(Debug, Default)]
pub(super) struct OriginCache {
    /// The origin the cache holds; `None` until the tile's first ray.
    pub(super) origin: Option<Vec3A>,
    /// Per candidate (the tile's order): `M·(origin − c)`.
    pub(super) unit: Vec<Vec3A>,
    /// Per candidate: `N·(origin − c) + offset`.
    pub(super) noise: Vec<Vec3A>,
}

/// The hits of the current ray that span the sample, kept as the ray's samples move forward:
/// hits enter when the ray reaches their start and are dropped once it has left them, so the
/// density visits only blobs the sample is in (a ray through a whole cloud had walked over about
/// 15 ended hits a sample). Same order as the ray's hit list, so the density's sums — and its
/// bits — are the same as over the whole list. A sample behind the last one starts over.
#[derive(Debug, Default)]
pub(super) struct ActiveHits {
    /// Indices into the ray's list (copying the hits themselves, 112 bytes each, had been a
    /// fifth of a preview frame).
    pub(super) list: Vec<u32>,
    /// Next hit of the ray's list to enter.
    pub(super) next: usize,
    /// The last sampled `t`.
    pub(super) t: f32,
    /// Smallest exit among `list`: nothing to drop before it.
    pub(super) drop_at: f32,
}

impl ActiveHits {
    /// Forget the window (a new ray).
    pub(super) fn reset(&mut self) {
        self.list.clear();
        self.next = 0;
        self.t = f32::NEG_INFINITY;
        self.drop_at = f32::INFINITY;
    }

    /// The indices, in `hits` (the ray's list, sorted by entry), of the hits with
    /// `t0 ≤ t ≤ t1`, in the list's order.
    #[inline]
    pub(super) fn at(&mut self, hits: &[Hit], t: f32) -> &[u32] {
        if t < self.t {
            self.reset();
        }
        self.t = t;
        if t > self.drop_at {
            self.list.retain(|&i| hits[i as usize].t1 >= t);
            self.drop_at = self
                .list
                .iter()
                .fold(f32::INFINITY, |m, &i| m.min(hits[i as usize].t1));
        }
        while let Some(h) = hits.get(self.next) {
            if h.t0 > t {
                break;
            }
            if h.t1 >= t {
                self.list.push(self.next as u32);
                self.drop_at = self.drop_at.min(h.t1);
            }
            self.next += 1;
        }
        &self.list
    }
}

impl BlobMedium {
    /// Gather the blobs of `candidates` crossed by `ray` into `hits` (sorted by entry) and their
    /// merged spans into `intervals`; `buffers.origin` caches the candidates' coordinates of a
    /// ray origin (filled by the tile's first ray; the same bits as computing them per ray).
    pub(super) fn gather(
        &self,
        candidates: &[u32],
        ray: &Ray,
        dt: f32,
        buffers: &mut GatherBuffers,
        hits: &mut Vec<Hit>,
        ivs: &mut Vec<[f32; 2]>,
    ) {
        hits.clear();
        ivs.clear();
        let moving = dt != 0.0 && !self.velocity.is_empty();
        let GatherBuffers { origin, sort } = buffers;
        if !moving && origin.origin.is_none() {
            origin.origin = Some(ray.origin);
            origin.unit.clear();
            origin.noise.clear();
            for &i in candidates {
                let i = i as usize;
                let rel = self.relative(i, ray.origin, 0.0, false);
                origin.unit.push(self.unit_from_world[i] * rel);
                origin.noise.push(self.noise_at(i, rel));
            }
        }
        let cached = !moving && origin.origin == Some(ray.origin);
        for (j, &i) in candidates.iter().enumerate() {
            let i = i as usize;
            let m = self.unit_from_world[i];
            // `None`: the cache holds this origin's coordinates.
            let rel = (!cached).then(|| self.relative(i, ray.origin, dt, moving));
            let o = rel.map_or_else(|| origin.unit[j], |rel| m * rel);
            let d = m * ray.dir;
            if let Some((t0, t1)) = ray_ellipsoid(o, d) {
                let no = rel.map_or_else(|| origin.noise[j], |rel| self.noise_at(i, rel));
                hits.push(Hit::new(
                    self.index[i],
                    (t0, t1),
                    self.b2[i],
                    self.feature[i],
                    self.half_min_support[i],
                    self.unit_from_world_t[i],
                    (o, d),
                    (no, self.noise_from_world[i] * ray.dir),
                ));
            }
        }
        sort.sort(hits);
        for h in hits.iter() {
            match ivs.last_mut() {
                Some(last) if h.t0 <= last[1] => last[1] = last[1].max(h.t1),
                _ => ivs.push([h.t0, h.t1]),
            }
        }
    }

    /// `(σ_t, inside)` under the cumulus base, if any (the density thins out below it).
    #[inline]
    pub(super) fn with_base(&self, (sigma, inside): (f32, bool), x: Vec3A) -> (f32, bool) {
        match &self.base {
            Some(b) if sigma > 0.0 => (sigma * b.factor(x.y), inside),
            _ => (sigma, inside),
        }
    }

    /// `σ_t` at parameter `t` of the ray whose `hits` were gathered (no base).
    #[cfg(test)]
    pub(super) fn density(&self, hits: &[Hit], t: f32) -> f32 {
        density(&self.params, hits, &all_of(hits), t).0
    }
}

/// The indices of all of `hits` (the whole list as the density's order).
#[cfg(test)]
pub(super) fn all_of(hits: &[Hit]) -> Vec<u32> {
    (0..hits.len() as u32).collect()
}

/// Count one density sample and the hits its loop walks over (only with the `counters`
/// feature; the active window holds no ended hit, so [`Counter::HitsEnded`] stays 0).
#[inline(always)]
fn count_sample(kind: Counter, hits: &[u32]) {
    if counters::ENABLED {
        counters::add(kind, 1);
        counters::add(Counter::HitsVisited, hits.len() as u64);
    }
}

impl Medium for BlobMedium {
    type Scratch = BlobScratch;

    fn scratch(&self) -> BlobScratch {
        BlobScratch::default()
    }

    fn begin_tile(&self, frustum: &Frustum, s: &mut BlobScratch) {
        s.tile.clear();
        s.gather.origin.origin = None;
        if self.velocity.is_empty() || self.sweep == 0.0 {
            s.tile.extend((0..self.len() as u32).filter(|&i| {
                frustum.may_contain_ball(self.center[i as usize], self.radius[i as usize])
            }));
        } else {
            // Wide enough for the blob anywhere within `±sweep` of the sample's time.
            s.tile.extend((0..self.len() as u32).filter(|&i| {
                let i = i as usize;
                let reach = self.radius[i] + self.velocity[i].length() * self.sweep;
                frustum.may_contain_ball(self.center[i], reach)
            }));
        }
    }

    fn begin_ray(&self, ray: &Ray, s: &mut BlobScratch) {
        let BlobScratch {
            tile,
            hits,
            intervals,
            active,
            dt,
            gather,
        } = s;
        self.gather(tile, ray, *dt, gather, hits, intervals);
        active.reset();
    }

    fn set_time_offset(&self, s: &mut BlobScratch, dt: f32) {
        s.dt = dt.clamp(-self.sweep, self.sweep);
    }

    fn intervals<'s>(&self, s: &'s BlobScratch) -> &'s [[f32; 2]] {
        &s.intervals
    }

    #[inline]
    fn extinction(&self, s: &mut BlobScratch, t: f32, x: Vec3A) -> f32 {
        let active = s.active.at(&s.hits, t);
        count_sample(Counter::LightSamples, active);
        self.with_base(density(&self.params, &s.hits, active, t), x)
            .0
    }

    #[inline]
    fn sample(&self, s: &mut BlobScratch, t: f32, x: Vec3A) -> (f32, bool) {
        let active = s.active.at(&s.hits, t);
        count_sample(Counter::MarchSamples, active);
        self.with_base(density(&self.params, &s.hits, active, t), x)
    }

    /// The blob with the largest field term `B²(1 − |q|²)²` among those the sample at `t` is in
    /// (the one that dominates the density there; ties: the first entered).
    #[inline]
    fn label(&self, s: &mut BlobScratch, t: f32) -> u32 {
        let active = s.active.at(&s.hits, t);
        let (mut best, mut label) = (0.0f32, crate::render::medium::NO_PIECE);
        for h in active.iter().map(|&i| &s.hits[i as usize]) {
            let (_, u) = h.offset_and_radius2(t);
            if u < 1.0 {
                let f = h.b2 * (1.0 - u) * (1.0 - u);
                if f > best {
                    (best, label) = (f, h.blob);
                }
            }
        }
        label
    }

    fn bounds(&self) -> Option<(Vec3A, Vec3A)> {
        BlobMedium::bounds(self)
    }

    /// The exact box of the supports in `frame`: an ellipsoid `c + M·u` (`|u| ≤ 1`) reaches
    /// `|row_r(frame·M)|` from its centre along row `r`.
    fn bounds_in(&self, frame: Mat3A) -> Option<(Vec3A, Vec3A)> {
        if self.is_empty() {
            return None;
        }
        let (mut lo, mut hi) = (Vec3A::splat(f32::MAX), Vec3A::splat(f32::MIN));
        for (c, unit) in self.center.iter().zip(&self.unit_from_world) {
            let f = (frame * unit.inverse()).transpose();
            let half = Vec3A::new(f.x_axis.length(), f.y_axis.length(), f.z_axis.length());
            let p = frame * *c;
            lo = lo.min(p - half);
            hi = hi.max(p + half);
        }
        Some((lo, hi))
    }

    fn step(&self) -> f32 {
        self.step
    }

    fn max_extinction(&self) -> f32 {
        self.params.sigma
    }

    fn empty_stride(&self) -> f32 {
        self.stride
    }

    fn tile_is_empty(&self, s: &BlobScratch) -> bool {
        s.tile.is_empty()
    }
}
