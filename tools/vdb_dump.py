#!/usr/bin/env python3
"""Read a VDB file with OpenVDB's own reader (pyopenvdb) and dump what a test checks.

Usage: vdb_dump.py FILE.vdb GRID OUT.txt

OUT.txt: a first line of JSON (grid names, name, class, metadata, voxel size, active count,
index and world bounding boxes of the active voxels, value range — of the vector length for a
vector grid), then one line per active voxel: `i j k x y z value` (`i j k x y z vx vy vz` for a
vector grid such as `vel`) with (x, y, z) the voxel centre from the grid's own transform.
Exit status 3 when pyopenvdb cannot be imported (the caller skips)."""
import json
import sys

try:
    import pyopenvdb as vdb
except ImportError as e:
    print(f"pyopenvdb unavailable: {e}", file=sys.stderr)
    sys.exit(3)

path, name, out = sys.argv[1], sys.argv[2], sys.argv[3]
names = [g.name for g in vdb.readAllGridMetadata(path)]
grid = vdb.read(path, name)
lo, hi = grid.evalActiveVoxelBoundingBox()
xf = grid.transform
lines = []
vmin, vmax = float("inf"), float("-inf")
for item in grid.citerOnValues():
    if item.min != item.max:
        raise SystemExit(f"unexpected active tile {item.min}..{item.max}")
    ijk = item.min
    x, y, z = xf.indexToWorld(ijk)
    v = item.value
    if isinstance(v, tuple):
        length = sum(c * c for c in v) ** 0.5
        vmin, vmax = min(vmin, length), max(vmax, length)
        text = " ".join(repr(c) for c in v)
    else:
        vmin, vmax = min(vmin, v), max(vmax, v)
        text = repr(v)
    lines.append(f"{ijk[0]} {ijk[1]} {ijk[2]} {x!r} {y!r} {z!r} {text}")
header = {
    "grids": names,
    "name": grid.name,
    "class": str(grid.gridClass),
    "metadata": {k: grid[k] for k in grid.metadata},
    "voxel_size": list(xf.voxelSize()),
    "active": grid.activeVoxelCount(),
    "index_bbox": [list(lo), list(hi)],
    "world_bbox": [list(xf.indexToWorld(lo)), list(xf.indexToWorld(hi))],
    "value_range": [vmin, vmax] if lines else [0.0, 0.0],
    "background": grid.background,
    "type": type(grid).__name__,
    "half": bool(grid.saveFloatAsHalf),
}
with open(out, "w") as f:
    f.write(json.dumps(header) + "\n")
    f.write("\n".join(lines) + ("\n" if lines else ""))
