//! A shot's story (the scene file's `story`, [`crate::scene::file::story`]): every target
//! loaded (or fitted and cached) and placed — its own `transform`, then the scene's — and the
//! story planned ([`crate::animate::StoryPlan`]).
//!
//! The shot's target is the story's last one (what the last frame shows); its box, the length
//! unit of the look and the Auto camera's framing, is the union of every target's box, so the
//! camera sees each of them and the cloud's look does not change from one target to the next.

use std::path::Path;

use super::Prepared;
use super::target::{check_target_box, load_spec, load_story_target, spec_name};
use crate::animate::{self, Animation, MorphBeat, Plan, StoryPlan, blob_bounds};
use crate::blobby::BlobModel;
use crate::geometry::Aabb;
use crate::scene::file::story::times;
use crate::scene::{Scene, SceneError};

/// Load and place the story's targets (fits cached in `cache_dir`) and plan the story.
pub(super) fn plan(scene: &Scene, cache_dir: &Path) -> Result<Prepared, SceneError> {
    let file = &scene.file;
    let mut targets: Vec<BlobModel> = Vec::with_capacity(file.story.len());
    let mut origin = None;
    let mut bounds = Aabb::EMPTY;
    for (i, entry) in file.story.iter().enumerate() {
        let (mut model, from) = load_story_target(scene, i, cache_dir)?;
        entry.transform.apply(&mut model.blobs);
        file.transform.apply(&mut model.blobs);
        let b = blob_bounds(&model.blobs);
        check_target_box(scene, &b, &spec_name(&entry.target))?;
        bounds = bounds.union(b);
        targets.push(model);
        origin = Some(from);
    }
    let times = times(&file.story);
    let first = file.story[0].first_animation();
    let source = match &first {
        Animation::Morph(m) => Some(load_spec(scene, &m.from, cache_dir)?.0),
        _ => None,
    };
    let later: Vec<MorphBeat<'_>> = (1..targets.len())
        .map(|i| MorphBeat {
            target: &targets[i],
            stagger: file.story[i].stagger(),
            times: times[i],
        })
        .collect();
    let story = StoryPlan::new(
        &first,
        &targets[0],
        source.as_ref(),
        times[0],
        &later,
        file.shot.frame_count() as usize,
        file.shot.fps,
        file.seed,
    )
    .map_err(|source| SceneError::Animate {
        scene: scene.path.clone(),
        source,
    })?;
    let plan = Plan::Story(story);
    let model = targets.pop().expect("a story has at least two targets");
    let direction = animate::Direction::new(&plan, file.wind, file.timing.clone())
        .with_motion(file.transform.motion());
    let framing = super::framing(&direction, bounds, &plan.timeline());
    Ok(Prepared {
        direction,
        framing,
        model,
        plan,
        bounds,
        origin: origin.expect("a story has at least two targets"),
    })
}
