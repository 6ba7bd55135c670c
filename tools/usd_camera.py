#!/usr/bin/env python3
"""Write an animated USD camera with Pixar's USD (`pip install usd-core`) and project points
through it, as the reference for nephele's `camera: Usd(...)` reader.

Usage: usd_camera.py STAGE.(usda|usdc) WIDTH HEIGHT FIRST LAST X Y Z [X Y Z ...]

Writes STAGE (its format by its extension): a camera `/World/rig/cam` under a rig that is
scaled, turned (an animated `orient` quaternion) and moved; the camera's own translate and
rotateXYZ animated, its focal length animated, a 4:3 film back with aperture offsets, time codes
FIRST..LAST at 4 per second, sampled sparsely so that values between samples are interpolated.
Then prints a JSON list, one entry per time code FIRST..LAST, of the pixel (x right, y down, in
a WIDTH x HEIGHT image) of each world point, the film back fitted to the image by USD's
fallback conform policy `expandAperture` (CameraUtil's `Fit`: the aperture grows about its
centre, offsets kept, until its aspect is the image's). Exit status 3 when `pxr` cannot be
imported (the caller skips)."""
import json
import sys

try:
    from pxr import Gf, Sdf, Usd, UsdGeom
except ImportError as e:
    print(f"usd-core (pxr) unavailable: {e}", file=sys.stderr)
    sys.exit(3)

path, width, height = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
first, last = int(sys.argv[4]), int(sys.argv[5])
coords = [float(v) for v in sys.argv[6:]]
points = [Gf.Vec3d(*coords[i:i + 3]) for i in range(0, len(coords), 3)]

stage = Usd.Stage.CreateNew(path)
stage.SetStartTimeCode(first)
stage.SetEndTimeCode(last)
stage.SetTimeCodesPerSecond(4)
stage.SetFramesPerSecond(4)
UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
UsdGeom.Xform.Define(stage, "/World")
rig = UsdGeom.Xform.Define(stage, "/World/rig")
rig.AddTranslateOp().Set(Gf.Vec3d(0.5, -0.25, 1.0))
orient = rig.AddOrientOp()
orient.Set(Gf.Quatf(1, 0, 0, 0), first)
orient.Set(Gf.Quatf(Gf.Rotation(Gf.Vec3d(0.2, 1, 0.1), 25).GetQuat()), last)
rig.AddScaleOp().Set(Gf.Vec3f(2, 2, 2))
cam = UsdGeom.Camera.Define(stage, "/World/rig/cam")
translate = cam.AddTranslateOp()
rotate = cam.AddRotateXYZOp()
span = last - first
for n, t in enumerate(range(first, last + 1, 6)):
    translate.Set(Gf.Vec3d(0.3 * n - 0.5, 0.2 + 0.1 * n, 3.5 - 0.15 * n * n), t)
    rotate.Set(Gf.Vec3f(-4.0 + 3 * n, -10.0 + 7 * n * n, 2.0 * n), t)
cam.CreateFocalLengthAttr().Set(28.0, first)
cam.GetFocalLengthAttr().Set(45.0, first + span // 2)
cam.GetFocalLengthAttr().Set(35.0, last)
cam.CreateHorizontalApertureAttr().Set(24.892)
cam.CreateVerticalApertureAttr().Set(18.669)
cam.CreateHorizontalApertureOffsetAttr().Set(1.2)
cam.CreateVerticalApertureOffsetAttr().Set(-0.7)
cam.CreateClippingRangeAttr().Set(Gf.Vec2f(0.01, 10000))
stage.GetRootLayer().Save()

stage = Usd.Stage.Open(path)
camera = UsdGeom.Camera(stage.GetPrimAtPath("/World/rig/cam"))
aspect = width / height
frames = []
for t in range(first, last + 1):
    gf = camera.GetCamera(Usd.TimeCode(t))
    h, v = gf.horizontalAperture, gf.verticalAperture
    # expandAperture: grow the narrower side about the window's centre.
    if h / v > aspect:
        gf.verticalAperture = h / aspect
    else:
        gf.horizontalAperture = v * aspect
    frustum = gf.frustum
    to_ndc = frustum.ComputeViewMatrix() * frustum.ComputeProjectionMatrix()
    pixels = []
    for p in points:
        ndc = to_ndc.Transform(p)
        pixels.append([(ndc[0] + 1) / 2 * width, (1 - ndc[1]) / 2 * height])
    frames.append(pixels)
print(json.dumps(frames))
