//! Reading a `UsdGeomCamera` prim from a USD stage (`.usda`, `.usdc`, `.usdz`; opened by
//! [`super::usd_stage`]): the prim's world transform at a time code (its `xformOp`s and its
//! ancestors', composed as USD does) and its lens attributes.
//!
//! Lens attributes not authored take the schema's fallbacks (`focalLength` 50,
//! `horizontalAperture` 20.955, `verticalAperture` 15.2908, offsets 0, `clippingRange`
//! `(1, 1000000)`).

use std::path::Path;

use glam::{DMat4, DVec3};
use openusd::sdf;

pub use super::usd_stage::{Field, UsdReadError};
use super::usd_stage::{Stage, Time, scalar, vec2};

/// The camera's values at one time code.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraSample {
    /// Camera to world, column vectors (the transpose of USD's row-vector matrix).
    pub to_world: DMat4,
    /// `focalLength` (tenths of a scene unit).
    pub focal_length: f64,
    /// `horizontalAperture`, `verticalAperture` (tenths of a scene unit).
    pub aperture: [f64; 2],
    /// `horizontalApertureOffset`, `verticalApertureOffset` (tenths of a scene unit).
    pub aperture_offset: [f64; 2],
    /// `clippingRange`: near and far, scene units.
    pub clipping_range: [f64; 2],
}

/// An opened stage and the camera prim in it.
pub struct StageCamera {
    stage: Stage,
    prim: sdf::Path,
}

impl StageCamera {
    /// Open the stage at `path` and find the `Camera` prim at `prim` (an absolute prim path).
    pub fn open(path: &Path, prim: &str) -> Result<StageCamera, UsdReadError> {
        let stage = Stage::open(path)?;
        let prim_path = stage.typed_prim(prim, "Camera")?;
        if let Some(sdf::Value::Token(p)) = stage.value(&prim_path, "projection", Time::Default)?
            && p.as_str() != "perspective"
        {
            return Err(stage.error(format!(
                "{prim} has projection {:?}; only perspective cameras are read",
                p.as_str()
            )));
        }
        Ok(StageCamera {
            stage,
            prim: prim_path,
        })
    }

    /// The stage's `timeCodesPerSecond` as authored (or its `framesPerSecond`, which USD reads
    /// in its place); `None` when the stage states neither.
    pub fn time_codes_per_second(&self) -> Option<f64> {
        self.stage.time_codes_per_second()
    }

    /// The camera's values at time code `time`, checked: finite, a positive focal length and
    /// apertures, a transform that keeps a view direction and an up direction.
    pub fn sample(&self, time: f64) -> Result<CameraSample, UsdReadError> {
        let prim = self.prim.as_str().to_string();
        let at = |what: &str| format!("{prim}.{what} at time code {time}");
        let scalar = |name: &str, fallback: f64| -> Result<f64, UsdReadError> {
            match self.stage.value(&self.prim, name, Time::Code(time))? {
                None => Ok(fallback),
                Some(v) => scalar(&v).ok_or_else(|| {
                    self.stage
                        .error(format!("{} is not a number: {v:?}", at(name)))
                }),
            }
        };
        let focal_length = scalar("focalLength", 50.0)?;
        let aperture = [
            scalar("horizontalAperture", 20.955)?,
            scalar("verticalAperture", 15.2908)?,
        ];
        let aperture_offset = [
            scalar("horizontalApertureOffset", 0.0)?,
            scalar("verticalApertureOffset", 0.0)?,
        ];
        for (name, v) in [
            ("focalLength", focal_length),
            ("horizontalAperture", aperture[0]),
            ("verticalAperture", aperture[1]),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(self.stage.error(format!(
                    "{} is {v}; it must be a positive finite number",
                    at(name)
                )));
            }
        }
        for (name, v) in [
            ("horizontalApertureOffset", aperture_offset[0]),
            ("verticalApertureOffset", aperture_offset[1]),
        ] {
            if !v.is_finite() {
                return Err(self
                    .stage
                    .error(format!("{} is {v}; it must be finite", at(name))));
            }
        }
        let clipping_range =
            match self
                .stage
                .value(&self.prim, "clippingRange", Time::Code(time))?
            {
                None => [1.0, 1e6],
                Some(v) if vec2(&v).is_some() => vec2(&v).unwrap_or_default(),
                Some(v) => {
                    return Err(self
                        .stage
                        .error(format!("{} is not a float2: {v:?}", at("clippingRange"))));
                }
            };
        if !clipping_range.iter().all(|v| v.is_finite()) {
            return Err(self.stage.error(format!(
                "{} is {clipping_range:?}; it must be finite",
                at("clippingRange")
            )));
        }
        let to_world = self.stage.to_world(&self.prim, Time::Code(time))?;
        let axis = |v: DVec3| to_world.transform_vector3(v);
        if !to_world.is_finite()
            || axis(DVec3::Z).length() <= 1e-300
            || axis(DVec3::Y).cross(axis(DVec3::Z)).length() <= 1e-300
        {
            return Err(self.stage.error(format!(
                "{prim}'s world transform at time code {time} is not finite or flattens the \
                 camera (no view or up direction)"
            )));
        }
        Ok(CameraSample {
            to_world,
            focal_length,
            aperture,
            aperture_offset,
            clipping_range,
        })
    }
}
