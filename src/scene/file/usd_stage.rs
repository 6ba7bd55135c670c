//! A USD stage (`.usda`, `.usdc`, `.usdz`) opened with the pure-Rust `openusd` crate as nephele
//! reads its inputs, and what its readers ([`super::usd_read`], the camera, and
//! [`super::usd_mesh`], holdout meshes) share: a prim found and its type checked, an
//! attribute's composed value at a time code, and a prim's world transform.
//!
//! Transforms: `xformOpOrder` lists a prim's ops outermost first, so with USD's row vectors a
//! point is `p · M_last · … · M_first`, and the world matrix is the local one times the
//! parent's, up to the root or to a prim whose order starts with `!resetXformStack!`. The ops
//! read are `translate`, `scale` (and their single-axis forms), `rotateX/Y/Z`, the six
//! three-axis rotations (`rotateXYZ` turns about X first, then Y, then Z), `orient` (a
//! quaternion) and `transform` (a `matrix4d`), each with an optional `:suffix` and the
//! `!invert!` prefix. Any other op is an error, as is an op listed without its attribute: a
//! camera or a holdout silently placed wrong would be worse. Time samples are interpolated
//! here as USD does: linearly between samples (quaternions spherically, matrices component by
//! component), held before the first and after the last. (Not by the crate: its 0.6 text
//! parser leaves a scalar sample such as `1001: 24` untyped, an integer, which it then holds
//! instead of interpolating.) Read at [`Time::Default`], an attribute's default value is
//! taken, else its first time sample.
//!
//! Every layer is read through a resolver that bounds it as nephele bounds its inputs
//! ([`crate::input::Limit::Stage`]) and that works around the 0.6 text parser's untyped samples
//! ([`super::usda_text`]).

use std::io;
use std::path::Path;

use glam::{DMat4, DQuat, DVec3};
use openusd::ar::{self, Resolver};
use openusd::{sdf, usd};

/// Which field of the scene an error belongs to (where it is located in the scene).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Field {
    /// The file field (`camera.file`, `holdouts[i].mesh`): the stage cannot be read.
    File,
    /// The prim field (`camera.prim`, `holdouts[i].prim`): the prim is missing, of the wrong
    /// type, or holds values that cannot be read.
    Prim,
}

/// A USD prim that cannot be read: the field it is reported at, and what is wrong (naming
/// the USD file).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct UsdReadError {
    /// The scene field the error is located at.
    pub field: Field,
    /// The message, starting with the USD file's path.
    pub message: String,
}

/// When an attribute is read.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Time {
    /// Its default value, else its first time sample (a static read).
    Default,
    /// At this time code, time samples interpolated (the default value when it has none).
    Code(f64),
}

impl std::fmt::Display for Time {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Time::Default => f.write_str("the default time"),
            Time::Code(t) => write!(f, "time code {t}"),
        }
    }
}

/// An opened stage, and its file's path for messages.
pub struct Stage {
    stage: usd::Stage,
    file: String,
}

/// A resolver that reads every layer as nephele reads its inputs: only regular files, of at
/// most [`crate::input::Limit::Stage`] (a device or a FIFO named as a sublayer is refused, not
/// read forever).
struct BoundedResolver(ar::DefaultResolver);

impl Resolver for BoundedResolver {
    fn create_identifier(&self, asset_path: &str, anchor: Option<&ar::ResolvedPath>) -> String {
        self.0.create_identifier(asset_path, anchor)
    }

    fn resolve(&self, asset_path: &str) -> Option<ar::ResolvedPath> {
        self.0.resolve(asset_path)
    }

    fn resolve_for_new_asset(&self, asset_path: &str) -> Option<ar::ResolvedPath> {
        self.0.resolve_for_new_asset(asset_path)
    }

    fn open_asset(&self, resolved: &ar::ResolvedPath) -> io::Result<Box<dyn ar::Asset>> {
        let path: &Path = resolved.as_ref();
        // A layer inside a `.usdz` (`pkg.usdz[inner.usda]`) is no file of its own: the
        // package itself was checked when it was opened.
        if std::fs::symlink_metadata(path).is_ok() {
            crate::input::open(path, crate::input::Limit::Stage)?;
        }
        let mut asset = self.0.open_asset(resolved)?;
        let bytes = asset.read_all()?;
        let fixed = bytes
            .starts_with(b"#usda")
            .then(|| std::str::from_utf8(&bytes).ok())
            .flatten()
            .and_then(super::usda_text::asset_samples_as_strings);
        Ok(Box::new(io::Cursor::new(
            fixed.map_or(bytes, String::into_bytes),
        )))
    }

    fn identity(&self) -> String {
        self.0.identity()
    }
}

impl Stage {
    /// Open the stage at `path` (errors at [`Field::File`]).
    pub fn open(path: &Path) -> Result<Stage, UsdReadError> {
        let file = path.display().to_string();
        let err = |message: String| UsdReadError {
            field: Field::File,
            message: format!("{file}: {message}"),
        };
        if let Err(e) = crate::input::open(path, crate::input::Limit::Stage) {
            let why = if e.kind() == io::ErrorKind::NotFound {
                "no such file (relative paths resolve against the scene file's folder)".to_string()
            } else {
                e.to_string()
            };
            return Err(err(why));
        }
        let text_path = path
            .to_str()
            .ok_or_else(|| err("the path is not UTF-8, which the USD reader needs".into()))?;
        let stage = usd::Stage::builder()
            .resolver(BoundedResolver(ar::DefaultResolver::new()))
            .open(text_path)
            .map_err(|e| err(format!("not a USD stage nephele can read: {e:#}")))?;
        Ok(Stage { stage, file })
    }

    /// An error about a prim ([`Field::Prim`]), naming the file.
    pub fn error(&self, message: String) -> UsdReadError {
        UsdReadError {
            field: Field::Prim,
            message: format!("{}: {message}", self.file),
        }
    }

    /// The prim at `prim` (an absolute prim path), checked to exist and to be of type `want`
    /// (`Camera`, `Mesh`).
    pub fn typed_prim(&self, prim: &str, want: &str) -> Result<sdf::Path, UsdReadError> {
        let prim_path = sdf::Path::new(prim).map_err(|e| {
            self.error(format!(
                "{prim:?} is not a prim path ({e}); write it as \"/World/name\""
            ))
        })?;
        let handle = self.stage.prim(prim_path.clone());
        let found = handle
            .is_valid()
            .map_err(|e| self.error(format!("{prim}: {e:#}")))?;
        if !found {
            let roots = self
                .stage
                .root_prims()
                .map(|r| {
                    r.iter()
                        .map(|t| format!("/{}", t.as_str()))
                        .collect::<Vec<_>>()
                })
                .unwrap_or_default();
            return Err(self.error(format!(
                "no prim at {prim} (the stage's root prims: {})",
                if roots.is_empty() {
                    "none".to_string()
                } else {
                    roots.join(", ")
                }
            )));
        }
        let type_name = self.type_name(&prim_path)?;
        if type_name != want {
            return Err(self.error(format!(
                "{prim} is {}, not a {want}",
                if type_name.is_empty() {
                    "a prim without a type".to_string()
                } else {
                    format!("a {type_name}")
                }
            )));
        }
        Ok(prim_path)
    }

    /// The type name of the prim at `path` (empty when it has none).
    pub fn type_name(&self, path: &sdf::Path) -> Result<String, UsdReadError> {
        let type_name = self
            .stage
            .prim(path.clone())
            .type_name()
            .map_err(|e| self.error(format!("{}: {e:#}", path.as_str())))?;
        Ok(type_name
            .map(|t| t.as_str().to_string())
            .unwrap_or_default())
    }

    /// Every prim of the stage that USD's default traversal visits (active, loaded, defined,
    /// not abstract; instances not expanded), depth first.
    pub fn prims(&self) -> Result<Vec<sdf::Path>, UsdReadError> {
        let mut out = Vec::new();
        self.stage
            .traverse(usd::PrimPredicate::DEFAULT, |p| out.push(p.clone()))
            .map_err(|e| self.error(format!("the stage's prims cannot be listed: {e:#}")))?;
        Ok(out)
    }

    /// The stage's `timeCodesPerSecond` as authored (or its `framesPerSecond`, which USD reads
    /// in its place); `None` when the stage states neither.
    pub fn time_codes_per_second(&self) -> Option<f64> {
        let authored = |key: &str| match self.stage.stage_metadata(key) {
            Ok(Some(sdf::Value::Double(v))) => Some(v),
            Ok(Some(sdf::Value::Float(v))) => Some(v as f64),
            Ok(Some(sdf::Value::Int(v))) => Some(v as f64),
            Ok(Some(sdf::Value::Int64(v))) => Some(v as f64),
            _ => None,
        };
        authored("timeCodesPerSecond").or_else(|| authored("framesPerSecond"))
    }

    /// The time codes of attribute `name`'s time samples on the prim at `path`, sorted (empty
    /// when it has none).
    pub fn sample_times(&self, path: &sdf::Path, name: &str) -> Result<Vec<f64>, UsdReadError> {
        let attr = path
            .append_property(name)
            .map_err(|e| self.error(format!("{}.{name}: {e:#}", path.as_str())))?;
        let samples = self
            .stage
            .attribute(attr)
            .time_samples()
            .map_err(|e| self.error(format!("{}.{name}: {e:#}", path.as_str())))?;
        let mut times: Vec<f64> = samples
            .into_iter()
            .flatten()
            .map(|(t, _)| t)
            .filter(|t| t.is_finite())
            .collect();
        times.sort_by(f64::total_cmp);
        times.dedup();
        Ok(times)
    }

    /// The composed value of attribute `name` of the prim at `path`, at `time`; `None` when
    /// not authored (or blocked).
    pub fn value(
        &self,
        path: &sdf::Path,
        name: &str,
        time: Time,
    ) -> Result<Option<sdf::Value>, UsdReadError> {
        let attr = path
            .append_property(name)
            .map_err(|e| self.error(format!("{}.{name}: {e:#}", path.as_str())))?;
        let attr = self.stage.attribute(attr);
        let got = match time {
            Time::Code(t) => match attr.time_samples() {
                Ok(Some(samples)) if !samples.is_empty() => Ok(interpolate(samples, t)),
                Err(e) => Err(e),
                _ => attr.get::<sdf::Value>(),
            },
            Time::Default => match attr.get::<sdf::Value>() {
                Ok(None) => attr.time_samples().map(|samples| {
                    samples
                        .filter(|s| !s.is_empty())
                        .and_then(|s| interpolate(s, f64::NEG_INFINITY))
                }),
                got => got,
            },
        };
        got.map(|v| v.filter(|v| !matches!(v, sdf::Value::ValueBlock | sdf::Value::None)))
            .map_err(|e| self.error(format!("{}.{name}: {e:#}", path.as_str())))
    }

    /// The world matrix of the prim at `prim` at `time` (column vectors): its `xformOp`s and
    /// its ancestors'.
    pub fn to_world(&self, prim: &sdf::Path, time: Time) -> Result<DMat4, UsdReadError> {
        let mut world = DMat4::IDENTITY;
        let mut path = prim.clone();
        loop {
            let (local, reset) = self.local(&path, time)?;
            // Row vectors: world = local · parent; column vectors: parent · local.
            world = local * world;
            if reset {
                break;
            }
            match path.parent() {
                Some(parent) if !parent.is_abs_root() => path = parent,
                _ => break,
            }
        }
        Ok(world)
    }

    /// The local transform of the prim at `path` (column vectors) and whether it resets the
    /// transform stack.
    fn local(&self, path: &sdf::Path, time: Time) -> Result<(DMat4, bool), UsdReadError> {
        let order: Vec<String> = match self.value(path, "xformOpOrder", Time::Default)? {
            None => return Ok((DMat4::IDENTITY, false)),
            Some(sdf::Value::TokenVec(v)) => v.iter().map(|t| t.as_str().to_string()).collect(),
            Some(sdf::Value::StringVec(v)) => v,
            Some(sdf::Value::TokenListOp(op)) => op
                .flatten()
                .iter()
                .map(|t| t.as_str().to_string())
                .collect(),
            Some(v) => {
                return Err(self.error(format!(
                    "{}.xformOpOrder is not a token array: {v:?}",
                    path.as_str()
                )));
            }
        };
        let mut m = DMat4::IDENTITY;
        let mut reset = false;
        for (i, op) in order.iter().enumerate() {
            if op == "!resetXformStack!" {
                if i != 0 {
                    return Err(self.error(format!(
                        "{}.xformOpOrder has !resetXformStack! at position {i}; it may only \
                         come first",
                        path.as_str()
                    )));
                }
                reset = true;
                continue;
            }
            // Outermost first: with column vectors each later op is applied to the point first.
            m *= self.op(path, op, time)?;
        }
        Ok((m, reset))
    }

    /// The matrix (column vectors) of the op `name` (`xformOp:rotateXYZ`, `!invert!…`) of the
    /// prim at `path`, at `time`.
    fn op(&self, path: &sdf::Path, name: &str, time: Time) -> Result<DMat4, UsdReadError> {
        let where_ = || format!("{}.{name} at {time}", path.as_str());
        let (invert, attr) = match name.strip_prefix("!invert!") {
            Some(rest) => (true, rest),
            None => (false, name),
        };
        let kind = attr
            .strip_prefix("xformOp:")
            .and_then(|k| k.split(':').next())
            .unwrap_or("");
        let Some(v) = self.value(path, attr, time)? else {
            return Err(self.error(format!(
                "{} is listed in xformOpOrder but has no value",
                where_()
            )));
        };
        let bad = |what: &str| self.error(format!("{} is not {what}: {v:?}", where_()));
        let deg = |d: f64| d.to_radians();
        let m = match kind {
            "translate" => DMat4::from_translation(vec3(&v).ok_or_else(|| bad("a 3-vector"))?),
            "translateX" | "translateY" | "translateZ" => {
                let s = scalar(&v).ok_or_else(|| bad("a number"))?;
                DMat4::from_translation(single_axis(kind, s, 0.0))
            }
            "scale" => DMat4::from_scale(vec3(&v).ok_or_else(|| bad("a 3-vector"))?),
            "scaleX" | "scaleY" | "scaleZ" => {
                let s = scalar(&v).ok_or_else(|| bad("a number"))?;
                DMat4::from_scale(single_axis(kind, s, 1.0))
            }
            "rotateX" | "rotateY" | "rotateZ" => {
                let a = deg(scalar(&v).ok_or_else(|| bad("a number"))?);
                match kind {
                    "rotateX" => DMat4::from_rotation_x(a),
                    "rotateY" => DMat4::from_rotation_y(a),
                    _ => DMat4::from_rotation_z(a),
                }
            }
            "rotateXYZ" | "rotateXZY" | "rotateYXZ" | "rotateYZX" | "rotateZXY" | "rotateZYX" => {
                let r = vec3(&v).ok_or_else(|| bad("a 3-vector of degrees"))?;
                // The first letter turns first: rightmost with column vectors.
                kind[6..].chars().fold(DMat4::IDENTITY, |m, axis| {
                    let turn = match axis {
                        'X' => DMat4::from_rotation_x(deg(r.x)),
                        'Y' => DMat4::from_rotation_y(deg(r.y)),
                        _ => DMat4::from_rotation_z(deg(r.z)),
                    };
                    turn * m
                })
            }
            "orient" => {
                let q = quat(&v).ok_or_else(|| bad("a quaternion"))?;
                let q = q
                    .try_normalize()
                    .ok_or_else(|| bad("a non-zero quaternion"))?;
                DMat4::from_quat(DQuat::from_vec4(q))
            }
            // USD's row-major rows are glam's columns: the transpose, for column vectors.
            "transform" => match &v {
                sdf::Value::Matrix4d(m) => DMat4::from_cols_array(&m.0),
                _ => return Err(bad("a matrix4d")),
            },
            _ => {
                return Err(self.error(format!(
                    "{}: the transform op {attr:?} is not one nephele reads (translate, scale, \
                     rotateX/Y/Z, rotateXYZ and the other orders, orient, transform)",
                    path.as_str()
                )));
            }
        };
        if !m.is_finite() {
            return Err(self.error(format!("{} is not finite", where_())));
        }
        if invert {
            if m.determinant().abs() <= 1e-300 {
                return Err(self.error(format!("{} is singular and cannot be inverted", where_())));
            }
            return Ok(m.inverse());
        }
        Ok(m)
    }
}

/// The value of time samples `samples` at `time`: linear between the two around it, held
/// outside them, held where the two cannot be blended (tokens, arrays); `None` when blocked.
fn interpolate(mut samples: sdf::TimeSampleMap, time: f64) -> Option<sdf::Value> {
    samples.sort_by(|a, b| a.0.total_cmp(&b.0));
    let after = samples.partition_point(|(t, _)| *t <= time);
    let v = match after {
        0 => samples[0].1.clone(),
        n if n == samples.len() => samples[n - 1].1.clone(),
        n => {
            let ((t0, a), (t1, b)) = (&samples[n - 1], &samples[n]);
            if *t0 == time {
                a.clone()
            } else {
                lerp(a, b, (time - t0) / (t1 - t0)).unwrap_or_else(|| a.clone())
            }
        }
    };
    (!matches!(v, sdf::Value::ValueBlock | sdf::Value::None)).then_some(v)
}

/// `a` to `b` at `u ∈ (0, 1)`, as USD blends attribute values: numbers, vectors and matrices
/// component by component, quaternions spherically; `None` for other values.
fn lerp(a: &sdf::Value, b: &sdf::Value, u: f64) -> Option<sdf::Value> {
    let mix = |x: f64, y: f64| x + (y - x) * u;
    if let (Some(x), Some(y)) = (scalar(a), scalar(b)) {
        return Some(sdf::Value::Double(mix(x, y)));
    }
    if let (Some(x), Some(y)) = (vec2(a), vec2(b)) {
        return Some(sdf::Value::Vec2d(openusd::gf::Vec2d {
            x: mix(x[0], y[0]),
            y: mix(x[1], y[1]),
        }));
    }
    if let (Some(x), Some(y)) = (vec3(a), vec3(b)) {
        let v = x.lerp(y, u);
        return Some(sdf::Value::Vec3d(openusd::gf::Vec3d {
            x: v.x,
            y: v.y,
            z: v.z,
        }));
    }
    if let (Some(x), Some(y)) = (quat(a), quat(b)) {
        let (x, y) = (x.try_normalize()?, y.try_normalize()?);
        let q = DQuat::from_vec4(x).slerp(DQuat::from_vec4(y), u);
        return Some(sdf::Value::Quatd(openusd::gf::Quatd {
            w: q.w,
            x: q.x,
            y: q.y,
            z: q.z,
        }));
    }
    if let (sdf::Value::Matrix4d(x), sdf::Value::Matrix4d(y)) = (a, b) {
        return Some(sdf::Value::Matrix4d(openusd::gf::Matrix4d(
            std::array::from_fn(|i| mix(x.0[i], y.0[i])),
        )));
    }
    None
}

/// A 2-vector value (`float2`, `double2`).
pub fn vec2(v: &sdf::Value) -> Option<[f64; 2]> {
    match v {
        sdf::Value::Vec2d(a) => Some([a.x, a.y]),
        sdf::Value::Vec2f(a) => Some([a.x as f64, a.y as f64]),
        _ => None,
    }
}

/// `value` along the axis named by the last letter of `kind`, `other` on the other two.
fn single_axis(kind: &str, value: f64, other: f64) -> DVec3 {
    let mut v = DVec3::splat(other);
    match kind.as_bytes().last() {
        Some(b'X') => v.x = value,
        Some(b'Y') => v.y = value,
        _ => v.z = value,
    }
    v
}

/// A number value (half, float, double, int).
pub fn scalar(v: &sdf::Value) -> Option<f64> {
    match v {
        sdf::Value::Double(d) => Some(*d),
        sdf::Value::Float(f) => Some(*f as f64),
        sdf::Value::Half(h) => Some(h.to_f64()),
        sdf::Value::Int(i) => Some(*i as f64),
        sdf::Value::Int64(i) => Some(*i as f64),
        _ => None,
    }
}

fn vec3(v: &sdf::Value) -> Option<DVec3> {
    match v {
        sdf::Value::Vec3d(a) => Some(DVec3::new(a.x, a.y, a.z)),
        sdf::Value::Vec3f(a) => Some(DVec3::new(a.x as f64, a.y as f64, a.z as f64)),
        sdf::Value::Vec3h(a) => Some(DVec3::new(a.x.to_f64(), a.y.to_f64(), a.z.to_f64())),
        _ => None,
    }
}

/// A quaternion as glam's `(x, y, z, w)`; USD writes `(w, x, y, z)`.
fn quat(v: &sdf::Value) -> Option<glam::DVec4> {
    match v {
        sdf::Value::Quatd(q) => Some(glam::DVec4::new(q.x, q.y, q.z, q.w)),
        sdf::Value::Quatf(q) => Some(glam::DVec4::new(
            q.x as f64, q.y as f64, q.z as f64, q.w as f64,
        )),
        sdf::Value::Quath(q) => Some(glam::DVec4::new(
            q.x.to_f64(),
            q.y.to_f64(),
            q.z.to_f64(),
            q.w.to_f64(),
        )),
        _ => None,
    }
}
