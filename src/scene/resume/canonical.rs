//! The canonical encoding of what a frame is made from, for its provenance hash: every value
//! written field by field as little-endian bits (floats by `to_bits`, so `-0.0 ≠ 0.0` and every
//! NaN payload counts), strings and lists length-prefixed, options and enum variants by a tag
//! byte, each struct opened by its name. The bytes depend on nothing but the values — not on
//! `Debug` formatting, the compiler or the machine — and they go straight into an FNV-1a hash.
//!
//! Every struct is taken apart with an exhaustive pattern (`let Sun { direction, … } = self`),
//! so a field added to a rendering input does not compile until it is encoded here: no input
//! can silently fall out of the hash.

use glam::{DMat3, DQuat, DVec3, Vec3};

use crate::animate::BlobMotion;
use crate::blobby::Blob;
use crate::hash::Fnv1a;
use crate::render::Mattes;
use crate::render::{BasePlane, CumulusBase};
use crate::render::{
    Camera, CloudMaterial, Film, NoiseSettings, PathTracing, Quality, Region, RenderSettings,
    Shutter, Sky, Sun, TimeSample,
};

/// FNV-1a (64 bits, [`crate::hash::Fnv1a`]) over the canonical bytes written to it.
#[derive(Clone, Copy, Debug)]
pub struct Encoder {
    state: Fnv1a,
}

impl Default for Encoder {
    fn default() -> Self {
        Encoder::new()
    }
}

impl Encoder {
    /// An encoder that has seen nothing (FNV-1a's offset basis).
    pub fn new() -> Encoder {
        Encoder {
            state: Fnv1a::new(),
        }
    }

    /// The hash of everything written so far.
    pub fn finish(&self) -> u64 {
        self.state.finish()
    }

    /// Raw bytes, as they are.
    pub fn bytes(&mut self, bytes: &[u8]) -> &mut Self {
        self.state.write(bytes);
        self
    }

    /// A length or count (`u64`, little-endian).
    pub fn len(&mut self, n: usize) -> &mut Self {
        self.bytes(&(n as u64).to_le_bytes())
    }

    /// A string: its length, then its UTF-8 bytes.
    pub fn str(&mut self, s: &str) -> &mut Self {
        self.len(s.len()).bytes(s.as_bytes())
    }

    /// Any [`Canonical`] value.
    pub fn put<T: Canonical + ?Sized>(&mut self, v: &T) -> &mut Self {
        v.encode(self);
        self
    }
}

/// A value with a canonical encoding (see the module doc).
pub trait Canonical {
    /// Write the value's canonical bytes.
    fn encode(&self, e: &mut Encoder);

    /// The FNV-1a hash of the value alone.
    fn canonical_hash(&self) -> u64 {
        let mut e = Encoder::new();
        self.encode(&mut e);
        e.finish()
    }
}

macro_rules! le_bits {
    ($($t:ty),*) => {$(
        impl Canonical for $t {
            fn encode(&self, e: &mut Encoder) {
                e.bytes(&self.to_le_bytes());
            }
        }
    )*};
}
le_bits!(u8, u32, u64, i32, i64);

impl Canonical for f32 {
    fn encode(&self, e: &mut Encoder) {
        e.bytes(&self.to_bits().to_le_bytes());
    }
}

impl Canonical for f64 {
    fn encode(&self, e: &mut Encoder) {
        e.bytes(&self.to_bits().to_le_bytes());
    }
}

impl Canonical for bool {
    fn encode(&self, e: &mut Encoder) {
        e.bytes(&[*self as u8]);
    }
}

impl Canonical for str {
    fn encode(&self, e: &mut Encoder) {
        e.str(self);
    }
}

impl Canonical for String {
    fn encode(&self, e: &mut Encoder) {
        e.str(self);
    }
}

/// A reference encodes as what it refers to.
impl<T: Canonical + ?Sized> Canonical for &T {
    fn encode(&self, e: &mut Encoder) {
        (**self).encode(e);
    }
}

impl<T: Canonical> Canonical for Option<T> {
    fn encode(&self, e: &mut Encoder) {
        match self {
            None => {
                e.bytes(&[0]);
            }
            Some(v) => {
                e.bytes(&[1]).put(v);
            }
        }
    }
}

impl<T: Canonical> Canonical for [T] {
    fn encode(&self, e: &mut Encoder) {
        e.len(self.len());
        for v in self {
            v.encode(e);
        }
    }
}

impl<T: Canonical> Canonical for Vec<T> {
    fn encode(&self, e: &mut Encoder) {
        self.as_slice().encode(e);
    }
}

impl Canonical for Vec3 {
    fn encode(&self, e: &mut Encoder) {
        e.put(&self.x).put(&self.y).put(&self.z);
    }
}

impl Canonical for DVec3 {
    fn encode(&self, e: &mut Encoder) {
        e.put(&self.x).put(&self.y).put(&self.z);
    }
}

impl Canonical for DQuat {
    fn encode(&self, e: &mut Encoder) {
        e.put(&self.x).put(&self.y).put(&self.z).put(&self.w);
    }
}

impl Canonical for DMat3 {
    fn encode(&self, e: &mut Encoder) {
        e.put(&self.x_axis).put(&self.y_axis).put(&self.z_axis);
    }
}

impl Canonical for Blob {
    fn encode(&self, e: &mut Encoder) {
        let Blob {
            center,
            rotation,
            semi_axes,
            a,
            b,
        } = self;
        e.str("Blob")
            .put(center)
            .put(rotation)
            .put(semi_axes)
            .put(a)
            .put(b);
    }
}

impl Canonical for BlobMotion {
    fn encode(&self, e: &mut Encoder) {
        let BlobMotion {
            center,
            velocity,
            gradient,
        } = self;
        e.str("BlobMotion").put(center).put(velocity).put(gradient);
    }
}

impl Canonical for Camera {
    fn encode(&self, e: &mut Encoder) {
        let Camera {
            position,
            look_at,
            up,
            fov_deg,
            shift,
        } = self;
        e.str("Camera")
            .put(position)
            .put(look_at)
            .put(up)
            .put(fov_deg);
        // Only a shifted lens adds to the encoding, so every unshifted camera (all of them
        // before the shift existed) keeps its hash.
        if *shift != glam::Vec2::ZERO {
            e.str("shift").put(&shift.x).put(&shift.y);
        }
    }
}

impl Canonical for Sun {
    fn encode(&self, e: &mut Encoder) {
        let Sun {
            direction,
            elevation_deg,
            azimuth_deg,
            color,
            intensity,
        } = self;
        e.str("Sun")
            .put(direction)
            .put(elevation_deg)
            .put(azimuth_deg)
            .put(color)
            .put(intensity);
    }
}

impl Canonical for Sky {
    fn encode(&self, e: &mut Encoder) {
        e.str("Sky");
        match self {
            Sky::Gradient { zenith, horizon } => {
                e.bytes(&[0]).put(zenith).put(horizon);
            }
            Sky::HosekWilkie {
                turbidity,
                ground_albedo,
            } => {
                e.bytes(&[1]).put(turbidity).put(ground_albedo);
            }
            Sky::Uniform { color } => {
                e.bytes(&[2]).put(color);
            }
            // The map by its content (an edited HDRI re-renders; a moved one does not).
            Sky::Environment(env) => {
                e.bytes(&[3])
                    .put(&env.rotate_deg)
                    .put(&env.intensity)
                    .put(&env.sun_from_map);
                match &env.map {
                    Some(m) => e.bytes(&[1]).put(&m.content_hash()),
                    None => e.bytes(&[0]),
                };
            }
        }
    }
}

impl Canonical for NoiseSettings {
    fn encode(&self, e: &mut Encoder) {
        let NoiseSettings {
            amplitude,
            frequency,
            octaves,
            evolve,
        } = self;
        e.str("Noise")
            .put(amplitude)
            .put(frequency)
            .put(octaves)
            .put(evolve);
    }
}

impl Canonical for CumulusBase {
    fn encode(&self, e: &mut Encoder) {
        let CumulusBase { height, softness } = self;
        e.str("CumulusBase").put(height).put(softness);
    }
}

impl Canonical for BasePlane {
    fn encode(&self, e: &mut Encoder) {
        let BasePlane { y, softness } = self;
        e.str("BasePlane").put(y).put(softness);
    }
}

impl Canonical for CloudMaterial {
    fn encode(&self, e: &mut Encoder) {
        let CloudMaterial {
            density,
            edge,
            albedo,
            phase_g,
            multiple_scattering,
            ms_contrast,
            noise,
            base,
        } = self;
        e.str("CloudMaterial")
            .put(density)
            .put(edge)
            .put(albedo)
            .put(phase_g)
            .put(multiple_scattering)
            .put(noise)
            .put(base);
        // Added later: only when set, so a cloud without it keeps its hash.
        if *ms_contrast != 0.0 {
            e.str("ms_contrast").put(ms_contrast);
        }
    }
}

impl Canonical for Quality {
    fn encode(&self, e: &mut Encoder) {
        let Quality {
            step_scale,
            shadow_grid,
            shadow_cell_pixels,
            ms_octaves,
            ms_photons,
            optical_step,
            samples,
            edge_samples,
            time_samples,
            reference,
        } = self;
        e.str("Quality")
            .put(step_scale)
            .put(shadow_grid)
            .put(shadow_cell_pixels)
            .put(ms_octaves)
            .put(optical_step)
            .put(samples)
            .put(edge_samples)
            .put(time_samples);
        // Only when path tracing: the hashes of marched frames do not change.
        if let Some(PathTracing {
            samples,
            max_depth,
            seed,
        }) = reference
        {
            e.str("reference").put(samples).put(max_depth).put(seed);
        }
        // Added with the fluence estimate (render version 4).
        if *ms_photons != 0 {
            e.str("ms_photons").put(ms_photons);
        }
    }
}

impl Canonical for RenderSettings {
    fn encode(&self, e: &mut Encoder) {
        let RenderSettings {
            width,
            height,
            camera,
            sun,
            sky,
            cloud,
            exposure,
            length_scale,
            seed,
            time,
            quality,
            base,
            surfaces,
        } = self;
        e.str("RenderSettings")
            .put(width)
            .put(height)
            .put(camera)
            .put(sun)
            .put(sky)
            .put(cloud)
            .put(exposure)
            .put(length_scale)
            .put(seed)
            .put(time)
            .put(quality)
            .put(base);
        // Only when there are any: the hashes of frames without them do not change.
        if let Some(s) = surfaces {
            e.str("surfaces").put(&s.key());
        }
    }
}

impl Canonical for Region {
    fn encode(&self, e: &mut Encoder) {
        let Region { x0, y0, x1, y1 } = self;
        e.str("Region").put(x0).put(y0).put(x1).put(y1);
    }
}

impl Canonical for Mattes {
    fn encode(&self, e: &mut Encoder) {
        let Mattes {
            layer,
            names,
            of_blob,
        } = self;
        e.str("Mattes").put(layer).put(names).put(of_blob);
    }
}

impl Canonical for Film {
    fn encode(&self, e: &mut Encoder) {
        let Film {
            region,
            passes,
            mattes,
            motion,
        } = self;
        e.str("Film").put(region).put(passes).put(mattes);
        // Added later: only when asked, so a film without it keeps its hash.
        if *motion {
            e.str("motion vectors");
        }
    }
}

impl Canonical for TimeSample {
    fn encode(&self, e: &mut Encoder) {
        let TimeSample {
            offset,
            blobs,
            velocity,
        } = self;
        e.str("TimeSample").put(offset).put(blobs).put(velocity);
    }
}

impl Canonical for Shutter {
    fn encode(&self, e: &mut Encoder) {
        let Shutter { samples, stratum } = self;
        e.str("Shutter").put(samples).put(stratum);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn encoding_is_little_endian_bits() {
        let mut e = Encoder::new();
        e.put(&1.0f32);
        let mut raw = Encoder::new();
        raw.bytes(&[0, 0, 0x80, 0x3f]);
        assert_eq!(e.finish(), raw.finish());
        // -0.0 and 0.0 differ; so do None and Some(0).
        assert_ne!(0.0f32.canonical_hash(), (-0.0f32).canonical_hash());
        assert_ne!(None::<u32>.canonical_hash(), Some(0u32).canonical_hash());
        // A length prefix keeps ["ab", "c"] apart from ["a", "bc"].
        assert_ne!(
            vec!["ab".to_string(), "c".into()].canonical_hash(),
            vec!["a".to_string(), "bc".into()].canonical_hash()
        );
    }

    #[test]
    fn every_setting_reaches_the_hash() {
        let base = CloudMaterial::default();
        let h = base.canonical_hash();
        let mut s = base;
        s.noise.evolve += 0.5;
        assert_ne!(s.canonical_hash(), h);
        let mut s = base;
        s.base = Some(CumulusBase {
            height: 0.2,
            softness: 0.0,
        });
        assert_ne!(s.canonical_hash(), h);
        assert_eq!(base.canonical_hash(), h, "same value, same hash");
    }

    /// A film without motion vectors hashes as films did before they existed (frames on disk
    /// stay current); one with them differs.
    #[test]
    fn motion_vectors_reach_the_film_hash_only_when_asked() {
        let film = Film {
            passes: true,
            ..Film::default()
        };
        let mut e = Encoder::new();
        e.str("Film")
            .put(&film.region)
            .put(&film.passes)
            .put(&film.mattes);
        assert_eq!(film.canonical_hash(), e.finish());
        let moving = Film {
            motion: true,
            ..film.clone()
        };
        assert_ne!(moving.canonical_hash(), film.canonical_hash());
    }
}
