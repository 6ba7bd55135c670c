"""Sequences: Shot.frames_iter and Shot.render_all render through one renderer with the shot
loop's reuse (a hold reuses the last frame, a still cloud its light grid), and their frames are
still the CLI's, bit for bit."""

from pathlib import Path

import numpy as np
import pytest

import nephele
from conftest import exr_rgba, read_exr, same_bits, tiny_scene_text


def hold_scene(tmp_path, model_path, orbit, shutter=0.0):
    """6 frames at 24 fps whose last 0.1 s hold the cloud still (frames 4 to 6)."""
    path = tmp_path / "hold.ron"
    path.write_text(tiny_scene_text(model_path, seconds=0.25, hold=0.1, orbit=orbit,
                                    shutter=shutter))
    return path


@pytest.mark.parametrize("orbit, held", [(0.0, "frame"), (20.0, "light_grid")])
def test_frames_iter_reuses_holds_and_equals_the_cli(tmp_path, duck_model, cli, orbit, held):
    _, model_path = duck_model
    scene_path = hold_scene(tmp_path, model_path, orbit)
    out = tmp_path / "cli"
    cli("render", scene_path, "--output", out)
    shot = nephele.Scene.load(scene_path).shot()
    assert shot.frames == [1, 2, 3, 4, 5, 6]
    it = shot.frames_iter()
    assert it.reuse is None and len(it) == 6 and it.frames == shot.frames
    reuse = {}
    for frame, rgba in it:
        reuse[frame] = it.reuse
        assert rgba.shape == (27, 48, 4) and rgba.dtype == np.float32
        expected = exr_rgba(read_exr(out / f"hold_{frame:04d}.exr")[0])
        assert same_bits(rgba, expected), frame
        # A frame rendered on its own has the same bits.
        assert same_bits(rgba, shot.render(frame)), frame
    assert len(it) == 0 and list(it) == []
    # The cloud grows in frames 1 to 3 and holds from frame 4 on: the held frames reuse the
    # frame before (a still camera) or its light grid (an orbiting one).
    assert reuse[1] == "buffers" and reuse[2] == "buffers"
    assert [reuse[f] for f in (5, 6)] == [held, held], reuse


def test_frames_iter_layers_a_selection_with_passes(tmp_path, duck_model, cli):
    _, model_path = duck_model
    scene_path = hold_scene(tmp_path, model_path, orbit=0.0)
    out = tmp_path / "cli"
    cli("render", scene_path, "--output", out, "--passes", "--frames", "2,5..6")
    shot = nephele.Scene.load(scene_path).shot(passes=True)
    got = list(shot.frames_iter(frames="5..6,2", layers=True))
    assert [f for f, _ in got] == [2, 5, 6]
    for frame, layers in got:
        channels, _ = read_exr(out / f"hold_{frame:04d}.exr")
        assert same_bits(layers["rgba"], exr_rgba(channels)), frame
        assert same_bits(layers["depth"], channels["Z"]), frame
        for name in ("sun", "sky", "multiple"):
            expected = np.stack([channels[f"{name}.{c}"] for c in "RGB"], axis=-1)
            assert same_bits(layers[name], expected), (frame, name)
        assert set(layers["mattes"]) >= {"names", "id", "coverage", "index"}
    # A held frame's layers are the frame before's, passes and mattes included.
    (_, five), (_, six) = got[1], got[2]
    for name in ("rgba", "depth", "sun", "sky", "multiple"):
        assert same_bits(five[name], six[name]), name
    assert same_bits(five["mattes"]["coverage"], six["mattes"]["coverage"])
    # Selections are checked against the shot.
    assert list(shot.frames_iter(frames=[3])) and len(shot.frames_iter(frames=4)) == 1
    with pytest.raises(nephele.SceneError, match=r"frames: 5\.\.7: need 1 ≤ first ≤ last ≤ 6"):
        shot.frames_iter(frames="5..7")
    with pytest.raises(ValueError, match="frames must be"):
        shot.frames_iter(frames=2.5)


def test_frames_iter_with_motion_blur_equals_the_cli(tmp_path, duck_model, cli):
    _, model_path = duck_model
    scene_path = hold_scene(tmp_path, model_path, orbit=0.0, shutter=0.5)
    out = tmp_path / "cli"
    cli("render", scene_path, "--output", out)
    it = nephele.Scene.load(scene_path).shot().frames_iter()
    reuse = []
    for frame, rgba in it:
        reuse.append(it.reuse)
        assert same_bits(rgba, exr_rgba(read_exr(out / f"hold_{frame:04d}.exr")[0])), frame
    # Blurred frames reuse nothing but memory; still ones (the hold) reuse as without blur.
    assert reuse[1] == "buffers" and reuse[-1] == "frame", reuse


def test_render_all_is_one_run_with_the_cli_files(tmp_path, duck_model, cli):
    """render_all renders a hold shot in one run; its files are the CLI's, byte for byte."""
    _, model_path = duck_model
    scene_path = hold_scene(tmp_path, model_path, orbit=0.0)
    shot = nephele.Scene.load(scene_path).shot(output=tmp_path / "py")
    on_disk = []

    def progress(report):
        # The shot can be used from the callback (no lock held), and the frames before this
        # one are on disk (this one's files are being written beside the next render).
        assert shot.frames == [1, 2, 3, 4, 5, 6]
        on_disk.append([Path(p).exists() for f in range(1, report["frame"])
                        for p in shot.frame_paths(f)])

    report = shot.render_all(progress=progress)
    assert report["rendered"] == 6 and all(all(d) for d in on_disk) and len(on_disk) == 6
    cli("render", scene_path, "--output", tmp_path / "cli")
    for frame in shot.frames:
        name = f"hold_{frame:04d}.exr"
        assert (tmp_path / "py" / name).read_bytes() == (tmp_path / "cli" / name).read_bytes()


def test_a_stopped_render_all_resumes(tmp_path, tiny_scene):
    shot = nephele.Scene.load(tiny_scene).shot(output=tmp_path / "out")

    def stop(report):
        if report["frame"] == 2:
            raise KeyboardInterrupt("stop")

    with pytest.raises(KeyboardInterrupt):
        shot.render_all(progress=stop)
    # Frames 1 and 2 are finished (files and manifests), frame 3 is not started.
    for frame in (1, 2):
        assert (tmp_path / "out" / f"tiny_{frame:04d}.manifest.json").exists()
    assert not any((tmp_path / "out").glob("tiny_0003*"))
    seen = []
    report = shot.render_all(progress=seen.append)
    assert (report["rendered"], report["skipped"]) == (1, 2)
    assert [(r["frame"], r["skipped"], r["index"], r["count"]) for r in seen] == [
        (1, True, 0, 3), (2, True, 1, 3), (3, False, 2, 3)]
