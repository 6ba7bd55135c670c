#!/usr/bin/env python3
"""Open a nephele shot stage with Pixar's USD (`pip install usd-core`) and project points.

Usage: usd_project.py STAGE.usda WIDTH HEIGHT FRAME X Y Z [X Y Z ...]

Prints one JSON object: the stage's time codes and rates, the volume's density field, its VDB
path at FRAME (as authored and resolved), every field of the volume (`fields`: name → field
name, data type and VDB path at FRAME), the camera's shutter open and close, the light types, and for each world point the pixel
(x right, y down, in pixels of a WIDTH x HEIGHT image) where the stage's camera at FRAME
projects it. Exit status 3 when `pxr` cannot be imported (the caller skips)."""
import json
import sys

try:
    from pxr import Gf, Usd, UsdGeom, UsdLux, UsdVol
except ImportError as e:
    print(f"usd-core (pxr) unavailable: {e}", file=sys.stderr)
    sys.exit(3)

path, width, height, frame = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), float(sys.argv[4])
coords = [float(v) for v in sys.argv[5:]]
stage = Usd.Stage.Open(path)
camera = UsdGeom.Camera(stage.GetPrimAtPath("/shot/camera"))
frustum = camera.GetCamera(Usd.TimeCode(frame)).frustum
to_ndc = frustum.ComputeViewMatrix() * frustum.ComputeProjectionMatrix()
pixels = []
for i in range(0, len(coords), 3):
    ndc = to_ndc.Transform(Gf.Vec3d(*coords[i:i + 3]))
    pixels.append([(ndc[0] + 1) / 2 * width, (1 - ndc[1]) / 2 * height])
volume = UsdVol.Volume(stage.GetPrimAtPath("/shot/cloud"))
field = volume.GetFieldPath("density")
asset = UsdVol.OpenVDBAsset(stage.GetPrimAtPath(field)).GetFilePathAttr().Get(Usd.TimeCode(frame))
fields = {}
for name, field_path in volume.GetFieldPaths().items():
    prim = UsdVol.OpenVDBAsset(stage.GetPrimAtPath(field_path))
    fields[name] = {
        "field_name": prim.GetFieldNameAttr().Get(),
        "data_type": prim.GetFieldDataTypeAttr().Get(),
        "vdb": prim.GetFilePathAttr().Get(Usd.TimeCode(frame)).path,
    }
print(json.dumps({
    "start": stage.GetStartTimeCode(),
    "end": stage.GetEndTimeCode(),
    "fps": stage.GetFramesPerSecond(),
    "tcps": stage.GetTimeCodesPerSecond(),
    "up_axis": UsdGeom.GetStageUpAxis(stage),
    "field": str(field),
    "field_name": UsdVol.OpenVDBAsset(stage.GetPrimAtPath(field)).GetFieldNameAttr().Get(),
    "vdb": asset.path,
    "vdb_resolved": asset.resolvedPath,
    "sun": stage.GetPrimAtPath("/shot/sun").GetTypeName(),
    "sky": stage.GetPrimAtPath("/shot/sky").GetTypeName(),
    "sun_intensity": UsdLux.DistantLight(stage.GetPrimAtPath("/shot/sun")).GetIntensityAttr().Get(),
    "fields": fields,
    "shutter": [camera.GetShutterOpenAttr().Get(), camera.GetShutterCloseAttr().Get()],
    "pixels": pixels,
}))
