"""nephele for Blender: turn the selected mesh into a nephele cloud shot and bring its VDB
frames back as a Volume object (grids `density` and `vel`). nephele renders the scene's camera
(when the scene has one; else its own camera, imported).

Object menu (3D Viewport) > "Nephele Cloud from Mesh". The work is in `core.py`.
"""

bl_info = {
    "name": "nephele clouds",
    "author": "nephele",
    "version": (0, 1, 0),
    "blender": (4, 2, 0),
    "location": "3D Viewport > Object > Nephele Cloud from Mesh",
    "description": "Render the selected mesh as a nephele cloud shot (VDB) and import it as a Volume",
    "category": "Import-Export",
}

import bpy  # noqa: E402
from bpy.props import BoolProperty, EnumProperty, FloatProperty, IntProperty, StringProperty  # noqa: E402

from . import core  # noqa: E402


class NepheleAddonPreferences(bpy.types.AddonPreferences):
    bl_idname = __package__

    binary: StringProperty(
        name="nephele binary",
        description="Path of the nephele CLI (empty: $NEPHELE_BIN, then `nephele` on PATH). "
        "Not used when the nephele Python module is installed in Blender's Python",
        subtype="FILE_PATH",
        default="",
    )

    def draw(self, context):
        self.layout.prop(self, "binary")


#: The scene file's `quality` levels (scenes/README.md "Quality"), cheapest first.
QUALITIES = [
    ("Preview", "Preview", "Fast drafts: coarse light grid, multiple scattering by octaves"),
    ("Final", "Final", "The shot's look: fine light grid, multiple scattering from photons"),
    ("Production", "Production", "Final with finer steps and light grid (slower)"),
    ("Reference", "Reference", "A path tracer through the same density (slow): checks a "
     "shot's light against the march"),
]


class OBJECT_OT_nephele_cloud(bpy.types.Operator):
    """Fit the active mesh with nephele, render its cloud shot to VDB frames and import them"""

    bl_idname = "object.nephele_cloud"
    bl_label = "Nephele Cloud from Mesh"
    bl_options = {"REGISTER", "UNDO"}

    output: StringProperty(name="Output folder", subtype="DIR_PATH", default="//nephele/")
    blobs: IntProperty(name="Blobs", default=300, min=4, max=3000)
    animation: EnumProperty(name="Animation", items=[
        ("Diffusion", "Diffusion", "A cloud spreads out of one piece into the shape"),
        ("Aggregation", "Aggregation", "Scattered puffs gather into the shape"),
    ])
    seconds: FloatProperty(name="Seconds", default=4.0, min=0.05)
    shutter: FloatProperty(name="Shutter", description="Open shutter, a fraction of a frame "
                           "(motion blur in nephele and in Blender)", default=0.5, min=0.0, max=1.0)
    voxels: IntProperty(name="Voxels across", description="Grid voxels across the mesh's "
                        "bounding-box diagonal", default=256, min=16, max=1024)
    quality: EnumProperty(name="Quality", default="Preview", items=QUALITIES)
    camera_source: EnumProperty(name="Camera", default="AUTO", items=[
        ("AUTO", "Scene camera if any", "The scene's camera when it has one, else nephele's"),
        ("SCENE", "Scene camera", "nephele renders the scene's camera on every frame (its "
         "animation, lens, sensor and sensor fit; written as a .chan file)"),
        ("NEPHELE", "nephele's camera", "nephele frames the cloud with its own automatic camera"),
    ])
    camera: BoolProperty(name="Import nephele camera", description="With nephele's camera: "
                         "import it (from its EXR frames) and make it the scene camera", default=True)
    scene_frames: BoolProperty(name="Scene frame range", description="The shot is the scene's "
                               "frames (start to end); off: Seconds from the start frame",
                               default=True)
    start_at_cursor: BoolProperty(name="Start at the 3D cursor", description="Diffusion: the "
                                  "cloud starts from the blob nearest the 3D cursor (place the "
                                  "cursor on or in the mesh)", default=False)
    use_timing: BoolProperty(name="Timing from nephele_progress", description="Retime the shot "
                             "by the object's animated custom property 'nephele_progress' (0 = "
                             "the first pose, 1 = formed; key it in the Graph Editor to slow "
                             "down, hold, speed up or run backwards)", default=True)

    @classmethod
    def poll(cls, context):
        return context.active_object is not None and context.active_object.type == "MESH"

    def execute(self, context):
        scene = context.scene
        prefs = context.preferences.addons[__package__].preferences if __package__ in context.preferences.addons else None
        fps = scene.render.fps / scene.render.fps_base
        seconds = self.seconds
        if self.scene_frames:
            seconds = (scene.frame_end - scene.frame_start + 1) / fps
        width, height = core.render_size(scene)
        obj = context.active_object
        start = core.start_from_cursor(scene) if self.start_at_cursor else None
        frames = core.shot_frames(core.ShotSettings(seconds=seconds, fps=fps,
                                                    start_frame=scene.frame_start))
        try:
            timing = core.timing_from_property(obj, scene, frames, fps) if self.use_timing else None
        except ValueError as e:
            self.report({"ERROR"}, str(e))
            return {"CANCELLED"}
        settings = core.ShotSettings(start=start, timing=timing,
            blobs=self.blobs, animation=self.animation, seconds=seconds,
            fps=fps, start_frame=scene.frame_start, width=width, height=height,
            shutter=self.shutter, quality=self.quality, voxels_per_diagonal=self.voxels,
            # The EXR frames: nephele's picture of the cloud from the scene camera (to composite),
            # or where nephele's own camera is read from.
            extra_formats=["Exr"] if self.camera or self.camera_source != "NEPHELE" else [],
        )
        try:
            volume, _, scene_path = core.make_cloud(
                context.active_object, self.output, settings,
                binary=prefs.binary if prefs else None, with_camera=self.camera,
                progress=lambda line: print("nephele:", line), camera_source=self.camera_source)
        except (RuntimeError, ValueError, OSError) as e:
            self.report({"ERROR"}, str(e))
            return {"CANCELLED"}
        scene.frame_end = core.shot_frames(settings)[-1]
        self.report({"INFO"}, f"{volume.name}: from {scene_path}")
        return {"FINISHED"}


def menu(self, context):
    self.layout.operator(OBJECT_OT_nephele_cloud.bl_idname)


classes = (NepheleAddonPreferences, OBJECT_OT_nephele_cloud)


def register():
    for c in classes:
        bpy.utils.register_class(c)
    bpy.types.VIEW3D_MT_object.append(menu)


def unregister():
    bpy.types.VIEW3D_MT_object.remove(menu)
    for c in reversed(classes):
        bpy.utils.unregister_class(c)
