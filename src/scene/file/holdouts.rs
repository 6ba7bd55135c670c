//! The scene's opaque surfaces: `holdouts` (meshes of the plate's geometry that hide the cloud
//! behind them, optionally shadowing it) and the `ground` plane (the shadow catcher of the
//! `shadow` pass). Read when the scene is loaded, into the renderer's
//! [`crate::render::Surfaces`]; `scenes/README.md` documents the fields.
//!
//! ```ron
//! holdouts: [(mesh: "hill.obj", transform: (up: Z, scale: 0.01), shadows: true)],
//! holdouts: [(mesh: "set.usdc", prim: "/World/hill")],
//! ground: (height: 0.0, shadow_pass: true),
//! ```

use std::path::Path;
use std::sync::Arc;

use serde::{Deserialize, Serialize};

use super::transform::TargetTransform;
use crate::file_error::FileError;
use crate::render::{Ground, HoldoutMesh, Surfaces};
use crate::scene::SceneError;
use crate::scene::resume::canonical::Encoder;

/// One holdout as written.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HoldoutSpec {
    /// The mesh (OBJ, PLY, OFF, STL or a USD stage; relative to the scene file's folder) or
    /// `builtin:NAME`.
    pub mesh: String,
    /// A USD stage's `Mesh` prim (default: every visible `Mesh` prim of the stage).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub prim: Option<String>,
    /// Where it stands in the shot: the target's transform syntax (default: as modelled).
    #[serde(default)]
    pub transform: TargetTransform,
    /// Whether it shadows the cloud from the sun and the sky (default false).
    #[serde(default)]
    pub shadows: bool,
}

/// The ground plane as written.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct GroundSpec {
    /// Height of the plane `y = height`, scene units (default 0).
    pub height: f64,
    /// Write the `shadow` layer into the EXR (default true: a ground is there to catch the
    /// cloud's shadow).
    pub shadow_pass: bool,
}

impl Default for GroundSpec {
    fn default() -> Self {
        GroundSpec {
            height: 0.0,
            shadow_pass: true,
        }
    }
}

/// The surfaces of the scene at `path` (text `text`, folder `base`): each holdout's mesh read
/// and placed by its transform. `None` without holdouts and ground. An error is located at the
/// holdout's mesh path in the scene text and names the mesh file.
pub fn load(
    path: &Path,
    text: &str,
    base: &Path,
    holdouts: &[HoldoutSpec],
    ground: Option<GroundSpec>,
) -> Result<Option<Arc<Surfaces>>, SceneError> {
    if holdouts.is_empty() && ground.is_none() {
        return Ok(None);
    }
    let located = |i: usize, mesh: &str, message: String| {
        let (line, column) = super::super::locate(text, "holdouts", mesh);
        SceneError::File(FileError::Parse {
            path: path.to_path_buf(),
            line,
            column,
            message: format!("holdouts[{i}].mesh: {message}"),
        })
    };
    let mut e = Encoder::new();
    e.str("surfaces").len(holdouts.len());
    let mut meshes = Vec::with_capacity(holdouts.len());
    for (i, h) in holdouts.iter().enumerate() {
        let at_prim = |message: String| {
            let (line, column) = locate_prim(text, &h.mesh, h.prim.as_deref().unwrap_or(""));
            SceneError::File(FileError::Parse {
                path: path.to_path_buf(),
                line,
                column,
                message: format!("holdouts[{i}].prim: {message}"),
            })
        };
        let usd = super::usd_mesh::is_usd(&h.mesh);
        if h.prim.is_some() && !usd {
            return Err(at_prim(format!(
                "{}: `prim` names a prim of a USD stage (.usd, .usda, .usdc, .usdz)",
                h.mesh
            )));
        }
        let mesh = if h.mesh.starts_with("builtin:") {
            crate::mesh::load(&h.mesh).map(|m| m.mesh)
        } else {
            let full = base.join(&h.mesh);
            if !full.exists() {
                return Err(located(
                    i,
                    &h.mesh,
                    format!(
                        "{} does not exist (relative paths resolve against the scene file's folder)",
                        full.display()
                    ),
                ));
            }
            if usd {
                let mesh = super::usd_mesh::read(&full, h.prim.as_deref()).map_err(|e| {
                    match (e.field, &h.prim) {
                        (super::usd_stage::Field::Prim, Some(_)) => at_prim(e.message),
                        _ => located(i, &h.mesh, e.message),
                    }
                })?;
                mesh.validate(&full).map(|()| mesh)
            } else {
                crate::mesh::io::read_mesh(&full).and_then(|m| m.validate(&full).map(|()| m))
            }
        }
        .map_err(|err| located(i, &h.mesh, format!("{}: {err}", h.mesh)))?;
        let positions: Vec<_> = mesh
            .positions
            .iter()
            .map(|&p| h.transform.apply_point(p))
            .collect();
        e.str("holdout").len(positions.len());
        for p in &positions {
            e.put(&p.x).put(&p.y).put(&p.z);
        }
        e.len(mesh.triangles.len());
        for t in &mesh.triangles {
            e.put(&t[0]).put(&t[1]).put(&t[2]);
        }
        e.put(&h.shadows);
        meshes.push((
            i,
            HoldoutMesh {
                positions,
                triangles: mesh.triangles,
                shadows: h.shadows,
            },
        ));
    }
    if let Some(g) = ground {
        e.str("ground").put(&g.height).put(&g.shadow_pass);
    }
    let key = e.finish();
    let names: Vec<(usize, String)> = meshes
        .iter()
        .map(|(i, _)| (*i, holdouts[*i].mesh.clone()))
        .collect();
    let surfaces = Surfaces::new(
        key,
        meshes.into_iter().map(|(_, m)| m).collect(),
        ground.map(|g| Ground {
            height: g.height as f32,
        }),
        ground.is_some_and(|g| g.shadow_pass),
    )
    .map_err(|message| {
        let (i, name) = names.first().cloned().unwrap_or_default();
        located(i, &name, format!("{name}: {message}"))
    })?;
    Ok(Some(Arc::new(surfaces)))
}

/// The line and column of holdout `mesh`'s `prim` value in the scene `text` (the first
/// `"prim"` after the first `"mesh"` in `holdouts`).
fn locate_prim(text: &str, mesh: &str, prim: &str) -> (usize, usize) {
    let mut at = text.find("holdouts").unwrap_or(0);
    for value in [mesh, prim] {
        if let Some(p) = text[at..].find(&format!("\"{value}\"")) {
            at += p;
        }
    }
    let before = &text[..at];
    let line = before.matches('\n').count() + 1;
    let column = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
    (line, column)
}
