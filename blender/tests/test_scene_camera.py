"""nephele renders the Blender scene's camera (issue 50): an animated camera with a non-default
lens and sensor fit goes to nephele as a `.chan` file; nephele's frames and Cycles' render of
the imported VDBs from that same camera must put the cloud in the same place (alpha centroids
within 1 px at 160×90). A 1001-based shot. Numbers measured are printed (pytest -s).
"""

import math

import numpy as np
import pytest

bpy = pytest.importorskip("bpy", reason="the bpy wheel is not installed (blender/ci.sh installs it)")
from mathutils import Matrix, Vector  # noqa: E402

from test_blender import centroid, cone, load_rgba, nephele_bin  # noqa: E402
from nephele_blender import core  # noqa: E402

W, H = 160, 90
START = 1001
FRAMES = (START, START + 1, START + 2)


def aim(eye, target, roll_deg):
    """A camera rotation (Euler XYZ) looking from `eye` at `target`, rolled about its view."""
    q = (Vector(target) - Vector(eye)).to_track_quat("-Z", "Y")
    m = q.to_matrix() @ Matrix.Rotation(math.radians(roll_deg), 3, "Z")
    return m.to_euler("XYZ")


def keyed_camera(scene, centre):
    data = bpy.data.cameras.new("shot camera")
    data.sensor_fit = "VERTICAL"  # the height spans sensor_height (AUTO would fit the width)
    data.sensor_width, data.sensor_height = 30.0, 18.0
    cam = bpy.data.objects.new("shot camera", data)
    scene.collection.objects.link(cam)
    keys = {  # frame: (offset from the cone, aim offset, roll, lens mm)
        START: ((4.5, -5.0, 2.0), (0.3, 0.0, 0.2), 12.0, 40.0),
        START + 2: ((5.5, -3.2, 1.0), (-0.2, 0.1, -0.1), -8.0, 52.0),
    }
    for frame, (off, look, roll, lens) in keys.items():
        eye = Vector(centre) + Vector(off)
        cam.location = eye
        cam.rotation_euler = aim(eye, Vector(centre) + Vector(look), roll)
        data.lens = lens
        cam.keyframe_insert("location", frame=frame)
        cam.keyframe_insert("rotation_euler", frame=frame)
        data.keyframe_insert("lens", frame=frame)
    scene.camera = cam
    return cam


@pytest.fixture(scope="module")
def camera_shot(tmp_path_factory):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.frame_start, scene.frame_end = START, FRAMES[-1]
    scene.render.resolution_x, scene.render.resolution_y = W, H
    scene.render.resolution_percentage = 100
    obj = cone(location=(0.8, 1.5, 0.4), rotation=(0.5, 0.0, 0.7))
    cam = keyed_camera(scene, obj.location)
    scene.frame_set(START)
    settings = core.ShotSettings(
        blobs=40, fit_samples=5000, fit_candidates=500, animation="Diffusion",
        seconds=len(FRAMES) / 24, fps=24.0, start_frame=START, width=W, height=H,
        shutter=0.0, quality="Preview", voxels_per_diagonal=64, seed=2, extra_formats=["Exr"],
        hold_seconds=0.0)
    out = tmp_path_factory.mktemp("camera_shot")
    volume, camera, scene_path = core.make_cloud(obj, out, settings, binary=nephele_bin(),
                                                 use_module=False)  # camera_source AUTO
    obj.hide_render = True
    return obj, volume, cam, camera, out, scene_path


def test_the_scene_camera_is_what_nephele_renders(camera_shot):
    _, _, cam, camera, out, scene_path = camera_shot
    assert camera == cam == bpy.context.scene.camera
    assert not [o for o in bpy.data.objects if "nephele camera" in o.name]
    text = scene_path.read_text()
    assert 'camera: Chan((file: "Cone.chan", rotation_order: ZXY' in text, text
    lines = [l.split() for l in (out / "Cone.chan").read_text().splitlines() if not l.startswith("#")]
    assert [int(l[0]) for l in lines] == list(FRAMES)
    # VERTICAL fit: the height spans sensor_height; the lens is animated 40 → 52 mm.
    for l, frame in zip(lines, FRAMES):
        bpy.context.scene.frame_set(frame)
        assert float(l[7]) == pytest.approx(math.degrees(2 * math.atan(9.0 / cam.data.lens)), rel=1e-6)
    assert float(lines[0][7]) != pytest.approx(float(lines[-1][7]))


@pytest.mark.parametrize("fit,size", [("AUTO", (160, 90)), ("AUTO", (90, 160)),
                                      ("HORIZONTAL", (160, 90)), ("HORIZONTAL", (90, 160)),
                                      ("VERTICAL", (160, 90)), ("VERTICAL", (90, 160))])
def test_vertical_fov_is_blenders_frame(fit, size):
    """The fit rule against Blender's own camera frame (`Camera.view_frame`)."""
    scene = bpy.context.scene
    keep = scene.render.resolution_x, scene.render.resolution_y
    data = bpy.data.cameras.new("fov check")
    try:
        data.lens, data.sensor_width, data.sensor_height, data.sensor_fit = 33.0, 30.0, 18.0, fit
        scene.render.resolution_x, scene.render.resolution_y = size
        corners = data.view_frame(scene=scene)
        top = max(c.y for c in corners)
        expected = math.degrees(2 * math.atan(top / -corners[0].z))
        assert core.vertical_fov_deg(data, *size) == pytest.approx(expected, rel=1e-5)
    finally:
        scene.render.resolution_x, scene.render.resolution_y = keep
        bpy.data.cameras.remove(data)


def test_chan_rotation_is_the_camera_in_nephele_axes():
    """The `.chan` line, rebuilt as nephele reads it (ZXY: R = Ry·Rx·Rz, looking down −Z, +Y
    up), is the Blender camera's orientation turned into Y-up axes (x, z, −y)."""
    m = Matrix.Translation((1.0, 2.0, 3.0)) @ aim((1, 2, 3), (0.3, -1.0, 0.5), 17.0).to_matrix().to_4x4()
    line = core.chan_line(7, m, 30.0)
    rx, ry, rz = (math.radians(a) for a in line.rotate_deg)
    c, s = math.cos, math.sin
    Rx = np.array([[1, 0, 0], [0, c(rx), -s(rx)], [0, s(rx), c(rx)]])
    Ry = np.array([[c(ry), 0, s(ry)], [0, 1, 0], [-s(ry), 0, c(ry)]])
    Rz = np.array([[c(rz), -s(rz), 0], [s(rz), c(rz), 0], [0, 0, 1]])
    R = Ry @ Rx @ Rz
    view_b, up_b = -np.array(m.col[2][:3]), np.array(m.col[1][:3])
    assert np.allclose(R @ [0, 0, -1], core.to_nephele(view_b), atol=1e-6)
    assert np.allclose(R @ [0, 1, 0], core.to_nephele(up_b), atol=1e-6)
    assert np.allclose(line.translate, (1.0, 3.0, -2.0))


def test_cameras_nephele_cannot_render_are_clear_errors():
    scene = bpy.context.scene
    frame = scene.frame_current
    keep = scene.camera
    data = bpy.data.cameras.new("bad")
    cam = bpy.data.objects.new("bad", data)
    empty = bpy.data.objects.new("an empty", None)
    scene.collection.objects.link(cam)
    scene.collection.objects.link(empty)
    try:
        scene.camera = cam
        data.type = "ORTHO"
        with pytest.raises(ValueError, match="orthographic: nephele renders perspective"):
            core.scene_camera_chan(scene, [frame], W, H)
        data.type = "PERSP"
        data.shift_x = 0.1
        with pytest.raises(ValueError, match="lens shift"):
            core.scene_camera_chan(scene, [frame], W, H)
        data.shift_x = 0.0
        assert len(core.scene_camera_chan(scene, [frame, frame + 1], W, H)) == 2
        scene.camera = empty
        with pytest.raises(ValueError, match="'an empty' is a empty object, not a camera"):
            core.scene_camera_chan(scene, [frame], W, H)
        scene.camera = None
        with pytest.raises(ValueError, match="the scene has no camera"):
            core.scene_camera_chan(scene, [frame], W, H)
        assert scene.frame_current == frame
    finally:
        scene.camera = keep
        bpy.data.objects.remove(cam)
        bpy.data.objects.remove(empty)


def cycles_alpha(path, frame):
    scene = bpy.context.scene
    scene.frame_set(frame)
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = 16
    scene.cycles.use_denoising = False
    scene.cycles.max_bounces = 4
    scene.cycles.volume_bounces = 2
    scene.render.film_transparent = True
    scene.render.use_motion_blur = False
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.image_settings.color_mode = "RGBA"
    scene.render.filepath = str(path)
    bpy.ops.render.render(write_still=True)
    return load_rgba(path)[..., 3]


@pytest.mark.parametrize("frame", FRAMES)
def test_cycles_from_the_scene_camera_matches_nephele(camera_shot, frame, tmp_path):
    _, _, _, _, out, _ = camera_shot
    a_b = cycles_alpha(tmp_path / f"cycles_{frame}.exr", frame)
    a_n = load_rgba(out / f"Cone_{frame:04d}.exr")[..., 3]
    assert a_b.shape == a_n.shape == (H, W)
    c_b, c_n = centroid(a_b), centroid(a_n)
    d = c_b - c_n
    mb, mn = a_b > 0.2, a_n > 0.2
    iou = (mb & mn).sum() / max(1, (mb | mn).sum())
    print(f"\nscene camera, frame {frame}: alpha centroid Cycles {c_b.round(2)} nephele "
          f"{c_n.round(2)}: difference ({d[0]:+.2f}, {d[1]:+.2f}) px, |d| {np.linalg.norm(d):.2f} px; "
          f"coverage Cycles {a_b.mean():.3f} nephele {a_n.mean():.3f}; IoU(alpha>0.2) {iou:.2f}")
    # The cloud is inside the frame (a clipped cloud's centroid says little).
    for a in (a_b, a_n):
        assert a[0].max() < 0.05 and a[-1].max() < 0.05 and a[:, 0].max() < 0.05 and a[:, -1].max() < 0.05
    assert np.abs(d).max() < 1.0, d
    assert iou > 0.6, iou


def test_the_operator_renders_the_scene_camera_over_the_scene_frames(tmp_path, monkeypatch):
    """The menu's operator with its defaults: the scene's camera (AUTO, the scene has one) over
    the scene's frame range (1001-based), at the scene's render size × percentage."""
    import nephele_blender

    monkeypatch.setenv("NEPHELE_BIN", nephele_bin())
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.frame_start, scene.frame_end = START, START + 1
    scene.render.resolution_x, scene.render.resolution_y = 96, 54
    scene.render.resolution_percentage = 50
    obj = cone(location=(0.0, 0.0, 0.0), rotation=(0.0, 0.0, 0.0))
    cam = keyed_camera(scene, obj.location)
    bpy.context.view_layer.objects.active = obj
    nephele_blender.register()
    try:
        result = bpy.ops.object.nephele_cloud(output=str(tmp_path), blobs=12, voxels=32,
                                              quality="Preview", shutter=0.0)
    finally:
        nephele_blender.unregister()
    assert result == {"FINISHED"}
    assert scene.camera == cam and (scene.frame_start, scene.frame_end) == (START, START + 1)
    lines = [l.split() for l in (tmp_path / "Cone.chan").read_text().splitlines() if l[0] != "#"]
    assert [int(l[0]) for l in lines] == [START, START + 1]
    assert "width: 48, height: 27" in (tmp_path / "Cone.ron").read_text()
    assert (tmp_path / "Cone_1002.exr").is_file() and "Cone cloud" in bpy.data.objects
