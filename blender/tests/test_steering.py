"""The add-on steers the shot (issue 51): a diffusion that starts at the 3D cursor, and a timing
curve keyed on the object's `nephele_progress` property. Real `bpy` and the nephele CLI (run by
blender/ci.sh, NEPHELE_BIN = the CLI); the measured numbers are printed (pytest -s).
"""

import re
import sys
from pathlib import Path

import numpy as np
import pytest

bpy = pytest.importorskip("bpy", reason="the bpy wheel is not installed (blender/ci.sh installs it)")

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))
from nephele_blender import core  # noqa: E402
from test_blender import W, H, cone, load_rgba, nephele_bin  # noqa: E402

FRAMES = 8


def settings(**kw):
    return core.ShotSettings(
        blobs=40, fit_samples=5000, fit_candidates=500, animation="Diffusion",
        seconds=FRAMES / 8, fps=8.0, start_frame=1, width=W, height=H, shutter=0.0,
        quality="Preview", voxels_per_diagonal=48, seed=2, extra_formats=["Exr"],
        hold_seconds=0.0, **kw)


def alpha(out, name, frame):
    return load_rgba(out / f"{name}_{frame:04d}.exr")[:, :, 3]


def row_centroid(a):
    ys = np.mgrid[0:a.shape[0], 0:a.shape[1]][0]
    assert a.sum() > 0.05, "no cloud in the frame"
    return float((ys * a).sum() / a.sum())


@pytest.fixture(scope="module")
def steered(tmp_path_factory):
    """Two shots of an upright cone: one starting at the 3D cursor near its apex, one near its
    base; the apex shot also retimed by a keyed `nephele_progress` (0 at frame 1, 1 at frame 3,
    held after)."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.fps, scene.render.fps_base = 8, 1.0
    obj = cone(location=(0.0, 0.0, 0.0), rotation=(0.0, 0.0, 0.0))
    obj[core.TIMING_PROPERTY] = 0.0
    obj.keyframe_insert(f'["{core.TIMING_PROPERTY}"]', frame=1)
    obj[core.TIMING_PROPERTY] = 1.0
    obj.keyframe_insert(f'["{core.TIMING_PROPERTY}"]', frame=3)
    shots = {}
    for name, z in (("apex", 0.6), ("base", -0.7)):
        scene.cursor.location = (0.0, 0.0, z)
        frames = core.shot_frames(settings())
        timing = core.timing_from_property(obj, scene, frames, 8.0) if name == "apex" else None
        s = settings(start=core.start_from_cursor(scene), timing=timing)
        out = tmp_path_factory.mktemp(name)
        _, _, scene_path = core.make_cloud(obj, out, s, binary=nephele_bin(), use_module=False,
                                           camera_source="NEPHELE", with_camera=False)
        shots[name] = (out, scene_path, timing)
    return obj, shots


def test_the_cursor_is_the_start_and_the_cloud_starts_there(steered):
    obj, shots = steered
    text = shots["apex"][1].read_text()
    # Blender (0, 0, 0.6) is nephele (0, 0.6, 0): Z up turned to Y up.
    assert "start: (0.0, 0.6000000238418579, " in text or "start: (0.0, 0.6, " in text, text
    name = bpy.path.clean_name(obj.name)
    apex = row_centroid(alpha(shots["apex"][0], name, 1))
    base = row_centroid(alpha(shots["base"][0], name, 1))
    print(f"first frame's alpha centroid row: start at the apex {apex:.2f}, at the base {base:.2f} (of {H})")
    # The image's up is nephele's +Y: the apex start is higher in the frame (a smaller row).
    assert apex < base - 2.0


def test_the_keyed_progress_is_the_shots_timing(steered):
    obj, shots = steered
    out, scene_path, timing = shots["apex"]
    assert [round(t, 6) for t, _, _ in timing] == [round(k / 8, 6) for k in range(FRAMES)]
    progress = [p for _, p, _ in timing]
    assert progress[0] == 0.0 and progress[2] == pytest.approx(1.0) and 0.0 < progress[1] < 1.0
    assert all(p == pytest.approx(1.0) for p in progress[2:])
    text = scene_path.read_text()
    assert re.search(r"timing: \[\(time: 0\.0, progress: 0\.0, ease: Linear\), ", text), text
    # Formed by frame 3 (progress 1), where the untimed shot is still growing.
    name = bpy.path.clean_name(obj.name)
    timed = alpha(out, name, 3).sum() / alpha(out, name, FRAMES).sum()
    plain = alpha(shots["base"][0], name, 3).sum() / alpha(shots["base"][0], name, FRAMES).sum()
    print(f"frame 3 coverage over the last frame's: timed {timed:.3f}, untimed {plain:.3f}")
    assert timed > 0.9 and plain < timed - 0.1


def test_a_progress_outside_0_1_is_refused_naming_the_frame(steered):
    obj, _ = steered
    scene = bpy.context.scene
    obj[core.TIMING_PROPERTY] = 1.5
    obj.keyframe_insert(f'["{core.TIMING_PROPERTY}"]', frame=5)
    with pytest.raises(ValueError, match=r"frame [45]: "):
        core.timing_from_property(obj, scene, list(range(1, FRAMES + 1)), 8.0)
