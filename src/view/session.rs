//! The view's state: the scene as last loaded well (a [`Generation`]) and the one before it (the
//! A/B's "before the last save"), the error of a bad edit, the frames rendered so far and their
//! statistics, and the page's event stream ([`Hub`]).
//!
//! A save loads the scene again ([`Session::reload`]): when it loads and its target and plan
//! are made, it becomes the new generation (frames are rendered anew, on demand); when not, its
//! error (`file:line:column: field: message` where the scene text locates it) is shown and the
//! last good generation stays. Frames render one at a time (each uses every core), through the
//! same calls as `nephele render` ([`Shot::render_frame`]).

use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, OnceLock, mpsc};
use std::time::Instant;

use serde_json::{Value, json};

use crate::render::{Frame, RenderSettings};
use crate::scene::file::overrides::Override;
use crate::scene::stats::StatsBasis;
use crate::scene::{self, RenderOptions, Scene, Shot};

/// The two sizes a frame is rendered at.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Level {
    /// `render --preview`'s: a quarter of the width (at least 64 px), preview quality.
    Preview,
    /// The scene's size and quality.
    Final,
}

impl Level {
    /// The level named in a request (`preview`, `final`).
    pub fn parse(s: &str) -> Option<Level> {
        match s {
            "preview" => Some(Level::Preview),
            "final" => Some(Level::Final),
            _ => None,
        }
    }
}

/// A rendered frame with what its pictures need, and its encoded pictures so far.
#[derive(Debug)]
pub struct Rendered {
    /// The frame as the renderer made it.
    pub frame: Frame,
    /// The settings it was rendered with (the beauty's camera, sky and exposure).
    pub settings: RenderSettings,
    /// Wall seconds of its render.
    pub seconds: f64,
    /// Encoded pictures by layer and exposure (a few; cleared when it grows).
    pngs: Mutex<HashMap<String, Arc<Vec<u8>>>>,
}

impl Rendered {
    /// The PNG of `layer` at exposure offset `ev` (encoded once, then from memory).
    pub fn png(&self, layer: super::layers::Layer, ev: f32) -> Result<Arc<Vec<u8>>, String> {
        let key = format!("{layer:?}/{}", ev.to_bits());
        if let Some(p) = self.pngs.lock().unwrap().get(&key) {
            return Ok(p.clone());
        }
        let png = Arc::new(super::layers::png(self, layer, ev)?);
        let mut pngs = self.pngs.lock().unwrap();
        if pngs.len() >= 8 {
            pngs.clear();
        }
        pngs.insert(key, png.clone());
        Ok(png)
    }
}

/// One frame's statistics as the page plots them.
#[derive(Clone, Copy, Debug, serde::Serialize)]
pub struct FrameStat {
    /// Frame number.
    pub frame: u32,
    /// Visible volume over the last frame's.
    pub volume_fraction: f64,
    /// 3D pieces (6-connected components of the solid).
    pub pieces: usize,
    /// Share of the picture's pixels the cloud covers (alpha > 0.05).
    pub coverage: f64,
    /// Wall seconds of the preview render.
    pub render_s: f64,
}

/// Candidate seeds of a draft fit (at most).
pub const DRAFT_CANDIDATES: usize = 400;

/// Surface samples of a draft fit (at most).
pub const DRAFT_SAMPLES: usize = 20_000;

/// How many `Final` (or passes) frames a generation keeps.
pub const KEPT_LARGE: usize = 8;

/// Frames are cached by number, level and whether they carry the passes.
type FrameKey = (u32, Level, bool);

/// The scene as loaded well once: its shots (opened on first need) and rendered frames.
#[derive(Debug)]
pub struct Generation {
    /// Its number in this session (1, 2, … one a good save, and one a draft).
    pub id: u64,
    /// True when its target is a draft fit ([`Session::draft`]), shown while the fit runs.
    pub draft: bool,
    /// The scene.
    pub scene: Scene,
    /// The files it reads (the scene file first): what the watcher watches.
    pub watched: Vec<PathBuf>,
    cache: PathBuf,
    shots: Mutex<HashMap<(Level, bool), Arc<Shot>>>,
    frames: Mutex<HashMap<FrameKey, Arc<Rendered>>>,
    /// The cached `Final` and passes frames, oldest first.
    large: Mutex<std::collections::VecDeque<FrameKey>>,
    stats: Mutex<BTreeMap<u32, FrameStat>>,
    basis: OnceLock<Option<StatsBasis>>,
}

impl Generation {
    /// The shot at `level`, with or without the passes (opened once; its fits are cached in the
    /// view's folder, never the output folder).
    pub fn shot(&self, level: Level, passes: bool) -> Result<Arc<Shot>, String> {
        let mut shots = self.shots.lock().unwrap();
        if let Some(s) = shots.get(&(level, passes)) {
            return Ok(s.clone());
        }
        let options = RenderOptions {
            output: Some(self.cache.clone()),
            preview: level == Level::Preview,
            passes,
            ..RenderOptions::default()
        };
        let shot = Arc::new(Shot::open(self.scene.clone(), &options).map_err(|e| message(&e))?);
        shots.insert((level, passes), shot.clone());
        Ok(shot)
    }

    /// The first and last frame numbers of the shot.
    pub fn range(&self) -> (u32, u32) {
        let s = &self.scene.file.shot;
        (s.start_frame, s.last_frame())
    }

    /// What the page needs to know of it.
    pub fn info(&self) -> Value {
        let (start, last) = self.range();
        let size = |level| self.shot(level, false).map(|s| s.size()).ok();
        json!({
            "id": self.id,
            "draft": self.draft,
            "name": self.scene.name,
            "start": start,
            "last": last,
            "fps": self.scene.file.shot.fps,
            "preview": size(Level::Preview),
            "final": size(Level::Final),
            "output": self.scene.output_dir,
        })
    }

    /// The frame statistics gathered so far, by frame.
    pub fn stats(&self) -> Vec<FrameStat> {
        self.stats.lock().unwrap().values().copied().collect()
    }

    /// The frames cached at `level` (without the passes).
    pub fn cached_frames(&self, level: Level) -> Vec<u32> {
        let mut v: Vec<u32> = self
            .frames
            .lock()
            .unwrap()
            .keys()
            .filter(|k| k.1 == level && !k.2)
            .map(|k| k.0)
            .collect();
        v.sort_unstable();
        v
    }

    /// Cache `rendered` under `key`. The preview frames are all kept (the flipbook); of the
    /// `Final` frames and those with the passes only the last [`KEPT_LARGE`] (a 1080p frame
    /// holds 40 MB of floats: a whole shot of them would not fit in memory).
    fn keep(&self, key: FrameKey, rendered: Arc<Rendered>) {
        let mut frames = self.frames.lock().unwrap();
        if key.1 == Level::Final || key.2 {
            let mut large = self.large.lock().unwrap();
            large.push_back(key);
            while large.len() > KEPT_LARGE {
                if let Some(old) = large.pop_front() {
                    frames.remove(&old);
                }
            }
        }
        frames.insert(key, rendered);
    }

    fn cached(&self, key: FrameKey) -> Option<Arc<Rendered>> {
        self.frames.lock().unwrap().get(&key).cloned()
    }
}

/// The page's event stream: every subscriber gets each event's JSON text.
#[derive(Debug, Default)]
pub struct Hub {
    subscribers: Mutex<Vec<mpsc::Sender<String>>>,
}

impl Hub {
    /// A new subscriber's receiving end.
    pub fn subscribe(&self) -> mpsc::Receiver<String> {
        let (tx, rx) = mpsc::channel();
        self.subscribers.lock().unwrap().push(tx);
        rx
    }

    /// Send `event` to every subscriber (those gone are dropped).
    pub fn send(&self, event: &Value) {
        let text = event.to_string();
        self.subscribers
            .lock()
            .unwrap()
            .retain(|s| s.send(text.clone()).is_ok());
    }
}

#[derive(Debug, Default)]
struct State {
    current: Option<Arc<Generation>>,
    previous: Option<Arc<Generation>>,
    error: Option<String>,
    loading: bool,
    next_id: u64,
    /// Files to watch: the last attempt's (the scene file and what the last good one read).
    watched: Vec<PathBuf>,
    /// The "render the shot" job's last word.
    shot_render: Option<Value>,
}

/// The view's session (see the module doc).
#[derive(Debug)]
pub struct Session {
    /// The scene file, fixed at start.
    pub scene_path: PathBuf,
    /// The command line's `--set`/`--size` overrides, applied at every load.
    pub overrides: Vec<Override>,
    /// The view's fit cache folder.
    pub cache: PathBuf,
    /// Distinguishes this session's picture URLs from another's on the same port.
    pub nonce: u64,
    state: Mutex<State>,
    render: Mutex<()>,
    /// The frame the page asked for last (a draft renders it before the fit runs).
    last_frame: Mutex<Option<u32>>,
    /// The page's event stream.
    pub hub: Hub,
}

/// A scene error as one line (`file:line:column: field: message` where located).
fn message(e: &scene::SceneError) -> String {
    crate::error_chain::message(e)
}

impl Session {
    /// A session on `scene_path` with fits cached in `cache`; nothing is loaded yet (the
    /// watcher's first [`Session::reload`] does).
    pub fn start(scene_path: PathBuf, cache: PathBuf, overrides: Vec<Override>) -> Arc<Session> {
        let nonce = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_nanos() as u64 & 0xffff_ffff_ffff);
        Arc::new(Session {
            state: Mutex::new(State {
                loading: true,
                watched: vec![scene_path.clone()],
                next_id: 1,
                ..State::default()
            }),
            scene_path,
            cache,
            overrides,
            nonce,
            render: Mutex::new(()),
            last_frame: Mutex::new(None),
            hub: Hub::default(),
        })
    }

    /// The files the watcher watches now.
    pub fn watched(&self) -> Vec<PathBuf> {
        self.state.lock().unwrap().watched.clone()
    }

    /// The generation numbered `id`, if it is the current or the one before.
    pub fn generation(&self, id: u64) -> Option<Arc<Generation>> {
        let s = self.state.lock().unwrap();
        [&s.current, &s.previous]
            .into_iter()
            .flatten()
            .find(|g| g.id == id)
            .cloned()
    }

    /// The state as the page reads it (also the event stream's first event).
    pub fn snapshot(&self) -> Value {
        let s = self.state.lock().unwrap();
        json!({
            "type": "state",
            "session": format!("{:x}", self.nonce),
            "scene": self.scene_path,
            "loading": s.loading,
            "error": s.error,
            "current": s.current.as_ref().map(|g| g.info()),
            "previous": s.previous.as_ref().map(|g| g.id),
            "shot_render": s.shot_render,
        })
    }

    /// Load the scene again (a save): a new generation, or its error with the last good one
    /// kept. Tells the page either way. A target to be fitted anew is first shown from a
    /// draft fit ([`Session::draft`]), then from its fit.
    pub fn reload(&self) {
        {
            self.state.lock().unwrap().loading = true;
        }
        self.hub.send(&json!({"type": "loading"}));
        let started = Instant::now();
        let scene = match scene::load_scene_with(&self.scene_path, &self.overrides) {
            Ok(scene) => scene,
            Err(e) => return self.publish(Err(message(&e)), started),
        };
        seed_cache(&scene.output_dir, &self.cache);
        let watched = referenced_files(&scene);
        if let Some(draft) = self.draft(&scene)
            && let Ok(generation) = self.open_generation(draft, watched.clone(), true)
        {
            self.publish(Ok(generation), started);
            // The page's frame of the draft, before the fit takes the cores.
            let current = self.state.lock().unwrap().current.clone();
            let frame = *self.last_frame.lock().unwrap();
            if let (Some(g), Some(f)) = (current, frame) {
                let f = f.clamp(g.range().0, g.range().1);
                let _ = self.frame(&g, f, Level::Preview, false);
            }
        }
        let generation = self.open_generation(scene, watched, false);
        self.publish(generation, started);
    }

    /// Make `loaded` the page's state (a generation, or an error keeping the last good one)
    /// and tell the page.
    fn publish(&self, loaded: Result<Generation, String>, started: Instant) {
        {
            let mut s = self.state.lock().unwrap();
            let drafted = s.current.as_ref().is_some_and(|g| g.draft);
            match loaded {
                Ok(generation) => {
                    s.loading = generation.draft;
                    s.watched = generation.watched.clone();
                    // A/B compares with the picture before the save, never with a draft.
                    if !drafted {
                        s.previous = s.current.take();
                    }
                    s.current = Some(Arc::new(generation));
                    s.error = None;
                }
                Err(e) => {
                    s.loading = false;
                    if drafted {
                        s.current = s.previous.clone();
                    }
                    // Keep watching what the last good scene read (a fix may be there).
                    let mut watched = vec![self.scene_path.clone()];
                    if let Some(g) = &s.current {
                        watched.extend(g.watched.iter().skip(1).cloned());
                    }
                    s.watched = watched;
                    s.error = Some(e);
                }
            }
        }
        let mut event = self.snapshot();
        event["load_s"] = json!(started.elapsed().as_secs_f64());
        self.hub.send(&event);
    }

    /// `scene` with a draft fit as its target when its target is a fit not yet cached: fewer
    /// candidates and samples ([`DRAFT_CANDIDATES`], [`DRAFT_SAMPLES`]) and the faithful
    /// optimisation only — a tenth of the fit's time — saved in the view's cache as
    /// `draft-<the fit's cache name>`. `None` when there is nothing to draft (or the draft
    /// fails: the fit then says why).
    fn draft(&self, scene: &Scene) -> Option<Scene> {
        use crate::scene::target::{fit_config, target_cache_file};
        // A deforming target's rest frame is not a mesh file to draft from: its fit only.
        if scene.deforming.is_some() {
            return None;
        }
        // A story's targets are fitted by its own run: no draft.
        let spec = scene.file.target.as_ref()?;
        let cfg = fit_config(spec)?;
        let scene::Target::Fit { mesh, .. } = spec else {
            return None;
        };
        let file = target_cache_file(scene, &self.cache).ok()??;
        if file.exists() {
            return None;
        }
        let draft = self
            .cache
            .join(format!("draft-{}", file.file_name()?.to_string_lossy()));
        if crate::blobby::load_model(&draft).is_err() {
            let draft_cfg = crate::pipeline::FitConfig {
                candidates: cfg.candidates.min(DRAFT_CANDIDATES),
                samples: cfg.samples.min(DRAFT_SAMPLES),
                optimisation: crate::pipeline::Optimisation::Faithful(Default::default()),
                ..cfg
            };
            let loaded = crate::mesh::load(mesh).ok()?;
            let _one = self.render.lock().unwrap();
            let fitted = crate::pipeline::fit(&draft_cfg, &loaded).ok()?;
            crate::blobby::save_model(&draft, &fitted.model).ok()?;
        }
        let mut drafted = scene.clone();
        drafted.file.target = Some(scene::Target::Model(draft.to_string_lossy().into_owned()));
        Some(drafted)
    }

    /// A generation of `scene` (reading `watched`): its preview shot opened and its target
    /// and plan made (a fit when the target needs one), or the error as one line.
    fn open_generation(
        &self,
        scene: Scene,
        watched: Vec<PathBuf>,
        draft: bool,
    ) -> Result<Generation, String> {
        let id = {
            let mut s = self.state.lock().unwrap();
            s.next_id += 1;
            s.next_id - 1
        };
        let generation = Generation {
            id,
            draft,
            watched,
            scene,
            cache: self.cache.clone(),
            shots: Mutex::default(),
            frames: Mutex::default(),
            large: Mutex::default(),
            stats: Mutex::default(),
            basis: OnceLock::new(),
        };
        let shot = generation.shot(Level::Preview, false)?;
        // Not under the render lock: while a fit runs, the draft's pictures still come.
        shot.prepared().map_err(|e| message(&e))?;
        Ok(generation)
    }

    /// Frame number `frame` of `generation` at `level` (with the passes when `passes`): from
    /// the cache, or rendered now (one render at a time). A preview frame's statistics are
    /// added to the generation's.
    pub fn frame(
        &self,
        generation: &Generation,
        frame: u32,
        level: Level,
        passes: bool,
    ) -> Result<Arc<Rendered>, String> {
        let (start, last) = generation.range();
        if !(start..=last).contains(&frame) {
            return Err(format!(
                "frame {frame} is outside the shot ({start}..{last})"
            ));
        }
        *self.last_frame.lock().unwrap() = Some(frame);
        let key = (frame, level, passes);
        if let Some(r) = generation.cached(key) {
            return Ok(r);
        }
        let shot = generation.shot(level, passes)?;
        let rendered = {
            // One render at a time; a frame another request renders meanwhile is taken from
            // the cache as soon as it is there (a lock's waiter may not be woken next).
            let _one = loop {
                if let Some(r) = generation.cached(key) {
                    return Ok(r);
                }
                match self.render.try_lock() {
                    Ok(one) => break one,
                    Err(_) => std::thread::sleep(std::time::Duration::from_millis(2)),
                }
            };
            let k = shot.index(frame);
            let started = Instant::now();
            let image = shot.render_frame(k).map_err(|e| message(&e))?;
            let seconds = started.elapsed().as_secs_f64();
            let settings = shot.settings(k).map_err(|e| message(&e))?;
            // A diffusion's blend path, made by this frame, for the next generation's plan.
            let _ = shot.cache_blend_path();
            let rendered = Arc::new(Rendered {
                frame: image,
                settings,
                seconds,
                pngs: Mutex::default(),
            });
            generation.keep(key, rendered.clone());
            rendered
        };
        Ok(rendered)
    }

    /// Add a preview frame's statistics to `generation`'s (after its picture is sent: the
    /// lattice's volume is not on the way to the picture) and tell the page.
    pub fn add_stats(&self, generation: &Generation, frame: u32, rendered: &Rendered) {
        if generation.stats.lock().unwrap().contains_key(&frame) {
            return;
        }
        let Ok(shot) = generation.shot(Level::Preview, false) else {
            return;
        };
        let basis = generation.basis.get_or_init(|| StatsBasis::new(&shot).ok());
        let (Some(basis), Ok(blobs)) = (basis, shot.blobs(shot.index(frame))) else {
            return;
        };
        let s = basis.frame(frame, &blobs, Some(&rendered.frame));
        let stat = FrameStat {
            frame,
            volume_fraction: s.volume_fraction,
            pieces: s.volume.components,
            coverage: s.coverage.map_or(0.0, |c| c.fraction),
            render_s: rendered.seconds,
        };
        generation.stats.lock().unwrap().insert(frame, stat);
        self.hub
            .send(&json!({"type": "stats", "generation": generation.id, "stat": stat}));
    }

    /// Start rendering the whole shot into its output folder (the page's "render the shot"),
    /// as `nephele render SCENE` does, on a thread of its own; progress goes to the page.
    /// Refused while one runs or when the scene does not load.
    pub fn render_shot(self: &Arc<Self>) -> Result<(), String> {
        let scene = {
            let mut s = self.state.lock().unwrap();
            if s.shot_render
                .as_ref()
                .is_some_and(|r| r["running"] == json!(true))
            {
                return Err("the shot is already rendering".into());
            }
            let Some(g) = &s.current else {
                return Err("the scene does not load".into());
            };
            let scene = g.scene.clone();
            s.shot_render = Some(json!({"running": true, "done": 0}));
            scene
        };
        let session = self.clone();
        std::thread::spawn(move || {
            let report = |v: Value| {
                session.state.lock().unwrap().shot_render = Some(v.clone());
                let mut event = v;
                event["type"] = json!("shot_render");
                session.hub.send(&event);
            };
            let mut done = 0u32;
            let result = Shot::open(scene, &RenderOptions::default()).and_then(|shot| {
                let total = shot.frames().len();
                shot.run(&mut |f| {
                    done += 1;
                    report(
                        json!({"running": true, "done": done, "total": total, "frame": f.frame}),
                    );
                })
            });
            match result {
                Ok(r) => report(json!({
                    "running": false, "done": done, "rendered": r.rendered,
                    "skipped": r.skipped, "dir": r.output_dir,
                })),
                Err(e) => report(json!({"running": false, "done": done, "error": message(&e)})),
            }
        });
        Ok(())
    }
}

/// The files `scene` reads, the scene file first: the target's and a morph's source mesh or
/// model, the camera's file, the sky's map and the holdouts' meshes (`builtin:` ones are none).
/// A target that is a mesh sequence (`walk_####.obj`) is watched as each of its frame files
/// and their folder (a frame added, removed or renamed over changes the folder's stamp).
pub fn referenced_files(scene: &Scene) -> Vec<PathBuf> {
    let f = &scene.file;
    let base = scene.path.parent().unwrap_or(Path::new(""));
    let mut files = vec![scene.path.clone()];
    let mut add = |p: &str, resolved: bool| {
        if p.is_empty() || p.starts_with("builtin:") {
            return;
        }
        let path = if resolved {
            PathBuf::from(p)
        } else {
            base.join(p)
        };
        if !files.contains(&path) {
            files.push(path);
        }
    };
    let target = |t: &scene::Target| match t {
        scene::Target::Model(p) => p.clone(),
        scene::Target::Fit { mesh, .. } => mesh.clone(),
    };
    if let Some(t) = &f.target {
        let mesh = target(t);
        if crate::mesh::sequence::is_pattern(&mesh) {
            // A pattern names no file: its frames (as the loader found them) and its folder.
            let pattern = base.join(&mesh);
            if let Some(dir) = pattern.parent() {
                add(&dir.to_string_lossy(), true);
            }
            for (_, file) in
                crate::mesh::sequence::frame_files(&pattern.to_string_lossy()).unwrap_or_default()
            {
                add(&file.to_string_lossy(), true);
            }
        } else {
            add(&mesh, true);
        }
    }
    if let crate::animate::Animation::Morph(m) = &f.animation {
        add(&target(&m.from), true);
    }
    // A story's targets (and a first morph's source) are read as well.
    for entry in &f.story {
        add(&target(&entry.target), true);
        if let Some(crate::animate::Animation::Morph(m)) = &entry.animation {
            add(&target(&m.from), true);
        }
    }
    match &f.camera {
        scene::CameraSpec::Chan(c) => add(&c.file, true),
        scene::CameraSpec::Usd(c) => add(&c.file, true),
        _ => {}
    }
    if let crate::render::Sky::Environment(env) = &f.sky {
        add(&env.file, true);
    }
    for h in &f.holdouts {
        add(&h.mesh, false);
    }
    files
}

/// Copy the fits and blend paths cached in the shot's output folder into the view's cache
/// (read only there: the view writes nothing into the output folder). Their names carry their
/// key, so a file under a name is the same wherever it is.
fn seed_cache(output: &Path, cache: &Path) {
    let Ok(entries) = std::fs::read_dir(output) else {
        return;
    };
    for entry in entries.flatten() {
        let name = entry.file_name();
        let text = name.to_string_lossy();
        let cached =
            (text.starts_with("target-") || text.starts_with("blend-")) && text.ends_with(".ron");
        let to = cache.join(&name);
        if cached && !to.exists() {
            // Through a temporary name: a view started beside this one never reads half a file.
            let tmp = cache.join(format!(".{text}.{}.tmp", std::process::id()));
            if std::fs::copy(entry.path(), &tmp).is_ok() {
                let _ = std::fs::rename(&tmp, &to);
            }
            let _ = std::fs::remove_file(&tmp);
        }
    }
}
