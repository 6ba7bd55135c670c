//! A holdout's mesh from a USD stage: `holdouts: [(mesh: "set.usda", prim: "/World/hill")]`,
//! `UsdGeomMesh` prims (`.usda`, `.usdc`, `.usdz`; opened by [`super::usd_stage`]).
//!
//! - Which prims: the `Mesh` prim at `prim`, or without `prim` every `Mesh` prim USD's default
//!   traversal visits (active, defined, not abstract; instances are not expanded) that is not
//!   hidden (`visibility = "invisible"`) and not a `guide` or `proxy` (`purpose`), on itself or
//!   an ancestor, all read into one mesh.
//! - Time: holdouts are static, so every value (the points, the faces, the transform ops) is
//!   read once: its default value, else its first time sample.
//! - Faces: `faceVertexCounts` and `faceVertexIndices`, each n-gon split as a fan from its first
//!   vertex (as the OBJ reader does); `orientation = "leftHanded"` reverses the winding.
//! - Placement: the prim's world transform (its `xformOp`s and its ancestors'); the scene's
//!   holdout `transform` is applied on top.
//!
//! An error names the USD file and is located at the scene's `holdouts[i].mesh` (the stage
//! cannot be read, it has no mesh) or `holdouts[i].prim` (no such prim, not a `Mesh`, no
//! points, a face of fewer than 3 vertices, an index out of range, a point not finite).

use std::path::Path;

use glam::{DMat4, DVec3};
use openusd::sdf;

use super::usd_stage::{Field, Stage, Time, UsdReadError};
use crate::mesh::Mesh;

/// Whether `mesh` names a USD stage (by its extension).
pub fn is_usd(mesh: &str) -> bool {
    Path::new(mesh)
        .extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| {
            ["usd", "usda", "usdc", "usdz"]
                .iter()
                .any(|u| e.eq_ignore_ascii_case(u))
        })
}

/// The mesh of the `Mesh` prim `prim` (or of every visible `Mesh` prim) of the stage at
/// `path`, in the stage's world coordinates.
pub fn read(path: &Path, prim: Option<&str>) -> Result<Mesh, UsdReadError> {
    // The reader is a large third-party parser: should it panic on a malformed file, the scene
    // gets an error naming the file rather than a crash.
    std::panic::catch_unwind(|| read_stage(path, prim)).unwrap_or_else(|_| {
        Err(UsdReadError {
            field: Field::File,
            message: format!(
                "{}: the USD reader failed on this file (it may be malformed)",
                path.display()
            ),
        })
    })
}

fn read_stage(path: &Path, prim: Option<&str>) -> Result<Mesh, UsdReadError> {
    let stage = Stage::open(path)?;
    let prims = mesh_prims(&stage, path, prim)?;
    let mut mesh = Mesh {
        positions: Vec::new(),
        triangles: Vec::new(),
    };
    for p in &prims {
        add_prim(&stage, p, &mut mesh, Time::Default)?;
    }
    Ok(mesh)
}

/// A stage's mesh at each of its time codes ([`read_frames`]).
#[derive(Clone, Debug)]
pub struct MeshFrames {
    /// The mesh at each time code.
    pub meshes: Vec<Mesh>,
    /// The time codes, increasing.
    pub time_codes: Vec<f64>,
    /// The stage's `timeCodesPerSecond` (or `framesPerSecond`), if it states one.
    pub time_codes_per_second: Option<f64>,
}

/// A deforming mesh from a stage: the `Mesh` prim at `prim` (or every visible one, as
/// [`read`] takes them) at each time code where any of their `points` has a time sample
/// (values between a prim's own samples interpolated, as USD does), placed by the world
/// transform at that time.
pub fn read_frames(path: &Path, prim: Option<&str>) -> Result<MeshFrames, UsdReadError> {
    std::panic::catch_unwind(|| {
        let stage = Stage::open(path)?;
        let prims = mesh_prims(&stage, path, prim)?;
        let mut times = Vec::new();
        for p in &prims {
            times.extend(stage.sample_times(p, "points")?);
        }
        times.sort_by(f64::total_cmp);
        times.dedup();
        let mut meshes = Vec::with_capacity(times.len());
        for &t in &times {
            let mut mesh = Mesh::default();
            for p in &prims {
                add_prim(&stage, p, &mut mesh, Time::Code(t))?;
            }
            meshes.push(mesh);
        }
        Ok(MeshFrames {
            meshes,
            time_codes: times,
            time_codes_per_second: stage.time_codes_per_second(),
        })
    })
    .unwrap_or_else(|_| {
        Err(UsdReadError {
            field: Field::File,
            message: format!(
                "{}: the USD reader failed on this file (it may be malformed)",
                path.display()
            ),
        })
    })
}

/// The `Mesh` prim at `prim`, or every visible one.
fn mesh_prims(
    stage: &Stage,
    path: &Path,
    prim: Option<&str>,
) -> Result<Vec<sdf::Path>, UsdReadError> {
    Ok(match prim {
        Some(p) => vec![stage.typed_prim(p, "Mesh")?],
        None => {
            let mut meshes = Vec::new();
            for p in stage.prims()? {
                if stage.type_name(&p)? == "Mesh" && !hidden(stage, &p)? {
                    meshes.push(p);
                }
            }
            if meshes.is_empty() {
                return Err(UsdReadError {
                    field: Field::File,
                    message: format!(
                        "{}: the stage has no visible Mesh prim (name one with `prim`)",
                        path.display()
                    ),
                });
            }
            meshes
        }
    })
}

/// Whether the prim at `path` or an ancestor is invisible, a guide or a proxy.
fn hidden(stage: &Stage, path: &sdf::Path) -> Result<bool, UsdReadError> {
    let mut at = Some(path.clone());
    while let Some(p) = at.filter(|p| !p.is_abs_root()) {
        let token = |name: &str| -> Result<String, UsdReadError> {
            Ok(match stage.value(&p, name, Time::Default)? {
                Some(sdf::Value::Token(t)) => t.as_str().to_string(),
                _ => String::new(),
            })
        };
        if token("visibility")? == "invisible"
            || matches!(token("purpose")?.as_str(), "guide" | "proxy")
        {
            return Ok(true);
        }
        at = p.parent();
    }
    Ok(false)
}

/// An `int[]` value as `i64`s.
fn ints(v: sdf::Value) -> Option<Vec<i64>> {
    match v {
        sdf::Value::IntVec(v) => Some(v.into_iter().map(i64::from).collect()),
        sdf::Value::Int64Vec(v) => Some(v),
        _ => None,
    }
}

/// A `point3f[]` (or `double3`, `half3`) value.
fn points(v: sdf::Value) -> Option<Vec<DVec3>> {
    match v {
        sdf::Value::Vec3fVec(v) => Some(
            v.iter()
                .map(|p| DVec3::new(p.x as f64, p.y as f64, p.z as f64))
                .collect(),
        ),
        sdf::Value::Vec3dVec(v) => Some(v.iter().map(|p| DVec3::new(p.x, p.y, p.z)).collect()),
        sdf::Value::Vec3hVec(v) => Some(
            v.iter()
                .map(|p| DVec3::new(p.x.to_f64(), p.y.to_f64(), p.z.to_f64()))
                .collect(),
        ),
        _ => None,
    }
}

/// Append the triangles of the `Mesh` prim at `path` at `time`, placed in the world, to `mesh`.
fn add_prim(
    stage: &Stage,
    path: &sdf::Path,
    mesh: &mut Mesh,
    time: Time,
) -> Result<(), UsdReadError> {
    let name = path.as_str();
    let read = |attr: &str| stage.value(path, attr, time);
    let mut local = match read("points")? {
        None => return Err(stage.error(format!("{name} has no points"))),
        Some(v) => points(v.clone())
            .ok_or_else(|| stage.error(format!("{name}.points is not a point3f array: {v:?}")))?,
    };
    if local.is_empty() {
        return Err(stage.error(format!("{name} has no points (an empty array)")));
    }
    if let Some(k) = local.iter().position(|p| !p.is_finite()) {
        return Err(stage.error(format!(
            "{name}.points[{k}] is {:?}; points must be finite",
            local[k]
        )));
    }
    let array = |attr: &str| -> Result<Vec<i64>, UsdReadError> {
        match read(attr)? {
            None => Err(stage.error(format!("{name} has no {attr}"))),
            Some(v) => ints(v.clone())
                .ok_or_else(|| stage.error(format!("{name}.{attr} is not an int array: {v:?}"))),
        }
    };
    let counts = array("faceVertexCounts")?;
    let indices = array("faceVertexIndices")?;
    let left_handed = matches!(
        read("orientation")?,
        Some(sdf::Value::Token(t)) if t.as_str() == "leftHanded"
    );
    let world = stage.to_world(path, time)?;
    if world != DMat4::IDENTITY {
        for p in &mut local {
            *p = world.transform_point3(*p);
        }
        if let Some(k) = local.iter().position(|p| !p.is_finite()) {
            return Err(stage.error(format!(
                "{name}.points[{k}] placed by the prim's world transform is {:?}; it must be finite",
                local[k]
            )));
        }
    }
    let base = mesh.positions.len() as u64;
    let n = local.len() as i64;
    if base + n as u64 > u32::MAX as u64 {
        return Err(stage.error(format!("{name}: too many points for one holdout")));
    }
    let mut next = 0usize;
    for (f, &count) in counts.iter().enumerate() {
        if count < 3 {
            return Err(stage.error(format!(
                "{name}.faceVertexCounts[{f}] is {count}; a face needs at least 3 vertices"
            )));
        }
        let end = next.saturating_add(count as usize);
        let Some(face) = indices.get(next..end) else {
            return Err(stage.error(format!(
                "{name}: faceVertexCounts sums past the {} entries of faceVertexIndices (at \
                 face {f})",
                indices.len()
            )));
        };
        let mut vertex = Vec::with_capacity(face.len());
        for (j, &i) in face.iter().enumerate() {
            if !(0..n).contains(&i) {
                return Err(stage.error(format!(
                    "{name}.faceVertexIndices[{}] is {i}, out of range for its {n} points",
                    next + j
                )));
            }
            vertex.push((base + i as u64) as u32);
        }
        for k in 1..vertex.len() - 1 {
            let t = [vertex[0], vertex[k], vertex[k + 1]];
            mesh.triangles
                .push(if left_handed { [t[0], t[2], t[1]] } else { t });
        }
        next = end;
    }
    if next != indices.len() {
        return Err(stage.error(format!(
            "{name}: faceVertexCounts sums to {next} but faceVertexIndices has {} entries",
            indices.len()
        )));
    }
    mesh.positions.extend(local);
    Ok(())
}
