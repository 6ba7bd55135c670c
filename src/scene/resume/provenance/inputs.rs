//! A frame's inputs, hashed part by part ([`Component`]) through their canonical encoding, and
//! which parts each kind of file ([`FileKind`]) is made from.

use std::collections::BTreeMap;

use crate::render::{Film, RENDER_VERSION, RenderSettings};
use crate::scene::resume::canonical::{Canonical, Encoder};
use crate::scene::resume::frame_names::FileKind;
use crate::scene::shot::request::FrameRequest;
use crate::scene::{Format, Shot};

use super::manifest::Manifest;

/// One part of a frame's inputs, hashed on its own so that a reason can name what changed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Component {
    /// [`RENDER_VERSION`].
    Renderer,
    /// Image size, quality, exposure, seed, time, length unit; the holdouts and ground plane.
    Image,
    /// The frame's camera.
    Camera,
    /// Sun and sky.
    Light,
    /// Cloud material, billows and base.
    Look,
    /// The frame's blobs.
    Blobs,
    /// Region, passes and ID mattes.
    Film,
    /// The open shutter's time samples.
    Shutter,
    /// Voxel size, the blobs' motions and the frame rate (the grids and their velocity).
    Grid,
    /// The EXR header's strings and frame rate.
    Header,
}

impl Component {
    /// Every component, in manifest order.
    pub const ALL: [Component; 10] = [
        Component::Renderer,
        Component::Image,
        Component::Camera,
        Component::Light,
        Component::Look,
        Component::Blobs,
        Component::Film,
        Component::Shutter,
        Component::Grid,
        Component::Header,
    ];

    /// Its key in a manifest.
    pub fn key(self) -> &'static str {
        match self {
            Component::Renderer => "renderer",
            Component::Image => "image",
            Component::Camera => "camera",
            Component::Light => "light",
            Component::Look => "look",
            Component::Blobs => "blobs",
            Component::Film => "film",
            Component::Shutter => "shutter",
            Component::Grid => "grid",
            Component::Header => "header",
        }
    }

    /// What it is, for a reason.
    pub fn label(self) -> &'static str {
        match self {
            Component::Renderer => "renderer",
            Component::Image => "image size, quality, holdouts or ground",
            Component::Camera => "camera",
            Component::Light => "sun and sky",
            Component::Look => "cloud look",
            Component::Blobs => "cloud shape (blobs)",
            Component::Film => "region, passes or mattes",
            Component::Shutter => "shutter",
            Component::Grid => "grid (voxel size, motion, fps)",
            Component::Header => "EXR header (scene, seed, colour space, fps)",
        }
    }

    /// The components a file of `kind` is made from.
    pub(super) fn of(kind: FileKind) -> &'static [Component] {
        use Component::*;
        match kind {
            FileKind::Format(Format::Exr) => &[
                Renderer, Image, Camera, Light, Look, Blobs, Film, Shutter, Header,
            ],
            FileKind::Format(Format::Png) => {
                &[Renderer, Image, Camera, Light, Look, Blobs, Film, Shutter]
            }
            FileKind::Format(Format::Vdb) | FileKind::Format(Format::Vol) => {
                &[Renderer, Look, Blobs, Grid]
            }
            FileKind::Blobs => &[Blobs],
        }
    }
}

/// A frame's inputs, hashed by component (see the module doc).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FrameInputs {
    hashes: BTreeMap<Component, u64>,
}

impl FrameInputs {
    /// The hash of one component.
    pub fn hash(&self, c: Component) -> u64 {
        self.hashes[&c]
    }

    /// Every component's hash as a manifest lists them: by [`Component::key`], as
    /// [`super::hash_text`].
    pub fn listed(&self) -> BTreeMap<String, String> {
        Component::ALL
            .iter()
            .map(|&c| (c.key().to_string(), super::hash_text(self.hash(c))))
            .collect()
    }

    /// The hash of a file of `kind`: its kind and the hashes of the components it is made from.
    pub fn file_hash(&self, kind: FileKind) -> u64 {
        let mut e = Encoder::new();
        e.str("nephele frame file").str(kind.key());
        for &c in Component::of(kind) {
            e.str(c.key()).put(&self.hash(c));
        }
        e.finish()
    }
}

/// The inputs of frame `request` of `shot`, rendered into `film`; `voxel` is the density
/// grids' voxel size; `on_disk` the frame's manifest, when it has one (read once a frame, for
/// this and [`super::check_frame`]).
pub fn frame_inputs(
    shot: &Shot,
    request: &FrameRequest,
    film: &Film,
    voxel: f64,
    on_disk: Option<&Manifest>,
) -> FrameInputs {
    let FrameRequest {
        k, settings, blobs, ..
    } = request;
    let k = *k;
    let scene = shot.scene();
    let file = &scene.file;
    let hash = |f: &dyn Fn(&mut Encoder)| {
        let mut e = Encoder::new();
        f(&mut e);
        e.finish()
    };
    let mut hashes = BTreeMap::new();
    hashes.insert(
        Component::Renderer,
        hash(&|e| {
            e.str("render version").put(&RENDER_VERSION);
        }),
    );
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
    } = settings;
    hashes.insert(
        Component::Image,
        hash(&|e| {
            e.put(width)
                .put(height)
                .put(exposure)
                .put(length_scale)
                .put(seed)
                .put(time)
                .put(quality);
            // The holdouts and the ground plane (their meshes, transforms, flags, the shadow
            // pass), only when the scene has any: other frames keep their hashes.
            if let Some(s) = surfaces {
                e.str("surfaces").put(&s.key());
                // The shadow pass writes `shadow_total` too: frames rendered before it lack
                // the layer and are redone.
                if s.shadow_pass() {
                    e.str("shadow_total");
                }
            }
        }),
    );
    hashes.insert(Component::Camera, camera.canonical_hash());
    hashes.insert(
        Component::Light,
        hash(&|e| {
            e.put(sun).put(sky);
        }),
    );
    hashes.insert(
        Component::Look,
        hash(&|e| {
            e.put(cloud).put(base).put(length_scale);
        }),
    );
    hashes.insert(Component::Blobs, blobs.canonical_hash());
    // An open shutter renders the blobs over its time samples.
    let shutter = request.shutter.as_ref();
    hashes.insert(
        Component::Shutter,
        hash(&|e| {
            e.put(&file.shot.shutter).put(&shutter);
        }),
    );
    // A VDB also holds the velocity grid, made from the blobs' motions about the frame's time
    // (in units per second, so the frame rate counts too), and UUIDs from the seed and frame.
    // Also when the run writes no VDB but the frame has one (kept from another run), so that
    // it can be told whether that VDB is still current.
    let frame = shot.number(k);
    let vdb = FileKind::Format(Format::Vdb);
    let lists_vdb = on_disk.is_some_and(|m| m.files.iter().any(|f| f.kind == vdb.key()));
    let motions = if file.output.formats.contains(&Format::Vdb) || lists_vdb || film.motion {
        shot.prepared().ok().map(|prep| {
            let t = prep.plan.timeline().time(k as usize);
            prep.direction.velocity(&prep.plan, t).motions().to_vec()
        })
    } else {
        None
    };
    // The motion vectors are the blobs' motions seen through the camera, per frame.
    hashes.insert(
        Component::Film,
        if film.motion {
            hash(&|e| {
                e.put(film).put(&motions).put(&file.shot.fps);
            })
        } else {
            film.canonical_hash()
        },
    );
    hashes.insert(
        Component::Grid,
        hash(&|e| {
            e.put(&voxel)
                .put(&motions)
                .put(&file.shot.fps)
                .put(&file.seed)
                .put(&frame);
            // The settings added since, only when set: a scene without them keeps its hash.
            if let Some(p) = file.output.voxel_pixels {
                e.str("voxel_pixels").put(&p);
            }
            if file.output.vdb_precision == crate::export::Precision::Half {
                e.str("vdb_precision half");
            }
        }),
    );
    let meta = header_strings(shot, frame, 0);
    hashes.insert(
        Component::Header,
        hash(&|e| {
            for (k, v) in &meta {
                // The hash itself is written after it is known.
                if k != "hash" {
                    e.str(k).str(v);
                }
            }
            let (num, den) = crate::render::output::fps_rational(file.shot.fps);
            e.put(&num).put(&den).put(&file.shot.fps);
            e.put(&(file.output.colorspace as u8));
        }),
    );
    FrameInputs { hashes }
}

/// The `nephele/…` strings of frame number `frame`'s EXR with file hash `hash`: `scene` (the
/// scene file's name), `frame`, `hash`, `colorspace`, `seed` (the scene's) and `version` (the
/// crate's).
pub fn header_strings(shot: &Shot, frame: u32, hash: u64) -> Vec<(String, String)> {
    let scene = shot.scene();
    let file = scene
        .path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    vec![
        ("scene".to_string(), file),
        ("frame".to_string(), frame.to_string()),
        ("hash".to_string(), super::hash_text(hash)),
        (
            "colorspace".to_string(),
            scene.file.output.colorspace.name().to_string(),
        ),
        ("seed".to_string(), scene.file.seed.to_string()),
        ("version".to_string(), env!("CARGO_PKG_VERSION").to_string()),
    ]
}
