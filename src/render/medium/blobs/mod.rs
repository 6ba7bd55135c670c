//! The blob cloud as a participating medium: f32 SoA blobs, ray gathering and the noisy
//! density (the light grid is built from it separately, [`crate::render::light::grid`]).
//!
//! In: a frame's [`Blob`]s (f64; slice index = identity) and [`RenderSettings`]. Out:
//! [`BlobMedium`], a [`Medium`] for the integrator.
//!
//! The density each sample sees is the model in [`crate::render::medium::density`].

use glam::{Mat3A, Vec3A};
use rand::RngExt;

use crate::blobby::{Blob, THRESHOLD};
use crate::render::camera::{Frustum, Ray, ray_ellipsoid};
use crate::render::counters::{self, Counter};
use crate::render::medium::Medium;
use crate::render::medium::density::{DensityParams, Hit, density};
use crate::render::medium::noise::Billows;
use crate::render::settings::{BasePlane, RenderSettings};
use crate::rng::{Stream, item_rng};

/// Finest billow wavelength in pixels of the frame (at the camera's look-at distance): finer
/// octaves would only alias at one sample per pixel.
pub const FINEST_BILLOW_PIXELS: f32 = 3.0;

/// Blobs smaller than this fraction of the largest (mean support radius) are specks that do
/// not set the march step ([`BlobMedium`]'s `step_for`).
pub const SPECK: f32 = 0.05;

/// Smallest `A` the renderer gives a blob: the shell between a blob's iso-surface and the end
/// of its support must hold the billows' tops (at the fitted minimum, 0.05, it is 2 % of the
/// radius, and the billows flattened against the support into a thin glassy dome).
pub const MIN_RENDER_A: f64 = 0.6;

/// `(A', B')` with `A' ≥` [`MIN_RENDER_A`] and the blob's own iso-surface unchanged:
/// `(1 + A')(1 − 1/B') = (1 + A)(1 − 1/B)` (for `t = 1`). A blob that cannot reach the iso-level
/// alone (`B ≤ 1`) is kept as it is.
pub fn roomy_support(a: f64, b: f64) -> (f64, f64) {
    if a >= MIN_RENDER_A || b <= 1.0 {
        return (a, b);
    }
    let iso = (1.0 + a) * (1.0 - 1.0 / b);
    (MIN_RENDER_A, 1.0 / (1.0 - iso / (1.0 + MIN_RENDER_A)))
}

/// Per-thread scratch of [`BlobMedium`].
#[derive(Debug, Default)]
pub struct BlobScratch {
    tile: Vec<u32>,
    hits: Vec<Hit>,
    intervals: Vec<[f32; 2]>,
    /// Seconds from the medium's time for the next rays (see [`Medium::set_time_offset`]).
    dt: f32,
    /// The hits spanning the last sampled `t`, in `hits`' order (see [`ActiveHits`]).
    active: ActiveHits,
    /// What the gather keeps between rays (see [`GatherBuffers`]).
    gather: GatherBuffers,
}

/// What [`BlobMedium::gather`] keeps between a thread's rays.
#[derive(Debug, Default)]
struct GatherBuffers {
    /// The tile's candidates' coordinates of one ray origin (see [`OriginCache`]).
    origin: OriginCache,
    /// The buffers that sort a ray's hits (see [`HitSort`]).
    sort: HitSort,
}

/// Sorts a ray's hits by entry through 8-byte keys (entry, then gathering order) and one copy
/// of each hit into place, instead of swapping the 144-byte hits themselves (their sort had
/// been a tenth of a preview frame). Equal entries keep the gathering order.
#[derive(Debug, Default)]
struct HitSort {
    keys: Vec<u64>,
    spare: Vec<Hit>,
}

impl HitSort {
    /// Sort `hits` by `t0` in `f32::total_cmp`'s order, ties in their current order.
    fn sort(&mut self, hits: &mut Vec<Hit>) {
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
struct OriginCache {
    /// The origin the cache holds; `None` until the tile's first ray.
    origin: Option<Vec3A>,
    /// Per candidate (the tile's order): `M·(origin − c)`.
    unit: Vec<Vec3A>,
    /// Per candidate: `N·(origin − c) + offset`.
    noise: Vec<Vec3A>,
}

/// The hits of the current ray that span the sample, kept as the ray's samples move forward:
/// hits enter when the ray reaches their start and are dropped once it has left them, so the
/// density visits only blobs the sample is in (a ray through a whole cloud had walked over about
/// 15 ended hits a sample). Same order as the ray's hit list, so the density's sums — and its
/// bits — are the same as over the whole list. A sample behind the last one starts over.
#[derive(Debug, Default)]
struct ActiveHits {
    /// Indices into the ray's list (copying the hits themselves, 144 bytes each, had been a
    /// fifth of a preview frame).
    list: Vec<u32>,
    /// Next hit of the ray's list to enter.
    next: usize,
    /// The last sampled `t`.
    t: f32,
    /// Smallest exit among `list`: nothing to drop before it.
    drop_at: f32,
}

impl ActiveHits {
    /// Forget the window (a new ray).
    fn reset(&mut self) {
        self.list.clear();
        self.next = 0;
        self.t = f32::NEG_INFINITY;
        self.drop_at = f32::INFINITY;
    }

    /// The indices, in `hits` (the ray's list, sorted by entry), of the hits with
    /// `t0 ≤ t ≤ t1`, in the list's order.
    #[inline]
    fn at(&mut self, hits: &[Hit], t: f32) -> &[u32] {
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

/// The blob cloud of one frame (live blobs only, SoA, f32). Equal media have equal density
/// everywhere (what a hold's frames reuse, [`crate::render::FrameRenderer`]).
#[derive(Clone, Debug, PartialEq)]
pub struct BlobMedium {
    /// Each live blob's index in the frame's list (its identity).
    index: Vec<u32>,
    center: Vec<Vec3A>,
    /// `diag(1/(s√(1+A)))·Rᵀ`: world offset → unit-support coordinates.
    unit_from_world: Vec<Mat3A>,
    /// Its transpose (the density's gradient needs it at every hit).
    unit_from_world_t: Vec<Mat3A>,
    /// `(frequency/L)·Rᵀ`: world offset → noise coordinates (before the offset).
    noise_from_world: Vec<Mat3A>,
    noise_offset: Vec<Vec3A>,
    b2: Vec<f32>,
    /// Feature size: the median semi-axis.
    feature: Vec<f32>,
    /// Half the smallest support semi-axis.
    half_min_support: Vec<f32>,
    /// Bounding-ball radius of the support.
    radius: Vec<f32>,
    lo: Vec<Vec3A>,
    hi: Vec<Vec3A>,
    params: DensityParams,
    step: f32,
    /// The cumulus base, if any.
    base: Option<BasePlane>,
    /// Velocity of each live blob's centre (world units per second); empty for a still cloud.
    velocity: Vec<Vec3A>,
    /// Largest time offset `|dt|` the rays may ask for (seconds): the tile culling widens each
    /// blob by `|v|·sweep`.
    sweep: f32,
}

impl BlobMedium {
    /// Prepare `blobs` for rendering with `settings`: convert and derive the step. Dead blobs
    /// (`B = 0`, a zero or non-finite size) are dropped here.
    pub fn new(settings: &RenderSettings, blobs: &[Blob]) -> BlobMedium {
        Self::build(settings, blobs, None)
    }

    /// [`BlobMedium::new`] for a motion-blur time sample: the blobs at the sample's time and
    /// their centres' velocities (`velocity[i]` for `blobs[i]`), so that a ray may ask for the
    /// cloud up to `sweep` seconds either side of it ([`Medium::set_time_offset`]: each blob
    /// moves with its centre's velocity; rotation and growth are held for that short while).
    pub fn moving(
        settings: &RenderSettings,
        blobs: &[Blob],
        velocity: &[glam::DVec3],
        sweep: f32,
    ) -> BlobMedium {
        let mut m = Self::build(settings, blobs, Some(velocity));
        m.sweep = sweep.abs();
        m
    }

    /// Use `step` as the coarse march step (all time samples of a frame march alike).
    pub fn set_step(&mut self, step: f32) {
        self.step = step;
    }

    fn build(
        settings: &RenderSettings,
        blobs: &[Blob],
        velocity: Option<&[glam::DVec3]>,
    ) -> BlobMedium {
        let length = settings.length_scale.max(1e-12);
        let noise = settings.cloud.noise;
        // Octave 0's wavelength; the noise frames below are in its units.
        let largest = length / noise.frequency.max(1e-6);
        let freq = 1.0 / largest;
        let mut m = BlobMedium {
            index: Vec::new(),
            center: Vec::new(),
            unit_from_world: Vec::new(),
            unit_from_world_t: Vec::new(),
            noise_from_world: Vec::new(),
            noise_offset: Vec::new(),
            b2: Vec::new(),
            feature: Vec::new(),
            half_min_support: Vec::new(),
            radius: Vec::new(),
            lo: Vec::new(),
            hi: Vec::new(),
            params: DensityParams {
                sigma: settings.cloud.density.max(0.0) / length,
                edge: settings.cloud.edge.max(0.0) * length,
                billows: Billows::new(
                    noise.octaves,
                    largest,
                    FINEST_BILLOW_PIXELS * settings.pixel_footprint(),
                    noise.amplitude,
                    noise.evolve * settings.time,
                ),
                inv_threshold: (1.0 / THRESHOLD) as f32,
            },
            base: settings.base,
            step: 0.0,
            velocity: Vec::new(),
            sweep: 0.0,
        };
        let mut radii = Vec::new();
        for (index, blob) in blobs.iter().enumerate() {
            let finite = blob.center.is_finite()
                && blob.semi_axes.is_finite()
                && blob.rotation.is_finite()
                && blob.a.is_finite()
                && blob.b.is_finite();
            if !finite || !blob.is_live() || blob.a <= 0.0 {
                continue;
            }
            let (a, b) = roomy_support(blob.a, blob.b);
            let support = (blob.semi_axes * (1.0 + a).sqrt()).as_vec3();
            let world_from_local = Mat3A::from_quat(blob.rotation.as_quat().normalize());
            let local_from_world = world_from_local.transpose();
            let center = Vec3A::from(blob.center.as_vec3());
            // Column j of R·diag(s) is the j-th support axis; its |row i| is the half extent.
            let axes = Mat3A::from_cols(
                world_from_local.x_axis * support.x,
                world_from_local.y_axis * support.y,
                world_from_local.z_axis * support.z,
            )
            .transpose();
            let half = Vec3A::new(
                axes.x_axis.length(),
                axes.y_axis.length(),
                axes.z_axis.length(),
            );
            let mut rng = item_rng(settings.seed, Stream::Noise, index as u64);
            let offset = Vec3A::new(
                rng.random_range(-128.0..128.0),
                rng.random_range(-128.0..128.0),
                rng.random_range(-128.0..128.0),
            );
            if let Some(v) = velocity {
                let v = v.get(index).copied().unwrap_or_default();
                m.velocity.push(if v.is_finite() {
                    Vec3A::from(v.as_vec3())
                } else {
                    Vec3A::ZERO
                });
            }
            m.index.push(index as u32);
            m.center.push(center);
            let unit_from_world = Mat3A::from_diagonal(support.recip()) * local_from_world;
            m.unit_from_world.push(unit_from_world);
            m.unit_from_world_t.push(unit_from_world.transpose());
            m.noise_from_world.push(local_from_world * freq);
            m.noise_offset.push(offset);
            m.b2.push((b * b) as f32);
            let mean_radius = (support.x * support.y * support.z).cbrt();
            let s = blob.semi_axes.as_vec3();
            m.feature.push(s.x.max(s.y).min(s.z).max(s.x.min(s.y)));
            m.half_min_support.push(0.5 * support.min_element());
            m.radius.push(support.max_element());
            m.lo.push(center - half);
            m.hi.push(center + half);
            radii.push(mean_radius);
        }
        m.step = Self::step_for(settings, &mut radii);
        m
    }

    /// March step: `step_scale ×` the median support radius of the blobs that shape the cloud
    /// (those at least [`SPECK`] of the largest), clamped to `[L/2000, L/16]` (`L` the length
    /// scale).
    ///
    /// Specks are left out because the blobs being born in a diffusion start near size 0: the
    /// frame in which 46 of the duck's 52 blobs appeared took a median of 0.0008 and marched
    /// at `L/2000`, six times as slowly as its neighbours. A speck is never stepped over: the
    /// coarse steps are clipped to the intervals of the supports.
    fn step_for(settings: &RenderSettings, radii: &mut [f32]) -> f32 {
        let length = settings.length_scale.max(1e-12);
        if radii.is_empty() {
            return length / 16.0;
        }
        radii.sort_by(f32::total_cmp);
        let largest = radii[radii.len() - 1];
        let shaping = &radii[radii.partition_point(|&r| r < SPECK * largest)..];
        let typical = shaping[shaping.len() / 2];
        (settings.quality.step_scale * typical).clamp(length / 2000.0, length / 16.0)
    }

    /// Number of live blobs.
    pub fn len(&self) -> usize {
        self.center.len()
    }

    /// True when no blob is live.
    pub fn is_empty(&self) -> bool {
        self.center.is_empty()
    }

    /// Union of the live supports' bounds, `None` when empty.
    pub fn bounds(&self) -> Option<(Vec3A, Vec3A)> {
        if self.is_empty() {
            return None;
        }
        let lo = self
            .lo
            .iter()
            .fold(Vec3A::splat(f32::MAX), |a, &b| a.min(b));
        let hi = self
            .hi
            .iter()
            .fold(Vec3A::splat(f32::MIN), |a, &b| a.max(b));
        Some((lo, hi))
    }

    /// The point `x` (world) relative to blob `i`'s centre at time offset `dt` from the
    /// medium's time (`moving`: the blobs have velocities and `dt ≠ 0`).
    #[inline]
    fn relative(&self, i: usize, x: Vec3A, dt: f32, moving: bool) -> Vec3A {
        if moving {
            x - (self.center[i] + self.velocity[i] * dt)
        } else {
            x - self.center[i]
        }
    }

    /// Blob `i`'s noise coordinates of a point at `rel` from its centre.
    #[inline]
    fn noise_at(&self, i: usize, rel: Vec3A) -> Vec3A {
        self.noise_from_world[i] * rel + self.noise_offset[i]
    }

    /// Gather the blobs of `candidates` crossed by `ray` into `hits` (sorted by entry) and their
    /// merged spans into `intervals`; `buffers.origin` caches the candidates' coordinates of a
    /// ray origin (filled by the tile's first ray; the same bits as computing them per ray).
    fn gather(
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
                hits.push(Hit {
                    blob: self.index[i],
                    t0,
                    t1,
                    b2: self.b2[i],
                    a_t: self.unit_from_world_t[i],
                    feature: self.feature[i],
                    half_min_support: self.half_min_support[i],
                    o,
                    d,
                    no,
                    nd: self.noise_from_world[i] * ray.dir,
                });
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
    fn with_base(&self, (sigma, inside): (f32, bool), x: Vec3A) -> (f32, bool) {
        match &self.base {
            Some(b) if sigma > 0.0 => (sigma * b.factor(x.y), inside),
            _ => (sigma, inside),
        }
    }

    /// `σ_t` at parameter `t` of the ray whose `hits` were gathered (no base).
    #[cfg(test)]
    fn density(&self, hits: &[Hit], t: f32) -> f32 {
        density(&self.params, hits, &all_of(hits), t).0
    }

    /// The medium a frame's light grid samples: [`BlobMedium::for_lattice`] at the grid's
    /// resolution for `settings` ([`RenderSettings::light_grid_cells`]).
    pub fn for_light_grid(&self, settings: &RenderSettings) -> BlobMedium {
        self.for_lattice(settings.light_grid_cells(self.bounds()))
    }

    /// The same medium without the billows finer than two cells of a lattice of `res` cells
    /// on the longest side of its bounds: for the light grid, where they would only alias (the
    /// shadows they cast are below the grid's resolution anyway), at a fraction of the cost.
    pub fn for_lattice(&self, res: u32) -> BlobMedium {
        match self.bounds() {
            Some(bounds) => self.for_lattice_over(bounds, res),
            None => self.clone(),
        }
    }

    /// [`BlobMedium::for_lattice`] for a lattice of `res` cells on the longest side of
    /// `bounds` (a box wider than the medium's own: motion blur's per-stratum light grids).
    pub fn for_lattice_over(&self, (lo, hi): (Vec3A, Vec3A), res: u32) -> BlobMedium {
        let mut m = self.clone();
        let cell = (hi - lo).max_element() / res.max(1) as f32;
        m.params.billows = self.params.billows.coarsened(2.0 * cell);
        m
    }
}

/// The indices of all of `hits` (the whole list as the density's order).
#[cfg(test)]
fn all_of(hits: &[Hit]) -> Vec<u32> {
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
        let (mut best, mut label) = (0.0f32, crate::render::output::cryptomatte::NO_MATTE);
        for h in active.iter().map(|&i| &s.hits[i as usize]) {
            let u = (h.o + h.d * t).length_squared();
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
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::medium::density::MAX_ACTIVE;

    /// An 8×8 `Final` frame looking down +Z from z = −5, with length unit `length_scale`.
    fn tiny_settings(length_scale: f32) -> RenderSettings {
        use crate::render::Camera;
        use crate::render::settings::{CloudMaterial, Quality, Sky, Sun};
        RenderSettings {
            width: 8,
            height: 8,
            camera: Camera {
                position: glam::Vec3::new(0.0, 0.0, -5.0),
                look_at: glam::Vec3::ZERO,
                up: glam::Vec3::Y,
                fov_deg: 40.0,
            },
            sun: Sun::default(),
            sky: Sky::default(),
            cloud: CloudMaterial::default(),
            exposure: 0.0,
            length_scale,
            seed: 1,
            time: 0.0,
            quality: Quality::final_frame(),
            base: None,
        }
    }

    #[test]
    fn blobs_being_born_do_not_set_the_march_step() {
        use glam::{DQuat, DVec3};
        let s = tiny_settings(10.0);
        let blob = |x: f64, r: f64| Blob {
            center: DVec3::new(x, 0.0, 0.0),
            rotation: DQuat::IDENTITY,
            semi_axes: DVec3::splat(r),
            a: 1.0,
            b: 2.0,
        };
        let grown: Vec<Blob> = (0..6).map(|i| blob(i as f64, 0.4)).collect();
        let step = BlobMedium::new(&s, &grown).step();
        // 46 specks (1/500 of the grown ones) beside them: the step is the grown blobs' ...
        let mut born = grown.clone();
        born.extend((0..46).map(|i| blob(0.01 * i as f64, 0.0008)));
        assert_eq!(BlobMedium::new(&s, &born).step(), step);
        // ... while 46 blobs a quarter of their size do set it (the median is theirs).
        let mut small = grown.clone();
        small.extend((0..46).map(|i| blob(0.01 * i as f64, 0.1)));
        let small_step = BlobMedium::new(&s, &small).step();
        assert!(small_step < 0.3 * step, "{small_step} vs {step}");
    }

    #[test]
    fn light_grid_cells_are_no_finer_than_a_pixel() {
        use crate::render::MIN_LIGHT_GRID_CELLS;
        let mut s = tiny_settings(1.0);
        s.height = 360;
        let px = s.pixel_footprint();
        let box_of = |pixels: f32| Some((Vec3A::ZERO, Vec3A::new(pixels * px, 1e-3, 1e-3)));
        // A cloud 100 px across gets 100 cells, one 1,000 px across the quality's 224, one 5 px
        // across the floor; no pixel floor (0) or no bounds: the quality's.
        assert_eq!(s.light_grid_cells(box_of(100.0)), 100);
        assert_eq!(s.light_grid_cells(box_of(1000.0)), 224);
        assert_eq!(s.light_grid_cells(box_of(5.0)), MIN_LIGHT_GRID_CELLS);
        assert_eq!(s.light_grid_cells(None), 224);
        s.quality.shadow_cell_pixels = 0.5;
        assert_eq!(s.light_grid_cells(box_of(100.0)), 200);
        s.quality.shadow_cell_pixels = 0.0;
        assert_eq!(s.light_grid_cells(box_of(5.0)), 224);
    }

    #[test]
    fn density_is_finite_under_more_overlapping_blobs_than_the_active_list_holds() {
        use glam::{DQuat, DVec3};
        // 30 weak, wide blobs whose supports the ray enters first, then one strong blob: the
        // strong one must make the active list (it used to be left out, giving 0/0 = NaN).
        let sphere = |z: f64, r: f64, b: f64| Blob {
            center: DVec3::new(0.0, 0.0, z),
            rotation: DQuat::IDENTITY,
            semi_axes: DVec3::splat(r),
            a: 1.0,
            b,
        };
        let mut blobs: Vec<Blob> = (0..30)
            .map(|i| sphere(0.01 * i as f64, 1.0, 0.05))
            .collect();
        blobs.push(sphere(0.0, 0.3, 4.0));
        let settings = tiny_settings(2.0);
        let m = BlobMedium::new(&settings, &blobs);
        let ray = Ray {
            origin: Vec3A::new(0.0, 0.0, -5.0),
            dir: Vec3A::Z,
        };
        let (mut hits, mut ivs) = (Vec::new(), Vec::new());
        let all: Vec<u32> = (0..m.len() as u32).collect();
        m.gather(
            &all,
            &ray,
            0.0,
            &mut GatherBuffers::default(),
            &mut hits,
            &mut ivs,
        );
        assert!(hits.len() > MAX_ACTIVE);
        let sigma = m.density(&hits, 5.0);
        assert!(
            sigma.is_finite() && sigma > 0.5 * m.params.sigma,
            "σ_t = {sigma}"
        );
    }

    #[test]
    fn origin_cache_gives_each_rays_own_bits() {
        use glam::{DQuat, DVec3};
        let blobs: Vec<Blob> = (0..9)
            .map(|i| Blob {
                center: DVec3::new(0.1 * i as f64, -0.07 * (i % 4) as f64, 0.2 * i as f64),
                rotation: DQuat::from_rotation_x(0.4 * i as f64),
                semi_axes: DVec3::new(0.5, 0.35, 0.25),
                a: 1.0,
                b: 2.0,
            })
            .collect();
        let m = BlobMedium::new(&tiny_settings(4.0), &blobs);
        let all: Vec<u32> = (0..m.len() as u32).collect();
        let eye = Vec3A::new(0.1, 0.0, -3.0);
        let ray = |origin: Vec3A, k: f32| Ray {
            origin,
            dir: Vec3A::new(0.02 * k, 0.01 * k, 1.0).normalize(),
        };
        let gather = |buffers: &mut GatherBuffers, r: &Ray| {
            let (mut hits, mut ivs) = (Vec::new(), Vec::new());
            m.gather(&all, r, 0.0, buffers, &mut hits, &mut ivs);
            format!("{hits:?} {ivs:?}")
        };
        // A cache filled by the tile's first ray, reused by the next rays from the same eye and
        // bypassed by a ray from elsewhere: each gives what a fresh gather gives.
        let mut cache = GatherBuffers::default();
        for (origin, k) in [(eye, 0.0), (eye, 3.0), (eye + Vec3A::X, 1.0), (eye, -2.0)] {
            let r = ray(origin, k);
            let alone = gather(&mut GatherBuffers::default(), &r);
            assert!(alone.contains("Hit"), "the ray should cross blobs");
            assert_eq!(gather(&mut cache, &r), alone);
        }
        assert_eq!(cache.origin.origin, Some(eye));
    }

    #[test]
    fn active_window_gives_the_full_lists_bits() {
        use glam::{DQuat, DVec3};
        // Overlapping blobs along the ray, some ending early: samples at increasing t (and
        // steps back, as the march's re-march takes) through the window equal the full list's.
        let blobs: Vec<Blob> = (0..12)
            .map(|i| Blob {
                center: DVec3::new(0.05 * i as f64, 0.02 * (i % 3) as f64, 0.3 * i as f64),
                rotation: DQuat::from_rotation_y(0.3 * i as f64),
                semi_axes: DVec3::new(0.4, 0.3, 0.2 + 0.05 * (i % 4) as f64),
                a: 1.0,
                b: 2.0,
            })
            .collect();
        let settings = tiny_settings(4.0);
        let m = BlobMedium::new(&settings, &blobs);
        let ray = Ray {
            origin: Vec3A::new(0.0, 0.0, -1.0),
            dir: Vec3A::Z,
        };
        let mut s = m.scratch();
        let all: Vec<u32> = (0..m.len() as u32).collect();
        s.tile = all;
        m.begin_ray(&ray, &mut s);
        let full = s.hits.clone();
        let mut positive = 0;
        for t in (0..400)
            .map(|k| 0.013 * k as f32)
            .chain([0.5, 0.7, 2.0, 1.0, 3.0])
        {
            let window = m.sample(&mut s, t, ray.at(t));
            let exact = density(&m.params, &full, &all_of(&full), t);
            assert_eq!(window.0.to_bits(), exact.0.to_bits(), "t = {t}");
            assert_eq!(window.1, exact.1);
            positive += (exact.0 > 0.0) as u32;
        }
        assert!(positive > 50, "the ray crosses the cloud ({positive})");
    }

    #[test]
    fn hit_sort_orders_by_entry_and_keeps_ties_in_gathering_order() {
        let hit = |t0: f32, blob: u32| Hit {
            blob,
            t0,
            t1: t0.abs() + 1.0,
            b2: 1.0,
            feature: 0.0,
            half_min_support: 0.0,
            a_t: glam::Mat3A::IDENTITY,
            o: Vec3A::ZERO,
            d: Vec3A::ZERO,
            no: Vec3A::ZERO,
            nd: Vec3A::ZERO,
        };
        let mut sort = HitSort::default();
        let mut rng = 0x2545_f491_u32;
        for n in [0usize, 1, 2, 7, 40] {
            let mut hits: Vec<Hit> = (0..n as u32)
                .map(|k| {
                    rng = rng.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                    // Few distinct entries (ties), both zeros, a negative.
                    let t0 = [0.0, -0.0, 0.5, 0.25, 3.0, -1.0][(rng >> 28) as usize % 6];
                    hit(t0, k)
                })
                .collect();
            let mut expected = hits.clone();
            expected.sort_by(|a, b| a.t0.total_cmp(&b.t0));
            sort.sort(&mut hits);
            let key = |h: &Hit| (h.t0.to_bits(), h.blob);
            assert_eq!(
                hits.iter().map(key).collect::<Vec<_>>(),
                expected.iter().map(key).collect::<Vec<_>>(),
                "{n} hits"
            );
        }
    }
}
