#!/usr/bin/env python3
"""March the sun's transmittance through a VDB's `density` grid with OpenVDB's own reader.

Usage: shadow_march.py FILE.vdb POINTS.txt OUT.txt

POINTS.txt: a first line `sx sy sz` (unit direction toward the sun), then one surface point
`x y z` a line. OUT.txt: one transmittance `exp(-integral of density dt)` a line, marched from
each point toward the sun in steps of a quarter voxel, the density trilinear between voxel
centres (as the grid's transform places them; 0 outside the active voxels), until the ray
leaves the grid's active bounding box. Written independently of nephele's code: the check of
its `shadow` pass. Exit status 3 when pyopenvdb or numpy cannot be imported (the caller skips).
"""
import sys

try:
    import numpy as np
    import pyopenvdb as vdb
except ImportError as e:
    print(f"pyopenvdb or numpy unavailable: {e}", file=sys.stderr)
    sys.exit(3)

path, points_path, out = sys.argv[1], sys.argv[2], sys.argv[3]
grid = vdb.read(path, "density")
lo, hi = grid.evalActiveVoxelBoundingBox()
lo = np.array(lo) - 1
hi = np.array(hi) + 1
dense = np.zeros(tuple(hi - lo + 1), dtype=np.float32)
grid.copyToArray(dense, ijk=tuple(int(v) for v in lo))
xf = grid.transform
voxel = xf.voxelSize()[0]

with open(points_path) as f:
    rows = [list(map(float, l.split())) for l in f if l.strip()]
to_sun = np.array(rows[0])
points = np.array(rows[1:])

# World -> continuous index (voxel centres at integers), through the grid's own transform.
origin = np.array(xf.worldToIndex((0.0, 0.0, 0.0)))
axes = np.array([np.array(xf.worldToIndex(tuple(e))) - origin for e in np.eye(3)])


def to_index(p):
    return origin + p @ axes


def sample(idx):
    rel = idx - lo
    base = np.floor(rel).astype(np.int64)
    frac = rel - base
    total = np.zeros(len(idx))
    shape = np.array(dense.shape)
    for dx in (0, 1):
        for dy in (0, 1):
            for dz in (0, 1):
                c = base + np.array([dx, dy, dz])
                ok = np.all((c >= 0) & (c < shape), axis=1)
                cc = np.where(ok[:, None], c, 0)
                v = dense[cc[:, 0], cc[:, 1], cc[:, 2]] * ok
                w = (
                    (frac[:, 0] if dx else 1 - frac[:, 0])
                    * (frac[:, 1] if dy else 1 - frac[:, 1])
                    * (frac[:, 2] if dz else 1 - frac[:, 2])
                )
                total += v * w
    return total


# The parameter range inside the (padded) active box, per point (slab test in world units).
wlo = np.array(xf.indexToWorld(tuple(int(v) for v in lo)))
whi = np.array(xf.indexToWorld(tuple(int(v) for v in hi)))
bmin, bmax = np.minimum(wlo, whi), np.maximum(wlo, whi)
with np.errstate(divide="ignore", invalid="ignore"):
    t0 = (bmin - points) / to_sun
    t1 = (bmax - points) / to_sun
tn = np.nanmax(np.where(np.isfinite(t0), np.minimum(t0, t1), -np.inf), axis=1)
tf = np.nanmin(np.where(np.isfinite(t1), np.maximum(t0, t1), np.inf), axis=1)
tn = np.maximum(tn, 0.0)
step = 0.25 * voxel
tau = np.zeros(len(points))
n = int(np.ceil(np.max(np.maximum(tf - tn, 0.0)) / step)) + 1
for k in range(n):
    t = tn + (k + 0.5) * step
    live = t < tf
    if not live.any():
        break
    idx = to_index(points + t[:, None] * to_sun)
    tau += np.where(live, sample(idx), 0.0) * step
with open(out, "w") as f:
    f.write("\n".join(repr(float(np.exp(-x))) for x in tau) + "\n")
