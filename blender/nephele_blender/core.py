"""The add-on's work, usable without its UI: export a mesh, write a nephele scene, render it
(the `nephele` CLI or the `nephele` Python module), and bring the VDB frames back as a Volume.

Axes: nephele is Y-up, Blender Z-up. A Blender point (x, y, z) is written to nephele as
(x, z, -y) (`to_nephele`); nephele's grids come back under an object rotated +90° about X, which
maps nephele (x, y, z) to Blender (x, -z, y), so the cloud sits where the mesh was. Velocities
(grid `vel`, world units per second in nephele's axes) turn with the object like the density.
The scene's camera goes to nephele the same way (`scene_camera_chan`): its world matrix turned
by the same axis change, written as a Nuke `.chan` file the scene file names
(`camera: Chan((file: ...))`).
"""

from __future__ import annotations

import math
import os
import shutil
import struct
import subprocess
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Callable, Dict, List, Optional, Sequence, Tuple

Vec = Tuple[float, float, float]


def to_nephele(v: Sequence[float]) -> Vec:
    """A Blender (Z-up) point or direction in nephele's axes (Y-up)."""
    return (v[0], v[2], -v[1])


def to_blender(v: Sequence[float]) -> Vec:
    """A nephele (Y-up) point or direction in Blender's axes (Z-up)."""
    return (v[0], -v[2], v[1])


#: Euler XYZ rotation (radians) of the Volume object holding nephele's grids.
VOLUME_ROTATION = (math.pi / 2, 0.0, 0.0)

#: The rotation matrix of `to_nephele` (rows): nephele = AXES · Blender. The Volume's rotation
#: (+90° about X) is its inverse, so a camera turned by it sees the cloud where Blender does.
AXES = ((1.0, 0.0, 0.0), (0.0, 0.0, 1.0), (0.0, -1.0, 0.0))

#: The `.chan` rotation order the add-on writes (Nuke's default for cameras; Z first).
CHAN_ROTATION_ORDER = "ZXY"


@dataclass
class ShotSettings:
    """What the nephele scene file says (see the repository's scenes/README.md)."""

    blobs: int = 300
    animation: str = "Diffusion"  # or "Aggregation"
    seconds: float = 4.0
    fps: float = 24.0
    start_frame: int = 1
    width: int = 640
    height: int = 360
    shutter: float = 0.5
    quality: str = "Final"  # Preview, Final, Production or Reference (the scene file's `quality`)
    voxels_per_diagonal: int = 256
    seed: int = 1
    fit_samples: Optional[int] = None
    fit_candidates: Optional[int] = None
    camera: str = "Auto((azimuth_deg: 30.0, elevation_deg: 15.0, distance: 1.0, fov_deg: 35.0))"
    extra_formats: List[str] = field(default_factory=lambda: ["Exr"])
    #: the animation's still target at the end (nephele's default 0.5 s when None); a shot
    #: shorter than this is all hold: every frame the same and `vel` zero.
    hold_seconds: Optional[float] = None
    #: where a diffusion starts (`animation: Diffusion((start: ...))`), in nephele's axes: the
    #: first blob shown is the one nearest this point (`start_from_cursor` gives the 3D cursor).
    start: Optional[Vec] = None
    #: the retime curve (`timing: [...]`): (seconds from the first frame, progress in [0, 1],
    #: "Linear" or "Smooth") keys (`timing_from_property` samples an animated property).
    timing: Optional[List[Tuple[float, float, str]]] = None


#: The custom property whose animation is the shot's timing curve: key `nephele_progress` on
#: the mesh object (0 = the scheme's first pose, 1 = the target formed) in the Graph Editor.
TIMING_PROPERTY = "nephele_progress"


def start_from_cursor(scene) -> Vec:
    """The 3D cursor in nephele's axes: where a diffusion starts."""
    return to_nephele(tuple(scene.cursor.location))


def timing_from_property(obj, scene, frames: Sequence[int], fps: float) -> Optional[List[Tuple[float, float, str]]]:
    """The timing curve keyed on `obj[TIMING_PROPERTY]`, read at every shot frame (so any
    interpolation, easing or modifier of its F-curve counts) as linear `timing` keys; None when
    the object has no such property. ValueError (naming the frame) for a progress outside
    [0, 1]. Restores the current frame."""
    if TIMING_PROPERTY not in obj.keys():
        return None
    current = scene.frame_current
    keys = []
    try:
        for frame in frames:
            scene.frame_set(frame)
            p = float(obj[TIMING_PROPERTY])
            if not (0.0 <= p <= 1.0):
                raise ValueError(f"frame {frame}: {obj.name}[{TIMING_PROPERTY!r}] is {p}; the "
                                 "progress is a fraction of the motion in [0, 1]")
            keys.append(((frame - frames[0]) / fps, p, "Linear"))
    finally:
        scene.frame_set(current)
    if len(keys) == 1:
        keys.append((keys[0][0] + 1.0 / fps, keys[0][1], "Linear"))
    return keys


# --- mesh export (no operator: works in background mode and any context) -------------------

def write_obj(path: Path, vertices: Sequence[Vec], triangles: Sequence[Tuple[int, int, int]]) -> None:
    """A triangle mesh as OBJ, vertices already in nephele's axes."""
    with open(path, "w", encoding="utf-8") as f:
        f.write("# written by the nephele Blender add-on (Y-up)\n")
        for v in vertices:
            f.write(f"v {v[0]:.9g} {v[1]:.9g} {v[2]:.9g}\n")
        for t in triangles:
            f.write(f"f {t[0] + 1} {t[1] + 1} {t[2] + 1}\n")


def export_object(obj, path: Path, depsgraph=None) -> Tuple[Vec, Vec]:
    """Write `obj`'s evaluated mesh (modifiers applied) in world space, nephele axes, as OBJ.
    Returns its bounding box in nephele's axes."""
    import bpy  # noqa: F401  (only inside Blender)

    if depsgraph is None:
        import bpy

        depsgraph = bpy.context.evaluated_depsgraph_get()
    evaluated = obj.evaluated_get(depsgraph)
    mesh = evaluated.to_mesh()
    try:
        mesh.calc_loop_triangles()
        world = obj.matrix_world
        verts = [to_nephele(world @ v.co) for v in mesh.vertices]
        tris = [tuple(t.vertices) for t in mesh.loop_triangles]
    finally:
        evaluated.to_mesh_clear()
    if not tris:
        raise ValueError(f"{obj.name}: the mesh has no faces to fit")
    write_obj(path, verts, tris)
    lo = tuple(min(v[i] for v in verts) for i in range(3))
    hi = tuple(max(v[i] for v in verts) for i in range(3))
    return lo, hi


def scene_text(mesh_file: str, out_dir: Path, name: str, s: ShotSettings, diagonal: float) -> str:
    """A nephele scene (RON) fitting `mesh_file` (relative to the scene file) and writing VDB
    (and EXR) frames to `out_dir`."""
    voxel = diagonal / max(16, s.voxels_per_diagonal)
    fit = f'Fit(mesh: "{mesh_file}", blobs: {s.blobs}, seed: {s.seed}'
    if s.fit_samples:
        fit += f", samples: {s.fit_samples}"
    if s.fit_candidates:
        fit += f", candidates: {s.fit_candidates}"
    fit += ")"
    if s.animation not in ("Diffusion", "Aggregation"):
        raise ValueError(f"animation {s.animation!r}: Diffusion or Aggregation")
    options = [f"hold_seconds: {float(s.hold_seconds)!r}"] if s.hold_seconds is not None else []
    if s.start is not None:
        if s.animation != "Diffusion":
            raise ValueError("a start point steers a Diffusion only")
        options.append("start: ({!r}, {!r}, {!r})".format(*(float(c) for c in s.start)))
    animation = f"{s.animation}(({', '.join(options)}))"
    timing = ""
    if s.timing:
        keys = ", ".join(f"(time: {float(t)!r}, progress: {float(p)!r}, ease: {e})" for t, p, e in s.timing)
        timing = f"\n    timing: [{keys}],"
    formats = ", ".join(["Vdb", *[f for f in s.extra_formats if f != "Vdb"]])
    out = str(out_dir).replace("\\", "/").replace('"', '\\"')
    return f"""// Written by the nephele Blender add-on. Y-up: Blender's Z is nephele's Y.
Scene(
    target: {fit},
    animation: {animation},{timing}
    camera: {s.camera},
    shot: (width: {s.width}, height: {s.height}, fps: {s.fps!r}, seconds: {s.seconds!r}, shutter: {s.shutter!r}, start_frame: {s.start_frame}),
    quality: {s.quality},
    output: (dir: "{out}", name: "{name}", formats: [{formats}], voxel: {voxel!r}),
    seed: {s.seed},
)
"""


# --- rendering -----------------------------------------------------------------------------

def find_binary(preferred: str = "") -> Optional[str]:
    """The `nephele` CLI: `preferred`, else $NEPHELE_BIN, else `nephele` on PATH."""
    for candidate in (preferred, os.environ.get("NEPHELE_BIN", "")):
        if candidate and Path(candidate).is_file():
            return candidate
    return shutil.which("nephele")


def render(scene_path: Path, binary: Optional[str] = None, frames: Optional[str] = None,
           progress: Optional[Callable[[str], None]] = None, use_module: Optional[bool] = None) -> None:
    """Render the shot: with the `nephele` Python module when it can be imported (and
    `use_module` is not False), else with the CLI `binary` (see `find_binary`). Raises
    RuntimeError with nephele's own message when the render fails."""
    module = None
    if use_module is not False:
        try:
            import nephele as module  # type: ignore
        except ImportError:
            if use_module:
                raise RuntimeError("the nephele Python module is not installed in Blender's Python")
    if module is not None:
        try:
            shot = module.Scene.load(str(scene_path)).shot(frames=frames)
            shot.render_all(progress=(lambda r: progress(f"frame {r['frame']}/{r['of']}")) if progress else None)
        except module.NepheleError as e:
            raise RuntimeError(str(e)) from None
        return
    exe = find_binary(binary or "")
    if not exe:
        raise RuntimeError("no nephele binary: set its path in the add-on's preferences, or "
                           "NEPHELE_BIN, or put `nephele` on PATH (cargo build --release)")
    cmd = [exe, "render", str(scene_path)]
    if frames:
        cmd += ["--frames", frames]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if progress:
        for line in proc.stderr.splitlines():
            progress(line)
    if proc.returncode != 0:
        last = [l for l in proc.stderr.splitlines() if l.strip()]
        raise RuntimeError(last[-1] if last else f"nephele exited with {proc.returncode}")


# --- the camera from a frame's EXR header --------------------------------------------------

def exr_attributes(path: Path) -> Dict[str, Tuple[str, bytes]]:
    """The header attributes of a single-part EXR: name -> (type, raw bytes)."""
    with open(path, "rb") as f:
        data = f.read(1 << 16)
    if data[:4] != b"\x76\x2f\x31\x01":
        raise ValueError(f"{path}: not an OpenEXR file")
    pos, attrs = 8, {}
    while data[pos] != 0:
        end = data.index(b"\0", pos)
        name = data[pos:end].decode()
        tend = data.index(b"\0", end + 1)
        kind = data[end + 1:tend].decode()
        (size,) = struct.unpack_from("<i", data, tend + 1)
        start = tend + 5
        attrs[name] = (kind, data[start:start + size])
        pos = start + size
    return attrs


@dataclass
class CameraFrame:
    """nephele's camera of a frame, in nephele's axes."""

    eye: Vec
    right: Vec
    up: Vec
    forward: Vec
    tan_half_h: float
    tan_half_v: float


def camera_from_exr(path: Path) -> CameraFrame:
    """Read `worldToCamera` and `worldToNDC` (row-vector m44f; camera space +x right, +y up,
    +z forward) back into the camera's eye, axes and field of view."""
    attrs = exr_attributes(path)
    m = struct.unpack("<16f", attrs["worldToCamera"][1])
    n = struct.unpack("<16f", attrs["worldToNDC"][1])
    axis = lambda c: tuple(m[r * 4 + c] for r in range(3))  # noqa: E731
    right, up, forward = axis(0), axis(1), axis(2)
    t = m[12:15]
    eye = tuple(-(t[0] * right[i] + t[1] * up[i] + t[2] * forward[i]) for i in range(3))
    # worldToNDC = view · proj, column 0 = right·a + forward/2, column 1 = −up·b + forward/2.
    a = sum((n[r * 4 + 0] - 0.5 * forward[r]) * right[r] for r in range(3))
    b = -sum((n[r * 4 + 1] - 0.5 * forward[r]) * up[r] for r in range(3))
    return CameraFrame(eye, right, up, forward, 0.5 / a, 0.5 / b)


def blender_camera_matrix(cam: CameraFrame):
    """The Blender camera object's world matrix (it looks down its −Z, +Y up)."""
    from mathutils import Matrix

    r, u, f, e = (to_blender(v) for v in (cam.right, cam.up, cam.forward, cam.eye))
    return Matrix((
        (r[0], u[0], -f[0], e[0]),
        (r[1], u[1], -f[1], e[1]),
        (r[2], u[2], -f[2], e[2]),
        (0.0, 0.0, 0.0, 1.0),
    ))


def import_camera(exr_paths: Dict[int, Path], name: str = "nephele camera"):
    """A Blender camera keyed on each frame to nephele's camera of that frame (EXR headers)."""
    import bpy

    data = bpy.data.cameras.new(name)
    data.sensor_fit = "HORIZONTAL"
    obj = bpy.data.objects.new(name, data)
    bpy.context.scene.collection.objects.link(obj)
    for frame, path in sorted(exr_paths.items()):
        cam = camera_from_exr(path)
        obj.matrix_world = blender_camera_matrix(cam)
        data.angle = 2.0 * math.atan(cam.tan_half_h)
        if len(exr_paths) > 1:
            obj.keyframe_insert("location", frame=frame)
            obj.keyframe_insert("rotation_euler", frame=frame)
            data.keyframe_insert("lens", frame=frame)
    return obj


# --- the Blender scene's camera as a .chan file ----------------------------------------------

def render_size(scene) -> Tuple[int, int]:
    """The scene's rendered image size in pixels (resolution × percentage)."""
    r = scene.render
    pct = r.resolution_percentage / 100.0
    return max(1, int(r.resolution_x * pct)), max(1, int(r.resolution_y * pct))


def vertical_fov_deg(cam_data, width: int, height: int, pixel_aspect: float = 1.0) -> float:
    """The vertical angle of view (degrees) of Blender camera data `cam_data` rendering a
    `width`×`height` image, as Blender frames it: the sensor fit says which image side the
    sensor spans — HORIZONTAL: `sensor_width` across the width; VERTICAL: `sensor_height` across
    the height; AUTO: `sensor_width` across the larger side (pixel aspect `x/y` included)."""
    if cam_data.type != "PERSP":
        kind = {"ORTHO": "orthographic", "PANO": "panoramic"}.get(cam_data.type, cam_data.type)
        raise ValueError(f"camera {cam_data.name!r} is {kind}: nephele renders "
                         "perspective cameras only (set its type to Perspective)")
    fit = cam_data.sensor_fit
    if fit == "AUTO":
        fit = "HORIZONTAL" if width * pixel_aspect >= height else "VERTICAL"
        sensor = cam_data.sensor_width
    else:
        sensor = cam_data.sensor_width if fit == "HORIZONTAL" else cam_data.sensor_height
    half = 0.5 * sensor / cam_data.lens
    if fit == "HORIZONTAL":
        half *= height / (width * pixel_aspect)
    return math.degrees(2.0 * math.atan(half))


@dataclass
class ChanLine:
    """One frame of a `.chan` file, in nephele's axes."""

    frame: int
    translate: Vec
    rotate_deg: Vec  # about X, Y, Z, applied in CHAN_ROTATION_ORDER
    vfov_deg: float


def chan_line(frame: int, matrix_world, vfov_deg: float) -> ChanLine:
    """A Blender camera's world matrix (it looks down its local −Z, +Y up, as a `.chan`
    camera does) in nephele's axes: rotation `AXES · R`, position `to_nephele(t)`; scale and
    shear dropped."""
    from mathutils import Matrix

    rot = Matrix(AXES) @ matrix_world.to_3x3().normalized()
    euler = rot.to_euler(CHAN_ROTATION_ORDER)  # mathutils: first letter applied first, as .chan
    return ChanLine(frame, to_nephele(matrix_world.translation),
                    tuple(math.degrees(a) for a in euler), vfov_deg)


def write_chan(path: Path, lines: Sequence[ChanLine]) -> None:
    with open(path, "w", encoding="utf-8") as f:
        f.write(f"# Blender scene camera in nephele's axes (Y-up), written by the nephele add-on;\n"
                f"# frame tx ty tz rx ry rz vfov — degrees, rotation order {CHAN_ROTATION_ORDER}\n")
        for c in lines:
            nums = (*c.translate, *c.rotate_deg, c.vfov_deg)
            f.write(f"{c.frame} " + " ".join(f"{v:.9g}" for v in nums) + "\n")


def scene_camera_chan(scene, frames: Sequence[int], width: int, height: int) -> List[ChanLine]:
    """The scene's camera (`scene.camera`, read again at every frame, so camera markers
    switch it) on each of `frames`: `scene.frame_set(frame)`, its `matrix_world`, and the
    vertical angle of view of its lens, sensor and fit for a `width`×`height` image. Raises
    ValueError (naming the camera) for a scene without a camera, a camera object that is not a
    camera, an orthographic or panoramic camera, a lens shift, or non-square pixels. Restores
    the scene's current frame."""
    r = scene.render
    if abs(r.pixel_aspect_x - r.pixel_aspect_y) > 1e-6:
        raise ValueError(f"pixel aspect {r.pixel_aspect_x:g}:{r.pixel_aspect_y:g}: nephele "
                         "renders square pixels (set the pixel aspect to 1:1)")
    current = scene.frame_current, scene.frame_subframe
    lines = []
    try:
        for frame in frames:
            scene.frame_set(frame)
            cam = scene.camera
            if cam is None:
                raise ValueError(f"frame {frame}: the scene has no camera (add one, or render "
                                 "with nephele's camera)")
            if cam.type != "CAMERA":
                raise ValueError(f"frame {frame}: the scene camera {cam.name!r} is a "
                                 f"{cam.type.lower()} object, not a camera")
            data = cam.data
            if abs(data.shift_x) > 1e-6 or abs(data.shift_y) > 1e-6:
                raise ValueError(f"frame {frame}: camera {cam.name!r} has a lens shift "
                                 f"({data.shift_x:g}, {data.shift_y:g}); nephele renders "
                                 "centred cameras only (set Shift X and Y to 0)")
            vfov = vertical_fov_deg(data, width, height)
            lines.append(chan_line(frame, cam.matrix_world, vfov))
    finally:
        scene.frame_set(current[0], subframe=current[1])
    return lines


# --- the Volume ----------------------------------------------------------------------------

def cloud_material(name: str = "nephele cloud", albedo: float = 0.95, anisotropy: float = 0.75,
                   density_scale: float = 1.0):
    """Principled Volume whose Density is the grid `density` (extinction per world unit) times
    `density_scale`, through an Attribute node linked into Density.

    Not the Principled Volume's own "Density Attribute" field: Cycles in Blender 5.0 (bpy 5.0.1)
    reads that field for the shading but not for the volume's extinction bound (majorant), so a
    grid volume then renders almost transparent (Blender's own dense mesh-to-volume cube peaks
    at alpha 0.24, speckled, or 0 depending on the view). Linked from an Attribute node, the
    same grid renders opaque (alpha 1.0); EEVEE and older Cycles read it the same way."""
    import bpy

    mat = bpy.data.materials.new(name)
    if hasattr(mat, "use_nodes"):
        try:
            mat.use_nodes = True
        except (AttributeError, TypeError):
            pass
    nodes = mat.node_tree.nodes
    for n in list(nodes):
        nodes.remove(n)
    out = nodes.new("ShaderNodeOutputMaterial")
    vol = nodes.new("ShaderNodeVolumePrincipled")
    vol.inputs["Density Attribute"].default_value = ""
    attr = nodes.new("ShaderNodeAttribute")
    attr.attribute_type = "GEOMETRY"
    attr.attribute_name = "density"
    scale = nodes.new("ShaderNodeMath")
    scale.operation = "MULTIPLY"
    scale.label = "density scale"
    scale.inputs[1].default_value = density_scale
    links = mat.node_tree.links
    links.new(attr.outputs["Fac"], scale.inputs[0])
    links.new(scale.outputs["Value"], vol.inputs["Density"])
    vol.inputs["Color"].default_value = (albedo, albedo, albedo, 1.0)
    vol.inputs["Anisotropy"].default_value = anisotropy
    links.new(vol.outputs["Volume"], out.inputs["Volume"])
    return mat


def import_volume(first_vdb: Path, start_frame: int, count: int, fps: float, shutter: float,
                  name: str = "nephele cloud", material=None, motion_blur: bool = True):
    """The VDB sequence `first_vdb` (frame `start_frame`, `count` frames) as a Volume object
    with grids `density` and `vel`, rotated from nephele's Y-up into Blender's Z-up; velocity
    in world units per second (`velocity_unit` SECOND, scale 1); the scene's fps, and its
    motion blur with nephele's shutter (a fraction of a frame, centred on the frame)."""
    import bpy

    scene = bpy.context.scene
    vol = bpy.data.volumes.new(name)
    vol.filepath = str(first_vdb)
    # `velocity_grid` can only name a grid Blender has loaded: set before any load, Blender
    # logs "Could not find grid with name vel" and empties it. A new Volume is not evaluated
    # yet (its frame is 0), so as a sequence it would look for `<name>_0000.vdb`; as a single
    # file it loads `first_vdb` itself. Unloaded again, the sequence then loads by frame.
    vol.is_sequence = False
    if not vol.grids.load():
        raise RuntimeError(f"{first_vdb}: Blender cannot read it ({vol.grids.error_message})")
    vol.velocity_grid = "vel"
    vol.grids.unload()
    vol.is_sequence = count > 1
    # Blender numbers a sequence's files from 1 at `frame_start`; nephele's first file is
    # `start_frame`, shown at scene frame `start_frame`.
    vol.frame_start = start_frame
    vol.frame_offset = start_frame - 1
    vol.frame_duration = count
    vol.sequence_mode = "CLIP"
    vol.velocity_unit = "SECOND"
    vol.velocity_scale = 1.0
    obj = bpy.data.objects.new(name, vol)
    obj.rotation_euler = VOLUME_ROTATION
    scene.collection.objects.link(obj)
    vol.materials.append(material or cloud_material())
    scene.render.fps = max(1, round(fps))
    scene.render.fps_base = scene.render.fps / fps
    if motion_blur and shutter > 0:
        scene.render.use_motion_blur = True
        scene.render.motion_blur_shutter = shutter
        scene.render.motion_blur_position = "CENTER"
    return obj


def frame_files(out_dir: Path, name: str, start: int, count: int, ext: str, padding: int = 4) -> Dict[int, Path]:
    return {f: out_dir / f"{name}_{f:0{padding}d}.{ext}" for f in range(start, start + count)}


def shot_frames(settings: ShotSettings) -> List[int]:
    """The shot's frame numbers: `start_frame` on, `round(seconds · fps)` of them (at least 1)."""
    count = max(1, round(settings.seconds * settings.fps))
    return list(range(settings.start_frame, settings.start_frame + count))


#: `make_cloud`'s camera sources: the scene's camera when it has one (else nephele's), the
#: scene's camera (an error without one), nephele's own (`ShotSettings.camera`).
CAMERA_SOURCES = ("AUTO", "SCENE", "NEPHELE")


def make_cloud(obj, out_dir: Path, settings: ShotSettings, binary: Optional[str] = None,
               progress: Optional[Callable[[str], None]] = None, with_camera: bool = True,
               use_module: Optional[bool] = None, camera_source: str = "AUTO"):
    """The whole round trip for mesh object `obj`: OBJ + scene in `out_dir`, render, import.

    `camera_source` (CAMERA_SOURCES): with "SCENE" (and "AUTO" when the scene has a camera)
    nephele renders the Blender scene's camera: `<name>.chan` holds it on every shot frame (see
    `scene_camera_chan`) and the scene file says `camera: Chan((file: "<name>.chan", ...))`;
    the scene camera stays the scene camera. With "NEPHELE" it renders `settings.camera`, and
    `with_camera` imports that camera (from the EXR frames) and makes it the scene camera.
    Returns `(volume_object, camera_object_or_None, scene_path)`: the camera the frames were
    rendered from, in Blender."""
    import bpy

    if camera_source not in CAMERA_SOURCES:
        raise ValueError(f"camera_source {camera_source!r}: one of {', '.join(CAMERA_SOURCES)}")
    scene = bpy.context.scene
    use_scene_camera = camera_source == "SCENE" or (camera_source == "AUTO" and scene.camera is not None)
    out_dir = Path(bpy.path.abspath(str(out_dir))).resolve()
    out_dir.mkdir(parents=True, exist_ok=True)
    name = bpy.path.clean_name(obj.name)
    frames = shot_frames(settings)
    if use_scene_camera:
        # Read before anything is written: a camera nephele cannot render fails here.
        lines = scene_camera_chan(scene, frames, settings.width, settings.height)
        chan_path = out_dir / f"{name}.chan"
        write_chan(chan_path, lines)
        settings = replace(settings, camera=(
            f'Chan((file: "{chan_path.name}", rotation_order: {CHAN_ROTATION_ORDER}, '
            f"fov_deg: {lines[0].vfov_deg!r}))"))
    mesh_path = out_dir / f"{name}.obj"
    lo, hi = export_object(obj, mesh_path)
    diagonal = math.dist(lo, hi)
    scene_path = out_dir / f"{name}.ron"
    scene_path.write_text(scene_text(mesh_path.name, out_dir, name, settings, diagonal))
    if progress:
        progress(f"rendering {scene_path}")
    render(scene_path, binary, progress=progress, use_module=use_module)
    count = len(frames)
    vdbs = frame_files(out_dir, name, settings.start_frame, count, "vdb")
    missing = [p for p in vdbs.values() if not p.exists()]
    if missing:
        raise RuntimeError(f"nephele wrote no {missing[0]}")
    volume = import_volume(vdbs[settings.start_frame], settings.start_frame, count,
                           settings.fps, settings.shutter, name=f"{name} cloud")
    camera = None
    if use_scene_camera:
        camera = scene.camera
    elif with_camera and "Exr" in settings.extra_formats:
        camera = import_camera(frame_files(out_dir, name, settings.start_frame, count, "exr"),
                               name=f"{name} nephele camera")
        scene.camera = camera
        scene.render.resolution_x = settings.width
        scene.render.resolution_y = settings.height
        scene.render.resolution_percentage = 100
    return volume, camera, scene_path
