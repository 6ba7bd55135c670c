//! A rendered frame as the arrays of its EXR layers: RGBA and the passes in the output colour
//! space ([`nephele::render::output::RgbConverter`], the EXR writer's conversion), depth, and
//! the Cryptomatte layer with the writer's ids, manifest and rank rule
//! ([`nephele::render::output::cryptomatte::IdMattes`]). The bytes are made without the GIL;
//! the arrays and dicts with it.

use nephele::render::Frame;
use nephele::render::output::ColorSpace;
use nephele::render::output::cryptomatte::{self, RANKS};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::arrays::{f32_bytes, i32_bytes, numpy_array};

/// A rendered frame as the bytes of its numpy arrays (native-endian), made without the GIL.
pub(crate) struct Layers {
    width: usize,
    height: usize,
    /// (H, W, 4) float32 RGBA in the output colour space.
    rgba: Vec<u8>,
    /// (H, W) float32.
    depth: Vec<u8>,
    /// `sun`, `sky`, `multiple`: (H, W, 3) float32 each.
    passes: Option<[(&'static str, Vec<u8>); 3]>,
    mattes: Option<MatteLayers>,
}

/// A frame's Cryptomatte layer ([`nephele::render::IdMattes`]) as arrays.
struct MatteLayers {
    layer: String,
    names: Vec<String>,
    /// Each name's id.
    ids: Vec<f32>,
    /// The header's manifest: name and the id's bits in hex.
    manifest: Vec<(String, String)>,
    /// (H, W, RANKS) int32: the rank's matte (index into `names`), -1 where empty.
    index: Vec<u8>,
    /// (H, W, RANKS) float32: the rank's id as the EXR stores it (0 where empty).
    id: Vec<u8>,
    /// (H, W, RANKS) float32: the rank's coverage.
    coverage: Vec<u8>,
}

impl Layers {
    /// The layers of `image`, its colours in `space`.
    pub(crate) fn of(image: &Frame, space: ColorSpace) -> Layers {
        let to_space = space.converter();
        let mut rgba = Vec::with_capacity(image.alpha.len() * 4);
        for (rgb, a) in image.rgb.iter().zip(&image.alpha) {
            rgba.extend_from_slice(&to_space.apply(*rgb));
            rgba.push(*a);
        }
        let passes = image.passes.as_ref().map(|p| {
            let layer = |l: &[[f32; 3]]| {
                f32_bytes(
                    &l.iter()
                        .flat_map(|c| to_space.apply(*c))
                        .collect::<Vec<_>>(),
                )
            };
            [
                ("sun", layer(&p.sun)),
                ("sky", layer(&p.sky)),
                ("multiple", layer(&p.multiple)),
            ]
        });
        let mattes = image.mattes.as_ref().map(|m| {
            let ids = m.ids();
            let n = m.ranks.len() * RANKS;
            let (mut index, mut id, mut coverage) = (
                Vec::with_capacity(n),
                Vec::with_capacity(n),
                Vec::with_capacity(n),
            );
            for pixel in &m.ranks {
                for &r in pixel {
                    // The EXR writer's rule: an id only where the rank names a matte.
                    let named = m.named(r);
                    index.push(named.map_or(-1, |k| k as i32));
                    id.push(named.map_or(0.0, |k| ids[k]));
                    coverage.push(r.coverage);
                }
            }
            MatteLayers {
                layer: m.layer.clone(),
                names: m.names.clone(),
                // In the names' order (the header's JSON is sorted by name).
                manifest: {
                    let manifest = m.manifest();
                    m.names
                        .iter()
                        .map(|n| (n.clone(), manifest[n.as_str()].clone()))
                        .collect()
                },
                ids,
                index: i32_bytes(&index),
                id: f32_bytes(&id),
                coverage: f32_bytes(&coverage),
            }
        });
        Layers {
            width: image.width as usize,
            height: image.height as usize,
            rgba: f32_bytes(&rgba),
            depth: f32_bytes(&image.depth),
            passes,
            mattes,
        }
    }

    /// The (H, W, 4) float32 RGBA array.
    pub(crate) fn rgba<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        numpy_array(py, &self.rgba, "float32", vec![self.height, self.width, 4])
    }

    /// `render_passes`' dict.
    pub(crate) fn dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let (h, w) = (self.height, self.width);
        let out = PyDict::new(py);
        out.set_item("rgba", self.rgba(py)?)?;
        out.set_item(
            "depth",
            numpy_array(py, &self.depth, "float32", vec![h, w])?,
        )?;
        if let Some(passes) = &self.passes {
            for (name, bytes) in passes {
                out.set_item(*name, numpy_array(py, bytes, "float32", vec![h, w, 3])?)?;
            }
        }
        if let Some(m) = &self.mattes {
            let d = PyDict::new(py);
            d.set_item("layer", &m.layer)?;
            d.set_item("names", &m.names)?;
            let manifest = PyDict::new(py);
            for (name, hex) in &m.manifest {
                manifest.set_item(name, hex)?;
            }
            d.set_item("ids", &m.ids)?;
            d.set_item("manifest", manifest)?;
            d.set_item("key", cryptomatte::layer_key(&m.layer))?;
            let shape = vec![h, w, RANKS];
            d.set_item("index", numpy_array(py, &m.index, "int32", shape.clone())?)?;
            d.set_item("id", numpy_array(py, &m.id, "float32", shape.clone())?)?;
            d.set_item("coverage", numpy_array(py, &m.coverage, "float32", shape)?)?;
            out.set_item("mattes", d)?;
        }
        Ok(out)
    }
}
