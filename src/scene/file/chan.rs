//! A shot's camera from a Nuke `.chan` file, as matchmove packages (3DEqualizer, SynthEyes,
//! Nuke, Maya, Houdini, Blender) export it: one line per frame,
//! `frame tx ty tz rx ry rz [vfov]` — the translation in scene units, the rotations in degrees
//! applied in the camera's rotation order (Nuke's default for cameras, `ZXY`: about Z first,
//! then X, then Y, so the camera's orientation is `R = R_y · R_x · R_z`), and the **vertical**
//! angle of view in degrees. The camera looks down its local −Z with +Y up, as Nuke's, Blender's
//! and nephele's do. A line's frame is the shot's frame number (`shot.start_frame` on): every
//! frame of the shot must have its line.

use std::path::Path;

use glam::{Mat3, Vec3};
use serde::{Deserialize, Serialize};

use crate::render::Camera;

/// The order in which a `.chan` file's three rotations are applied, first letter first.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum RotationOrder {
    /// X, then Y, then Z.
    XYZ,
    /// X, then Z, then Y.
    XZY,
    /// Y, then X, then Z.
    YXZ,
    /// Y, then Z, then X.
    YZX,
    /// Z, then X, then Y (Nuke's default for cameras).
    #[default]
    ZXY,
    /// Z, then Y, then X.
    ZYX,
}

impl RotationOrder {
    /// The rotation matrix of `deg` (degrees about X, Y and Z) applied in this order.
    pub fn matrix(self, deg: Vec3) -> Mat3 {
        let r = deg * (std::f32::consts::PI / 180.0);
        let (x, y, z) = (
            Mat3::from_rotation_x(r.x),
            Mat3::from_rotation_y(r.y),
            Mat3::from_rotation_z(r.z),
        );
        // The first applied is the rightmost (column vectors).
        match self {
            RotationOrder::XYZ => z * y * x,
            RotationOrder::XZY => y * z * x,
            RotationOrder::YXZ => z * x * y,
            RotationOrder::YZX => x * z * y,
            RotationOrder::ZXY => y * x * z,
            RotationOrder::ZYX => x * y * z,
        }
    }
}

/// One line of a `.chan` file.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ChanKey {
    /// Frame number.
    pub frame: i64,
    /// Camera position.
    pub translate: Vec3,
    /// Rotations about X, Y and Z, degrees.
    pub rotate: Vec3,
    /// Vertical angle of view, degrees, when the line has it.
    pub vfov_deg: Option<f32>,
}

/// A camera read from a `.chan` file (`camera: Chan((file: "cam.chan"))`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ChanCamera {
    /// The `.chan` file (relative paths resolve against the scene file's folder).
    pub file: String,
    /// The order its rotations are applied in (default `ZXY`, Nuke's).
    pub rotation_order: RotationOrder,
    /// Vertical field of view, degrees, for lines without the eighth column.
    pub fov_deg: f32,
    /// The file's lines, read when the scene is loaded (not written in scene files).
    #[serde(skip)]
    pub keys: Vec<ChanKey>,
}

impl Default for ChanCamera {
    fn default() -> Self {
        ChanCamera {
            file: String::new(),
            rotation_order: RotationOrder::default(),
            fov_deg: 35.0,
            keys: Vec::new(),
        }
    }
}

impl ChanCamera {
    /// The camera of frame number `frame` (a frame the file has no line for holds the nearest
    /// line's camera; loading checks the shot's frames all have one).
    pub fn at(&self, frame: i64) -> Camera {
        let key = match self.keys.binary_search_by_key(&frame, |k| k.frame) {
            Ok(i) => self.keys[i],
            Err(i) => self.keys[i.min(self.keys.len().saturating_sub(1))],
        };
        let r = self.rotation_order.matrix(key.rotate);
        Camera {
            position: key.translate,
            look_at: key.translate + r * Vec3::NEG_Z,
            up: r * Vec3::Y,
            fov_deg: key.vfov_deg.unwrap_or(self.fov_deg),
            shift: glam::Vec2::ZERO,
        }
    }

    /// Read the lines of the file at `path` (`file` resolved), checking that every frame
    /// number in `frames` has one. The error says where and what, naming the `.chan` file.
    pub fn load(
        &mut self,
        path: &Path,
        frames: std::ops::RangeInclusive<u32>,
    ) -> Result<(), String> {
        let text = crate::input::read_to_string(path, crate::input::Limit::Scene)
            .map_err(|e| format!("{}: {e}", path.display()))?;
        let mut keys = parse(&text).map_err(|(line, column, message)| {
            format!("{}:{line}:{column}: {message}", path.display())
        })?;
        keys.sort_by_key(|k| k.frame);
        if let Some(w) = keys.windows(2).find(|w| w[0].frame == w[1].frame) {
            return Err(format!(
                "{}: frame {} has two lines; give each frame one",
                path.display(),
                w[0].frame
            ));
        }
        let missing: Vec<u32> = frames
            .clone()
            .filter(|&f| keys.binary_search_by_key(&(f as i64), |k| k.frame).is_err())
            .collect();
        if let Some(&first) = missing.first() {
            return Err(format!(
                "{}: no line for frame {first}{} of the shot's frames {}..{} (a line's frame is \
                 the shot's frame number; set shot.start_frame to the file's first frame)",
                path.display(),
                if missing.len() > 1 {
                    format!(" and {} more", missing.len() - 1)
                } else {
                    String::new()
                },
                frames.start(),
                frames.end()
            ));
        }
        self.keys = keys;
        Ok(())
    }
}

/// The lines of `.chan` text; an error is its 1-based line and column and what is wrong.
pub fn parse(text: &str) -> Result<Vec<ChanKey>, (usize, usize, String)> {
    let mut keys = Vec::new();
    for (n, line) in text.lines().enumerate() {
        let content = line.split('#').next().unwrap_or("");
        let words: Vec<(usize, &str)> = content
            .split_whitespace()
            .map(|w| (w.as_ptr() as usize - line.as_ptr() as usize + 1, w))
            .collect();
        if words.is_empty() {
            continue;
        }
        if !(7..=8).contains(&words.len()) {
            return Err((
                n + 1,
                1,
                format!(
                    "{} numbers; a .chan line is `frame tx ty tz rx ry rz [vfov]` (7 or 8)",
                    words.len()
                ),
            ));
        }
        let mut v = [0.0f64; 8];
        for (i, &(col, w)) in words.iter().enumerate() {
            v[i] = match w.parse::<f64>() {
                Ok(x) if x.is_finite() => x,
                _ => return Err((n + 1, col, format!("{w:?} is not a finite number"))),
            };
        }
        if v[0].fract() != 0.0 {
            return Err((
                n + 1,
                words[0].0,
                format!("frame {} is not a whole number", words[0].1),
            ));
        }
        let vfov = (words.len() == 8).then_some(v[7] as f32);
        if let Some(f) = vfov
            && !(f > 0.0 && f < 180.0)
        {
            return Err((
                n + 1,
                words[7].0,
                format!("vertical angle of view {f} is not in (0, 180) degrees"),
            ));
        }
        keys.push(ChanKey {
            frame: v[0] as i64,
            translate: Vec3::new(v[1] as f32, v[2] as f32, v[3] as f32),
            rotate: Vec3::new(v[4] as f32, v[5] as f32, v[6] as f32),
            vfov_deg: vfov,
        });
    }
    if keys.is_empty() {
        return Err((1, 1, "no camera lines".into()));
    }
    Ok(keys)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: Vec3, b: Vec3) -> bool {
        (a - b).length() < 1e-5
    }

    #[test]
    fn rotations_turn_the_camera_as_nuke_does() {
        let cam = |order: RotationOrder, r: Vec3| {
            let c = ChanCamera {
                rotation_order: order,
                keys: vec![ChanKey {
                    frame: 1,
                    translate: Vec3::new(1.0, 2.0, 3.0),
                    rotate: r,
                    vfov_deg: Some(30.0),
                }],
                ..ChanCamera::default()
            };
            c.at(1)
        };
        // No rotation: looking down −Z, +Y up.
        let c = cam(RotationOrder::ZXY, Vec3::ZERO);
        assert!(close(c.look_at - c.position, Vec3::NEG_Z));
        assert!(close(c.up, Vec3::Y));
        assert_eq!(c.fov_deg, 30.0);
        // 90° about Y (pan left): looking down −X.
        let c = cam(RotationOrder::ZXY, Vec3::new(0.0, 90.0, 0.0));
        assert!(close(c.look_at - c.position, Vec3::NEG_X));
        // 90° about X (tilt up): looking up +Y, the camera's up now +Z.
        let c = cam(RotationOrder::ZXY, Vec3::new(90.0, 0.0, 0.0));
        assert!(close(c.look_at - c.position, Vec3::Y));
        assert!(close(c.up, Vec3::Z));
        // Tilt up 90° and pan 90°: in ZXY the tilt is applied before the pan (the pan turns
        // the tilted camera about the world's Y), in YXZ after it.
        let r = Vec3::new(90.0, 90.0, 0.0);
        let zxy = cam(RotationOrder::ZXY, r);
        assert!(close(zxy.look_at - zxy.position, Vec3::Y));
        assert!(close(zxy.up, Vec3::X));
        let yxz = cam(RotationOrder::YXZ, r);
        assert!(close(yxz.up, Vec3::Z));
        // A roll of 90° about Z: up turns to −X, the view stays down −Z.
        let c = cam(RotationOrder::ZXY, Vec3::new(0.0, 0.0, 90.0));
        assert!(close(c.up, Vec3::NEG_X));
        assert!(close(c.look_at - c.position, Vec3::NEG_Z));
    }

    #[test]
    fn bad_lines_are_located() {
        assert_eq!(
            parse("1 0 0 0 0 0 0 40\n2 0 0 0 0 0\n").unwrap_err().0,
            2,
            "six numbers"
        );
        let e = parse("# a comment\n\n1 0 0 x 0 0 0\n").unwrap_err();
        assert_eq!((e.0, e.1), (3, 7), "{}", e.2);
        let e = parse("1.5 0 0 0 0 0 0\n").unwrap_err();
        assert!(e.2.contains("whole number"), "{}", e.2);
        let e = parse("1 0 0 0 0 0 0 180\n").unwrap_err();
        assert_eq!(e.1, 15, "{}", e.2);
        assert_eq!(parse("  \n").unwrap_err().2, "no camera lines");
        let keys = parse("1001 1 2 3 4 5 6 21.5 # end\n1002 1 2 3 4 5 6\n").unwrap();
        assert_eq!(keys.len(), 2);
        assert_eq!(keys[0].vfov_deg, Some(21.5));
        assert_eq!(keys[1].vfov_deg, None);
    }
}
