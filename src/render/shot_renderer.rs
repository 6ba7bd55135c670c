//! A shot's frames rendered in order, each reusing what it can of the one before: the light
//! grid's buffers always (no few hundred megabytes allocated and zeroed a frame), the light grid
//! itself where the cloud and the sun have not changed, the whole frame in a hold (same cloud,
//! same settings: the renderer is deterministic and its jitter fixed per pixel, so the frame
//! would come out bit for bit the same).
//!
//! In: per frame, [`RenderSettings`] and the blobs. Out: the frame, as
//! [`super::render_frame`] would make it.

use super::blobs::BlobMedium;
use super::light_grid::LightGrid;
use super::{Frame, RenderSettings, render_medium};
use crate::blobby::Blob;

/// Renders frames one after another, keeping the last one's medium, light grid and frame.
#[derive(Debug, Default)]
pub struct ShotRenderer {
    last: Option<Last>,
}

/// What the last frame left.
#[derive(Debug)]
struct Last {
    /// Its settings with `time` zeroed (time reaches the frame only through the medium).
    settings: RenderSettings,
    medium: BlobMedium,
    grid: Option<LightGrid>,
    frame: Frame,
}

/// What a frame could take from the last one.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Reuse {
    /// Nothing but buffers: the cloud or the sun changed (or the first frame).
    Buffers,
    /// The light grid: same cloud and sun, another camera or image setting.
    LightGrid,
    /// The whole frame: a hold.
    Frame,
}

impl ShotRenderer {
    /// A renderer with nothing to reuse yet.
    pub fn new() -> ShotRenderer {
        ShotRenderer::default()
    }

    /// Render the frame of `blobs` with `settings`; the result equals
    /// [`super::render_frame`]'s bit for bit.
    pub fn render(&mut self, settings: &RenderSettings, blobs: &[Blob]) -> &Frame {
        self.render_reporting(settings, blobs).0
    }

    /// [`ShotRenderer::render`], also saying what was reused.
    pub fn render_reporting(
        &mut self,
        settings: &RenderSettings,
        blobs: &[Blob],
    ) -> (&Frame, Reuse) {
        let medium = BlobMedium::new(settings, blobs);
        let mut key = settings.clone();
        key.time = 0.0;
        let same_cloud = self.last.as_ref().is_some_and(|l| l.medium == medium);
        if same_cloud && self.last.as_ref().is_some_and(|l| l.settings == key) {
            let last = self.last.as_ref().expect("checked above");
            return (&last.frame, Reuse::Frame);
        }
        let (grid, reuse) = match self.last.take() {
            Some(l)
                if same_cloud
                    && l.settings.sun == settings.sun
                    && l.settings.light_grid_cells(medium.bounds())
                        == settings.light_grid_cells(medium.bounds()) =>
            {
                (l.grid, Reuse::LightGrid)
            }
            Some(l) => (
                LightGrid::for_frame_reusing(settings, &medium.for_light_grid(settings), l.grid),
                Reuse::Buffers,
            ),
            None => (
                LightGrid::for_frame(settings, &medium.for_light_grid(settings)),
                Reuse::Buffers,
            ),
        };
        let frame = render_medium(settings, &medium, &grid);
        let last = self.last.insert(Last {
            settings: key,
            medium,
            grid,
            frame,
        });
        (&last.frame, reuse)
    }
}
