#!/usr/bin/env python3
"""March the sun's transmittance through a VDB's `density` grid with OpenVDB's own reader,
and with a sky the whole shadow catcher (nephele's `shadow_total`).

Usage: shadow_march.py FILE.vdb POINTS.txt OUT.txt [SKY.txt]

POINTS.txt: a first line `sx sy sz` (unit direction toward the sun), then one surface point
`x y z` a line. OUT.txt: one transmittance `exp(-integral of density dt)` a line, marched from
each point toward the sun in steps of a quarter voxel, the density trilinear between voxel
centres (as the grid's transform places them; 0 outside the active voxels), until the ray
leaves the grid's active bounding box. Written independently of nephele's code: the check of
its `shadow` pass. Exit status 3 when pyopenvdb or numpy cannot be imported (the caller skips).

With SKY.txt (three lines: the sun's irradiance normal to it `r g b`, a gradient sky's zenith
`r g b` and horizon `r g b`, its radiance `horizon + (zenith - horizon) * sqrt(y)` above the
horizon), each OUT.txt line is `t_sun r g b`: the sun's transmittance and, per channel, the
light of sun and sky reaching the point (on ground facing +Y) through the cloud over the light
reaching it without:
  (T_sun E_sun cos_sun + int T(w) L(w) cos dw) / (E_sun cos_sun + int L cos dw),
the sky's irradiance in closed form (pi h + 4 pi (z - h) / 5), the cloud's part over the cone
toward the sphere around the grid's active box by a midpoint rule of SKY_GRID x SKY_GRID
directions (equal solid angles), each marched through the grid box-filtered SKY_COARSEN times
in steps of one coarse voxel.
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


if len(sys.argv) > 4:
    SKY_GRID = 16
    SKY_COARSEN = 8
    with open(sys.argv[4]) as f:
        sun_e, zenith, horizon = (np.array(list(map(float, l.split()))) for l in f if l.strip())
    # The grid box-filtered: coarse voxel I covers fine voxels F*I .. F*I + F - 1 (of `dense`).
    F = SKY_COARSEN
    pad = [(0, (-n) % F) for n in dense.shape]
    d = np.pad(dense, pad)
    coarse = d.reshape(d.shape[0] // F, F, d.shape[1] // F, F, d.shape[2] // F, F).mean(axis=(1, 3, 5))
    cshape = np.array(coarse.shape)

    def sample_coarse(idx):
        # Fine continuous index -> coarse (coarse voxel I's centre at fine F*I + (F-1)/2).
        rel = (idx - lo - 0.5 * (F - 1)) / F
        base = np.floor(rel).astype(np.int64)
        frac = rel - base
        total = np.zeros(len(idx))
        for dx in (0, 1):
            for dy in (0, 1):
                for dz in (0, 1):
                    c = base + np.array([dx, dy, dz])
                    ok = np.all((c >= 0) & (c < cshape), axis=1)
                    cc = np.where(ok[:, None], c, 0)
                    v = coarse[cc[:, 0], cc[:, 1], cc[:, 2]] * ok
                    w = (
                        (frac[:, 0] if dx else 1 - frac[:, 0])
                        * (frac[:, 1] if dy else 1 - frac[:, 1])
                        * (frac[:, 2] if dz else 1 - frac[:, 2])
                    )
                    total += v * w
        return total

    center = 0.5 * (bmin + bmax)
    radius = 0.5 * np.linalg.norm(bmax - bmin)
    # Midpoint directions in a cone about +Z: u uniform in (1 - cos), phi in azimuth.
    g = (np.arange(SKY_GRID) + 0.5) / SKY_GRID
    uu, pp = np.meshgrid(g, 2 * np.pi * g, indexing="ij")
    uu, pp = uu.ravel(), pp.ravel()
    cstep = F * voxel
    sky_e = np.pi * horizon + 0.8 * np.pi * (zenith - horizon)
    # Per point: the cone toward the sphere (its hemisphere when inside), its basis.
    to_c = center - points
    dist = np.linalg.norm(to_c, axis=1)
    inside = dist <= radius
    axis = np.where(inside[:, None], np.array([0.0, 1.0, 0.0]), to_c / dist[:, None])
    cos_max = np.where(inside, 0.0, np.sqrt(np.maximum(0, 1 - (radius / dist) ** 2)))
    helper = np.where(
        (np.abs(axis[:, 0]) < 0.9)[:, None], np.array([1.0, 0, 0]), np.array([0, 0, 1.0])
    )
    e1 = np.cross(axis, helper)
    e1 /= np.linalg.norm(e1, axis=1)[:, None]
    e2 = np.cross(axis, e1)
    c = 1 - uu[None, :] * (1 - cos_max[:, None])
    s = np.sqrt(np.maximum(0, 1 - c * c))
    dirs = (
        (np.cos(pp)[None, :] * s)[:, :, None] * e1[:, None, :]
        + (np.sin(pp)[None, :] * s)[:, :, None] * e2[:, None, :]
        + c[:, :, None] * axis[:, None, :]
    )
    omega = 2 * np.pi * (1 - cos_max) / (SKY_GRID * SKY_GRID)
    n_dirs = dirs.shape[1]
    starts = np.repeat(points, n_dirs, axis=0)
    dirs = dirs.reshape(-1, 3)
    y = dirs[:, 1]
    od = np.zeros(len(dirs))
    chunk = 1 << 16
    for a in range(0, len(dirs), chunk):
        o, dd = starts[a : a + chunk], dirs[a : a + chunk]
        with np.errstate(divide="ignore", invalid="ignore"):
            a0 = (bmin - o) / dd
            a1 = (bmax - o) / dd
        near = np.maximum(np.nanmax(np.minimum(a0, a1), axis=1), 0.0)
        far = np.nanmin(np.maximum(a0, a1), axis=1)
        live = (far > near) & (dd[:, 1] > 0)
        o, dd, near, far = o[live], dd[live], near[live], far[live]
        acc = np.zeros(len(o))
        m = int(np.ceil(np.max(far - near) / cstep)) + 1 if len(o) else 0
        for k in range(m):
            t = near + (k + 0.5) * cstep
            on = t < far
            if not on.any():
                break
            idx = to_index(o[on] + t[on, None] * dd[on])
            acc[on] += sample_coarse(idx) * cstep
        part = np.zeros(len(live))
        part[live] = acc
        od[a : a + chunk] = part
    radiance = horizon[None, :] + (zenith - horizon)[None, :] * np.sqrt(np.maximum(y, 0))[:, None]
    taken_sky = ((1 - np.exp(-od)) * np.maximum(y, 0))[:, None] * radiance
    taken_sky = taken_sky.reshape(len(points), n_dirs, 3).sum(axis=1) * omega[:, None]
    t_sun = np.exp(-tau)
    sun_n = sun_e[None, :] * max(0.0, to_sun[1])
    lit = sun_n + sky_e[None, :]
    taken = sun_n * (1 - t_sun)[:, None] + taken_sky
    ratio = np.where(lit > 0, 1 - taken / np.where(lit > 0, lit, 1), 1.0)
    with open(out, "w") as f:
        f.write(
            "\n".join(
                " ".join(repr(float(v)) for v in (t, *r)) for t, r in zip(t_sun, ratio)
            )
            + "\n"
        )
