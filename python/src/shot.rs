//! `Shot` (a scene's shot opened with render options: frames rendered in memory, its blobs and
//! camera, the whole shot rendered to files as `nephele render` does) and `FrameIter`
//! (a sequence in memory through one renderer, with the shot loop's reuse). Long work runs
//! with the GIL released; Python callbacks are called back under it.

use std::ops::ControlFlow;
use std::path::PathBuf;

use nephele::render::{FrameRenderer, Reuse};
use nephele::scene::{self, SceneError as CoreSceneError};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use crate::args::{int_in, selection};
use crate::arrays::{blobs_array, f64_bytes, numpy_array};
use crate::errors::{scene_err, scene_field_err, scene_other};
use crate::layers::Layers;
use crate::model::Model;

/// A scene's shot, opened with render options. Nothing mutates it after `Scene.shot`: its
/// target and plan are made once, on first need, so any number of threads (and a
/// `render_all` progress callback) can use it at once.
#[pyclass(module = "nephele", frozen)]
pub(crate) struct Shot {
    shot: scene::Shot,
}

impl Shot {
    /// The Python object of an opened shot.
    pub(crate) fn new(shot: scene::Shot) -> Shot {
        Shot { shot }
    }

    fn read(&self) -> &scene::Shot {
        &self.shot
    }

    /// The shot's 0-based frame of frame number `frame`: a `ValueError` naming the shot's
    /// frames for one outside them (or no integer ≥ 0).
    fn index(shot: &scene::Shot, frame: &Bound<'_, PyAny>) -> PyResult<u32> {
        let first = shot.number(0);
        let last = shot.number(shot.total() - 1);
        let outside = |f: &dyn std::fmt::Display| {
            PyValueError::new_err(format!(
                "frame {f} is outside the shot (frames {first}..{last})"
            ))
        };
        let frame = match int_in("frame", "frame", frame, 0, u64::from(u32::MAX)) {
            Ok(f) => f as u32,
            Err(e) if e.is_instance_of::<PyValueError>(frame.py()) => {
                return Err(outside(&frame.repr()?));
            }
            Err(e) => return Err(e),
        };
        if frame < first || frame > last {
            return Err(outside(&frame));
        }
        Ok(shot.index(frame))
    }

    /// Render `frame` on its own (nothing reused, nothing kept) with the GIL released, and
    /// convert it for numpy while still without the GIL.
    fn frame(&self, py: Python<'_>, frame: &Bound<'_, PyAny>) -> PyResult<Layers> {
        let shot = self.read();
        let k = Self::index(shot, frame)?;
        let space = shot.scene().file.output.colorspace;
        py.detach(|| shot.render_frame(k).map(|image| Layers::of(&image, space)))
            .map_err(scene_err)
    }
}

/// The frame a [`FrameRenderer`] renders for 0-based frame `k` of `shot`: the shot loop's own
/// request (`Shot::frame_request`: the frame's settings, blobs and shutter) into the shot's
/// film, so a frame comes out with the bits of the CLI's file.
fn render_with(
    renderer: &mut FrameRenderer,
    shot: &scene::Shot,
    k: u32,
) -> Result<(Layers, Reuse), CoreSceneError> {
    let request = shot.frame_request(k)?;
    let options = request.options(shot.film()?);
    let (image, report) = renderer.render_reporting(&request.settings, &request.blobs, &options);
    let space = shot.scene().file.output.colorspace;
    Ok((Layers::of(image, space), report.reuse))
}

#[pymethods]
impl Shot {
    /// The frame numbers to render (the scene's `frames`, or the `frames` given), sorted.
    #[getter]
    fn frames(&self) -> Vec<u32> {
        self.read().frames().to_vec()
    }

    /// All frame numbers of the shot, first to last.
    #[getter]
    fn all_frames(&self) -> Vec<u32> {
        let shot = self.read();
        (0..shot.total()).map(|k| shot.number(k)).collect()
    }

    /// Image `(width, height)` in pixels.
    #[getter]
    fn size(&self) -> (u32, u32) {
        self.read().size()
    }

    /// Frames per second.
    #[getter]
    fn fps(&self) -> f64 {
        self.read().scene().file.shot.fps
    }

    /// Open shutter as a fraction of a frame (`shot.shutter`; 0 = no motion blur).
    #[getter]
    fn shutter(&self) -> f64 {
        self.read().scene().file.shot.shutter
    }

    /// Folder the frame files are written to.
    #[getter]
    fn dir(&self) -> PathBuf {
        self.read().dir().to_path_buf()
    }

    /// True when frames are rendered with passes.
    #[getter]
    fn passes(&self) -> bool {
        self.read().passes()
    }

    /// The file names of `frame` (one per format, plus the blob dump if asked), in `dir`.
    fn frame_paths(&self, frame: u32) -> Vec<PathBuf> {
        scene::frame_names::frame_paths(self.read(), frame)
    }

    /// Render `frame` in memory: (H, W, 4) float32 linear RGBA, premultiplied, in the scene's
    /// `output.colorspace`: the values of the R, G, B, A channels of the EXR that
    /// `nephele render` writes for the frame, bit for bit. The frame is rendered on its own
    /// (nothing of it is kept); `frames_iter` renders a sequence with the shot's reuse.
    fn render<'py>(
        &self,
        py: Python<'py>,
        frame: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyAny>> {
        self.frame(py, frame)?.rgba(py)
    }

    /// Render `frame` in memory with every layer the EXR has: `rgba` (H, W, 4), `depth`
    /// (H, W; the EXR's Z, infinity where empty), and when the shot has passes (`passes=True`
    /// or `output.passes`) `sun`, `sky`, `multiple` (H, W, 3 each; they sum to the RGB) and
    /// `mattes`, the Cryptomatte layer (a dict: `layer`, `names`, `ids`, `manifest`, `key`,
    /// and (H, W, 6) arrays `index` int32, `id` and `coverage` float32, ranked by coverage).
    fn render_passes<'py>(
        &self,
        py: Python<'py>,
        frame: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyDict>> {
        self.frame(py, frame)?.dict(py)
    }

    /// Render frames in memory, in order, through one renderer that keeps what the shot loop
    /// keeps (a hold reuses the last frame, a still cloud its light grid): an iterator of
    /// `(frame, image)`, `image` being `render(frame)`'s array, or `render_passes(frame)`'s
    /// dict with `layers=True`. `frames` is a selection like `Scene.shot`'s (default: the
    /// shot's frames). Each frame has the bits `render(frame)` gives.
    #[pyo3(signature = (frames=None, layers=false))]
    fn frames_iter(
        slf: &Bound<'_, Self>,
        frames: Option<&Bound<'_, PyAny>>,
        layers: bool,
    ) -> PyResult<FrameIter> {
        let shot = slf.get().read();
        let frames = match frames {
            None => shot.frames().to_vec(),
            Some(f) => {
                let (first, last) = (shot.number(0), shot.number(shot.total() - 1));
                let path = &shot.scene().path;
                selection(f, path)?
                    .resolve(first, last)
                    .map_err(|e| scene_field_err(path, "frames", e))?
            }
        };
        Ok(FrameIter {
            shot: slf.clone().unbind(),
            renderer: FrameRenderer::new(),
            frames,
            next: 0,
            layers,
            reuse: None,
        })
    }

    /// The blobs of `frame`, an (N, 12) float64 array with `Model.COLUMNS`.
    fn blobs<'py>(
        &self,
        py: Python<'py>,
        frame: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let shot = self.read();
        let k = Self::index(shot, frame)?;
        let blobs = py.detach(|| shot.blobs(k)).map_err(scene_err)?;
        blobs_array(py, &blobs)
    }

    /// The target model (loaded, or fitted and cached in the output folder), placed by the
    /// scene's transform.
    #[getter]
    fn target(&self, py: Python<'_>) -> PyResult<Model> {
        let shot = self.read();
        let model = py
            .detach(|| shot.prepared().map(|p| p.model.clone()))
            .map_err(scene_err)?;
        Ok(Model { model })
    }

    /// The camera of `frame` as rendered: `eye`, `right`, `up`, `forward` (world, unit axes),
    /// `tan_half_fov` `(horizontal, vertical)`, and the EXR header's `world_to_camera` and
    /// `world_to_ndc` (4×4, row-vector convention `p' = p · M`).
    fn camera<'py>(
        &self,
        py: Python<'py>,
        frame: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let shot = self.read();
        let k = Self::index(shot, frame)?;
        let settings = py.detach(|| shot.settings(k)).map_err(scene_err)?;
        let cam = nephele::render::output::CameraFrame::new(
            &settings.camera,
            settings.width,
            settings.height,
        );
        let (view, ndc) = cam.exr_matrices();
        let d = PyDict::new(py);
        d.set_item("eye", cam.eye.to_array())?;
        d.set_item("right", cam.right.to_array())?;
        d.set_item("up", cam.up.to_array())?;
        d.set_item("forward", cam.forward.to_array())?;
        d.set_item("tan_half_fov", (cam.tan_half_h, cam.tan_half_v))?;
        // The EXR header stores the matrices in single precision.
        let view32: Vec<f64> = view.iter().map(|v| *v as f32 as f64).collect();
        let ndc32: Vec<f64> = ndc.iter().map(|v| *v as f32 as f64).collect();
        d.set_item(
            "world_to_camera",
            numpy_array(py, &f64_bytes(&view32), "float64", vec![4, 4])?,
        )?;
        d.set_item(
            "world_to_ndc",
            numpy_array(py, &f64_bytes(&ndc32), "float64", vec![4, 4])?,
        )?;
        Ok(d)
    }

    /// Render the shot's frames to files, as `nephele render` does: one run of the shot
    /// (`Shot::run`, its reuse and its writing beside the next frame's render), resumable
    /// (finished, up-to-date frames are skipped unless the shot was opened with `force=True`),
    /// with the GIL released. `progress(report)` is called after each frame with a dict
    /// `frame`, `of` (the shot's last frame), `skipped`, `seconds`, `index` (0-based among the
    /// frames), `count`; the frame's files are then being written (all of them are on disk
    /// when `render_all` returns). An exception `progress` raises, or Ctrl-C, stops the shot
    /// after that frame (its files written) and is raised. Returns `{"dir", "rendered",
    /// "skipped", "out_of_date"}`.
    #[pyo3(signature = (progress=None))]
    fn render_all<'py>(
        &self,
        py: Python<'py>,
        progress: Option<Py<PyAny>>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let shot = self.read();
        let count = shot.frames().len();
        nephele::atomic::check_output_dir(shot.dir()).map_err(|e| scene_other(&e))?;
        let mut index = 0usize;
        let mut stopped: Option<PyErr> = None;
        let report = py.detach(|| {
            shot.run_until(&mut |f| {
                let i = index;
                index += 1;
                Python::attach(|py| {
                    let called = (|| -> PyResult<()> {
                        if let Some(cb) = &progress {
                            let d = PyDict::new(py);
                            d.set_item("frame", f.frame)?;
                            d.set_item("of", f.of)?;
                            d.set_item("skipped", f.skipped)?;
                            d.set_item("seconds", f.seconds)?;
                            d.set_item("index", i)?;
                            d.set_item("count", count)?;
                            cb.call1(py, (d,))?;
                        }
                        py.check_signals()
                    })();
                    match called {
                        Ok(()) => ControlFlow::Continue(()),
                        Err(e) => {
                            stopped = Some(e);
                            ControlFlow::Break(())
                        }
                    }
                })
            })
        });
        // A failed write is the worse news; else the stop's exception.
        let report = report.map_err(scene_err)?;
        if let Some(e) = stopped {
            return Err(e);
        }
        let d = PyDict::new(py);
        d.set_item("dir", report.output_dir)?;
        d.set_item("rendered", report.rendered)?;
        d.set_item("skipped", report.skipped)?;
        d.set_item("out_of_date", PyList::new(py, report.out_of_date)?)?;
        Ok(d)
    }

    fn __repr__(&self) -> String {
        let shot = self.read();
        let (w, h) = shot.size();
        format!(
            "nephele.Shot({:?}, {} frames, {w}×{h})",
            shot.scene().path,
            shot.frames().len()
        )
    }
}

/// `Shot.frames_iter`'s iterator: renders the next frame on `next()` (GIL released),
/// through one [`FrameRenderer`] for all of them.
#[pyclass(module = "nephele")]
pub(crate) struct FrameIter {
    shot: Py<Shot>,
    renderer: FrameRenderer,
    frames: Vec<u32>,
    next: usize,
    layers: bool,
    reuse: Option<Reuse>,
}

#[pymethods]
impl FrameIter {
    fn __iter__(slf: PyRef<'_, Self>) -> PyRef<'_, Self> {
        slf
    }

    fn __next__(&mut self, py: Python<'_>) -> PyResult<Option<(u32, Py<PyAny>)>> {
        let Some(&frame) = self.frames.get(self.next) else {
            return Ok(None);
        };
        self.next += 1;
        let shot = self.shot.get().read();
        let k = shot.index(frame);
        let renderer = &mut self.renderer;
        let (layers, reuse) = py
            .detach(|| render_with(renderer, shot, k))
            .map_err(scene_err)?;
        self.reuse = Some(reuse);
        let image = if self.layers {
            layers.dict(py)?.into_any().unbind()
        } else {
            layers.rgba(py)?.unbind()
        };
        Ok(Some((frame, image)))
    }

    fn __len__(&self) -> usize {
        self.frames.len() - self.next
    }

    /// The frame numbers this iterator renders, in order.
    #[getter]
    fn frames(&self) -> Vec<u32> {
        self.frames.clone()
    }

    /// What the last frame took from the one before: `"frame"` (a hold: nothing rendered),
    /// `"light_grid"` (a still cloud: its lighting), `"buffers"` (memory only; also the first
    /// frame and every frame with motion blur); `None` before the first frame.
    #[getter]
    fn reuse(&self) -> Option<&'static str> {
        self.reuse.map(|r| match r {
            Reuse::Frame => "frame",
            Reuse::LightGrid => "light_grid",
            Reuse::Buffers => "buffers",
        })
    }

    fn __repr__(&self) -> String {
        format!(
            "nephele.FrameIter({} of {} frames left)",
            self.frames.len() - self.next,
            self.frames.len()
        )
    }
}
