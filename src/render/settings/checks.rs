//! The checks of the render settings a scene file sets (sun, sky, cloud look), beside their
//! types: each names the scene file's dotted field and says what is wrong, with the value found.
//! A value out of range is refused here, never clamped silently where it is used.

use super::{CloudMaterial, NoiseSettings, Sky, Sun};

/// A value out of range: the scene file's dotted field (`sun.intensity`) and what is wrong.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct InvalidField {
    /// The dotted field.
    pub field: &'static str,
    /// What is wrong, with the value found.
    pub message: String,
}

impl InvalidField {
    /// `field` is out of range: `message`.
    pub fn new(field: &'static str, message: String) -> InvalidField {
        InvalidField { field, message }
    }

    /// Every value of `v` finite, or the error naming `field`.
    pub fn check_finite(field: &'static str, v: &[f32]) -> Result<(), InvalidField> {
        if v.iter().all(|x| x.is_finite()) {
            Ok(())
        } else {
            Err(InvalidField::new(
                field,
                format!("must be finite, got {v:?}"),
            ))
        }
    }
}

impl Sun {
    /// Finite values, a non-negative intensity and colour, an elevation in 0..=90 degrees (or
    /// a non-zero direction).
    pub fn validate(&self) -> Result<(), InvalidField> {
        InvalidField::check_finite("sun.direction", &self.direction.to_array())?;
        InvalidField::check_finite("sun.color", &self.color.to_array())?;
        InvalidField::check_finite("sun.azimuth_deg", &[self.azimuth_deg])?;
        if !(self.intensity.is_finite() && self.intensity >= 0.0) {
            return Err(InvalidField::new(
                "sun.intensity",
                format!("must be ≥ 0, got {}", self.intensity),
            ));
        }
        if self.color.min_element() < 0.0 {
            return Err(InvalidField::new(
                "sun.color",
                format!("must not be negative, got {:?}", self.color.to_array()),
            ));
        }
        match self.elevation_deg {
            Some(el) if !(0.0..=90.0).contains(&el) => Err(InvalidField::new(
                "sun.elevation_deg",
                format!("must be in 0..=90 (degrees above the horizon), got {el}"),
            )),
            None if self.direction.length() <= 0.0 => Err(InvalidField::new(
                "sun.direction",
                "must not be zero".to_string(),
            )),
            _ => Ok(()),
        }
    }
}

impl Sky {
    /// Finite, non-negative colours; a Hošek–Wilkie sky's turbidity in 1..=10, ground albedo
    /// in 0..=1, and `sun` above the horizon; an environment's file named, a finite rotation
    /// and an intensity ≥ 0 (its texels are checked when it is read).
    pub fn validate(&self, sun: &Sun) -> Result<(), InvalidField> {
        match self {
            Sky::Uniform { color } => {
                InvalidField::check_finite("sky.color", &color.to_array())?;
                if color.min_element() < 0.0 {
                    return Err(InvalidField::new(
                        "sky.color",
                        format!("must not be negative, got {:?}", color.to_array()),
                    ));
                }
            }
            Sky::Environment(env) => {
                if env.file.trim().is_empty() {
                    return Err(InvalidField::new(
                        "sky.file",
                        "name the lat-long EXR (relative to the scene file's folder)".to_string(),
                    ));
                }
                InvalidField::check_finite("sky.rotate_deg", &[env.rotate_deg])?;
                if !(env.intensity.is_finite() && env.intensity >= 0.0) {
                    return Err(InvalidField::new(
                        "sky.intensity",
                        format!("must be ≥ 0, got {}", env.intensity),
                    ));
                }
            }
            &Sky::Gradient { zenith, horizon } => {
                InvalidField::check_finite("sky.zenith", &zenith.to_array())?;
                InvalidField::check_finite("sky.horizon", &horizon.to_array())?;
                if zenith.min_element() < 0.0 || horizon.min_element() < 0.0 {
                    return Err(InvalidField::new(
                        "sky",
                        "colours must not be negative".to_string(),
                    ));
                }
            }
            &Sky::HosekWilkie {
                turbidity,
                ground_albedo,
            } => {
                if !(1.0..=10.0).contains(&turbidity) {
                    return Err(InvalidField::new(
                        "sky.turbidity",
                        format!("must be in 1..=10, got {turbidity}"),
                    ));
                }
                if !(0.0..=1.0).contains(&ground_albedo) {
                    return Err(InvalidField::new(
                        "sky.ground_albedo",
                        format!("must be in 0..=1, got {ground_albedo}"),
                    ));
                }
                if sun.elevation() < 0.0 {
                    return Err(InvalidField::new(
                        "sun",
                        "a HosekWilkie sky needs the sun above the horizon (set sun.elevation_deg)"
                            .to_string(),
                    ));
                }
            }
        }
        Ok(())
    }
}

impl NoiseSettings {
    /// The billows' octaves: at most [`NoiseSettings::MAX_OCTAVES`], the noise's own limit
    /// (refused here rather than clamped where the noise is built).
    pub fn validate(&self) -> Result<(), InvalidField> {
        for (field, v) in [
            ("cloud.noise.amplitude", self.amplitude),
            ("cloud.noise.frequency", self.frequency),
            ("cloud.noise.evolve", self.evolve),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(InvalidField::new(
                    field,
                    format!("must be a number ≥ 0, got {v}"),
                ));
            }
        }
        if self.octaves as usize > NoiseSettings::MAX_OCTAVES {
            return Err(InvalidField::new(
                "cloud.noise.octaves",
                format!(
                    "must be at most {}, got {}",
                    NoiseSettings::MAX_OCTAVES,
                    self.octaves
                ),
            ));
        }
        Ok(())
    }
}

impl CloudMaterial {
    /// Non-negative density and edge, albedo in 0..=1, phase `g` in (−1, 1), the base's
    /// fractions in 0..=1, and the billows' [`NoiseSettings::validate`].
    pub fn validate(&self) -> Result<(), InvalidField> {
        for (field, v) in [("cloud.density", self.density), ("cloud.edge", self.edge)] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(InvalidField::new(
                    field,
                    format!("must be a number ≥ 0, got {v}"),
                ));
            }
        }
        self.noise.validate()?;
        if !(0.0..=1.0).contains(&self.albedo) {
            return Err(InvalidField::new(
                "cloud.albedo",
                format!("must be in 0..=1, got {}", self.albedo),
            ));
        }
        if !(self.phase_g > -1.0 && self.phase_g < 1.0) {
            return Err(InvalidField::new(
                "cloud.phase_g",
                format!("must be in (−1, 1), got {}", self.phase_g),
            ));
        }
        if !(-1.0..=2.0).contains(&self.ms_contrast) {
            return Err(InvalidField::new(
                "cloud.ms_contrast",
                format!("must be in -1..=2 (0: off), got {}", self.ms_contrast),
            ));
        }
        if let Some(b) = self.base {
            for (field, v) in [
                ("cloud.base.height", b.height),
                ("cloud.base.softness", b.softness),
            ] {
                if !(v.is_finite() && (0.0..=1.0).contains(&v)) {
                    return Err(InvalidField::new(
                        field,
                        format!("must be in 0..=1 (a fraction of the target's height), got {v}"),
                    ));
                }
            }
        }
        Ok(())
    }
}
