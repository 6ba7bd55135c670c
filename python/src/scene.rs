//! `Scene`: a scene file loaded and validated by the library (`scene_from_str`, so its errors
//! are the CLI's, with file, line and field), read from RON text or a dict, and its shot opened
//! with the options of `nephele render`.

use std::path::PathBuf;

use nephele::scene::{self, Override, RenderOptions, SceneFile};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use serde_json::Value;
use serde_path_to_error::Segment;

use crate::args::selection;
use crate::errors::{scene_err, scene_field_err};
use crate::shot::Shot;

/// The overrides of `Scene.load(set=..., size=...)`, parsed as the CLI parses them (a
/// malformed one is the CLI's message) and in its order.
fn overrides(set: &[String], size: Option<&str>) -> Result<Vec<Override>, String> {
    let size = size.map(Override::size).transpose()?;
    let set = set
        .iter()
        .map(|s| Override::set(s))
        .collect::<Result<Vec<_>, _>>()?;
    Ok(scene::overrides::in_order(size.as_ref(), &set))
}

/// A loaded, validated scene.
#[pyclass(module = "nephele", frozen)]
pub(crate) struct Scene {
    scene: scene::Scene,
}

#[pymethods]
impl Scene {
    /// Read, parse and validate a scene file (RON), with the CLI's overrides: `size`
    /// (`"WxH"`, as `--size`) first, then each `set` (`"KEY=VALUE"`, as `--set`) in order.
    #[staticmethod]
    #[pyo3(signature = (path, set=Vec::new(), size=None))]
    fn load(
        py: Python<'_>,
        path: PathBuf,
        set: Vec<String>,
        size: Option<String>,
    ) -> PyResult<Scene> {
        let overrides = overrides(&set, size.as_deref()).map_err(PyValueError::new_err)?;
        let scene = py
            .detach(|| scene::load_scene_with(&path, &overrides))
            .map_err(scene_err)?;
        Ok(Scene { scene })
    }

    /// Parse and validate scene text (RON); `path` names it in errors and is where relative
    /// target paths resolve from (its folder) and the default output name comes from.
    #[staticmethod]
    #[pyo3(signature = (text, path="scene.ron".into()))]
    fn from_str(text: &str, path: PathBuf) -> PyResult<Scene> {
        let scene = scene::scene_from_str(&path, text).map_err(scene_err)?;
        Ok(Scene { scene })
    }

    /// `from_dict` after `json.dumps`: the JSON is read into the scene file's own types, written
    /// back as RON and loaded like a file (same validation and messages). A value of the wrong
    /// type is a `SceneError` naming its key path (`field`) and what the key takes.
    #[staticmethod]
    fn _from_json(json: &str, path: PathBuf) -> PyResult<Scene> {
        let value: Value =
            serde_json::from_str(json).map_err(|e| scene_field_err(&path, ".", e))?;
        let file: SceneFile = serde_path_to_error::deserialize(&value).map_err(|e| {
            let field = e.path().to_string();
            let what = expected(&value, e.path(), e.inner().to_string());
            scene_field_err(&path, &field, what)
        })?;
        let text = ron::ser::to_string_pretty(&file, ron::ser::PrettyConfig::new())
            .map_err(|e| scene_field_err(&path, ".", e))?;
        // The RON is ours, not the user's: its lines would locate nothing for them.
        let scene = scene::scene_from_str(&path, &text).map_err(|e| scene_err(e.unlocated()))?;
        Ok(Scene { scene })
    }

    /// The scene file as JSON text (its target paths resolved), for `to_dict`.
    fn _to_json(&self) -> PyResult<String> {
        serde_json::to_string(&self.scene.file).map_err(|e| PyValueError::new_err(e.to_string()))
    }

    /// The scene file as RON text (its target paths resolved).
    fn to_ron(&self) -> PyResult<String> {
        ron::ser::to_string_pretty(&self.scene.file, ron::ser::PrettyConfig::new())
            .map_err(|e| PyValueError::new_err(e.to_string()))
    }

    /// The scene file's path (as given).
    #[getter]
    fn path(&self) -> PathBuf {
        self.scene.path.clone()
    }

    /// Frame file prefix (`output.name`, else the file's stem).
    #[getter]
    fn name(&self) -> String {
        self.scene.name.clone()
    }

    /// Output folder (`output.dir`, else `renders/<stem>`).
    #[getter]
    fn output_dir(&self) -> PathBuf {
        self.scene.output_dir.clone()
    }

    fn __repr__(&self) -> String {
        format!("nephele.Scene({:?})", self.scene.path)
    }

    /// Open the scene's shot (the options of `nephele render`). `frames` is a frame selection
    /// (`"1..24,30"`, or a list of frame numbers), `formats` overrides `output.formats`
    /// (`["exr", "vdb"]`), `output` overrides the output folder, `region` is
    /// `"x0,y0,x1,y1"`; `clean` removes the frames' files of formats the run does not write
    /// (kept otherwise).
    #[pyo3(signature = (preview=false, passes=false, frames=None, output=None, formats=None, force=false, region=None, dump_blobs=false, clean=false))]
    #[allow(clippy::too_many_arguments)]
    fn shot(
        &self,
        preview: bool,
        passes: bool,
        frames: Option<&Bound<'_, PyAny>>,
        output: Option<PathBuf>,
        formats: Option<Vec<String>>,
        force: bool,
        region: Option<String>,
        dump_blobs: bool,
        clean: bool,
    ) -> PyResult<Shot> {
        let frames = frames.map(|f| selection(f, &self.scene.path)).transpose()?;
        let mut scene = self.scene.clone();
        if let Some(list) = formats {
            scene.file.output.formats = list
                .iter()
                .map(|name| nephele::render::output::parse_format(name))
                .collect::<Result<_, _>>()
                .map_err(|e| scene_field_err(&self.scene.path, "formats", e))?;
        }
        let options = RenderOptions {
            frames,
            output,
            preview,
            force,
            clean,
            dump_blobs,
            stats: false,
            passes,
            region,
        };
        let shot = scene::Shot::open(scene, &options).map_err(scene_err)?;
        Ok(Shot::new(shot))
    }
}

/// serde's message for the value at `path` of `value`, where a wrong type for an enum (serde's
/// `expected string or map`) says which variants the key takes and how a dict writes them.
fn expected(value: &Value, path: &serde_path_to_error::Path, message: String) -> String {
    const ENUM: &str = ", expected string or map";
    let Some(got) = message.strip_suffix(ENUM) else {
        return message;
    };
    // The variants, from serde's own refusal of a variant no enum has, at the same place.
    let mut probe = value.clone();
    let Some(slot) = at(&mut probe, path) else {
        return message;
    };
    *slot = Value::String("\u{1}".into());
    let variants = match serde_path_to_error::deserialize::<_, SceneFile>(&probe) {
        Err(e) if e.path().to_string() == path.to_string() => {
            let text = e.inner().to_string();
            match text.split_once(", expected ") {
                Some((_, list)) if text.starts_with("unknown variant") => list.to_string(),
                _ => return message,
            }
        }
        _ => return message,
    };
    format!(
        "{got}, expected {variants}: a one-key dict {{\"Variant\": value}}, or the variant's \
         name alone when it has no data"
    )
}

/// The value at `path` in `value` (an enum's variant is the key of its one-key dict).
fn at<'v>(value: &'v mut Value, path: &serde_path_to_error::Path) -> Option<&'v mut Value> {
    let mut cur = value;
    for segment in path.iter() {
        cur = match segment {
            Segment::Seq { index } => cur.get_mut(*index)?,
            Segment::Map { key } => cur.get_mut(key.as_str())?,
            Segment::Enum { variant } => cur.get_mut(variant.as_str())?,
            Segment::Unknown => return None,
        };
    }
    Some(cur)
}
