#!/usr/bin/env python3
"""Render nephele's density grid in Mitsuba 3 and compare with nephele's own frames.

Input: a folder written by `tests/it/mitsuba.rs` (see its module doc):
  meta.json       camera, sun, phase function, nephele's times
  grid.vol        the volume export's Mitsuba grid: extinction per world unit, with its box
  sky.f32         the sky as a lat-long map in Mitsuba's envmap convention, (v, u, rgb);
                  unused when meta.json's "envmap" names the scene's own EXR (an
                  `Environment` sky: file, rotate_deg, intensity)
  nephele_ss.f32  nephele's frame, single scattering only, over the sky: (y, x, rgba)
  nephele_ms.f32  the same with nephele's multiple-scattering approximation
  nephele_grid_ss.f32  (optional) nephele's single scattering of grid.vol itself: the light
                  transport alone, without the grid's discretisation of the density
  nephele_ref.f32, nephele_ref2.f32  (optional, NEPHELE_MITSUBA_REFERENCE) nephele's
                  `quality: Reference` (its path tracer, full transport) at two path seeds,
                  through the blobs; nephele_grid_ref*.f32 the same through grid.vol;
                  reference.json its spp, seconds and work

Mitsuba renders the same camera, sun (directional, same irradiance) and sky (envmap) with
`volpath`: `max_depth` 2 (single scattering) and 64 (full transport), each twice with
different seeds so that the reference's own noise can be measured and excluded.

The cloud's two-lobe phase function is `TwoLobe` (`register_two_lobe`), not Mitsuba's `blendphase`: in
Mitsuba 3.6.4 `blendphase.sample` returns the pdf of the lobe it picked instead of the
mixture's, so the MIS weights between the phase sample and the envmap's sample do not sum to
one and every sky-lit order comes out too bright (a semi-infinite slab under a constant sky,
single scattering, against the closed form `a ∫ p(d·l) μ_l/(μ_l + μ_v) dl`: 1.39× seen from
above, 1.32× at 45°, 1.20× at 70°; each `hg` alone, and `TwoLobe`, within 1.2 %; the sun, a
delta light without MIS, is not affected). `--blendphase` renders with Mitsuba's own, for
comparing with references made before.

Output (stdout, JSON):
  ss_rel_rmse       relative RMSE of nephele's single scattering against Mitsuba's (linear
                    luminance over the cloud's pixels), the reference's noise excluded
  ss_rel_rmse_raw   the same, noise included; ss_ref_noise: the reference's relative noise
  ss_same_grid_rel_rmse  the same for nephele_grid_ss (both renderers on the same grid)
  full_rel_rmse     the same for nephele's full image (nephele_ms: single + multiple
                    scattering) against Mitsuba's full transport; full_rel_rmse_raw,
                    full_ref_noise as above; full_mean_ratio: nephele's mean over Mitsuba's
  ms_rel_rmse       the same for the multiple-scattering term alone (nephele_ms − nephele_ss
                    against Mitsuba's full − single scattering, per pixel, relative to the
                    term's mean); ms_rel_rmse_raw, ms_ref_noise, ms_mean_ratio
  mean_lum_*        mean ACES luminance of the cloud (alpha > 0.5) for nephele SS / MS and
                    Mitsuba SS / full transport
  base_top_*        mean luminance of the cloud's lowest quarter of rows over its top quarter
  ref_rel_rmse      (with nephele_ref*) nephele's Reference against Mitsuba's full transport,
                    per pixel, both renderers' noise excluded; ref_rel_rmse_raw noise included;
                    ref_noise, ref_mitsuba_noise: each one's relative noise (of its two-seed
                    mean); ref_mean_ratio; ref_same_grid_*: the same through grid.vol (a
                    Reference of max_depth 2, reference.json, is compared with Mitsuba's
                    single scattering instead)
  seconds_*         render times (nephele's from meta.json)
With --picture PATH: a 2×2 sheet (nephele SS | Mitsuba SS / nephele MS | Mitsuba full).

Usage: python3 tools/mitsuba_compare.py DIR [--spp 256] [--picture out.png] [--blendphase]
       python3 tools/mitsuba_compare.py --check-phase   (the slab check above, as JSON)
Needs `pip install mitsuba numpy`; uses the `llvm_ad_rgb` variant when its kernels compile on
this machine (tried in a child process, see `pick_variant`), else `scalar_rgb` (same image,
slower).
"""
import argparse
import json
import os
import subprocess
import sys
import time

import numpy as np
import drjit as dr
import mitsuba as mi

# Set by --blendphase: Mitsuba's own `blendphase` instead of `TwoLobe` (module doc).
BLENDPHASE = False


# A 4×4 render through a grid medium: the kernels a comparison needs.
PROBE = """
import mitsuba as mi
mi.set_variant("llvm_ad_rgb")
mi.render(mi.load_dict({
    "type": "scene",
    "integrator": {"type": "volpath", "max_depth": 2},
    "sensor": {"type": "perspective", "film": {"type": "hdrfilm", "width": 4, "height": 4}},
    "sun": {"type": "directional", "direction": [0, 0, 1]},
    "cloud": {"type": "cube", "bsdf": {"type": "null"},
              "to_world": mi.ScalarTransform4f().translate([0, 0, 4]),
              "interior": {"type": "heterogeneous", "sigma_t": {"type": "gridvolume",
                           "grid": mi.VolumeGrid(mi.TensorXf([1.0] * 8, (2, 2, 2, 1)))}}},
}), spp=1)
"""


def register_two_lobe():
    """Register `twolobe` (the class below) with the variant set (Mitsuba's Python plugins bind
    to the variant, so this runs after `mi.set_variant`)."""

    class TwoLobe(mi.PhaseFunction):
        """The cloud's phase function `(1 − w)·HG(μ, g1) + w·HG(μ, g2)` (nephele's
        `render::phase::cloud_phase`), sampled by lobe like `blendphase` but returning the
        mixture's pdf, which the integrators' MIS needs (see the module doc)."""

        def __init__(self, props):
            mi.PhaseFunction.__init__(self, props)
            self.w = props.get("weight", 0.2)
            self.g1 = props.get("g1", 0.75)
            self.g2 = props.get("g2", -0.3)
            self.m_flags = mi.PhaseFunctionFlags.Anisotropic
            self.m_components = [mi.PhaseFunctionFlags.Anisotropic]

        @staticmethod
        def hg(cos_theta, g):
            # Mitsuba's convention: cos_theta between wo and wi (wi points back along the ray).
            temp = 1.0 + g * g + 2.0 * g * cos_theta
            return dr.inv_four_pi * (1.0 - g * g) / (temp * dr.sqrt(temp))

        def mix(self, cos_theta):
            return (1.0 - self.w) * self.hg(cos_theta, self.g1) + self.w * self.hg(cos_theta, self.g2)

        def eval_pdf(self, ctx, mei, wo, active=True):
            p = self.mix(dr.dot(wo, mei.wi))
            return mi.Spectrum(p), p

        def sample(self, ctx, mei, sample1, sample2, active=True):
            # The lobe by its weight, then its cosine exactly (as Mitsuba's `hg` samples).
            g = dr.select(sample1 < self.w, self.g2, self.g1)
            sqr_term = (1.0 - g * g) / (1.0 - g + 2.0 * g * sample2.x)
            cos_theta = (1.0 + g * g - sqr_term * sqr_term) / (2.0 * g)
            sin_theta = dr.safe_sqrt(1.0 - cos_theta * cos_theta)
            s, c = dr.sincos(2.0 * dr.pi * sample2.y)
            wo = mei.to_world(mi.Vector3f(sin_theta * s, sin_theta * c, -cos_theta))
            return wo, mi.Spectrum(1.0), self.mix(-cos_theta)

        def to_string(self):
            return f"TwoLobe[weight={self.w}, g1={self.g1}, g2={self.g2}]"

    mi.register_phasefunction("twolobe", lambda props: TwoLobe(props))


def phase_dict(meta, blendphase=False):
    """The cloud's phase function for Mitsuba: `TwoLobe`, or (`blendphase`) Mitsuba's own
    `blendphase` of two `hg` lobes, biased under MIS in 3.6.4 (module doc)."""
    g, w, ratio = meta["g"], meta["back_weight"], meta["back_ratio"]
    if blendphase:
        return {
            "type": "blendphase",
            "weight": w,
            "phase1": {"type": "hg", "g": g},
            "phase2": {"type": "hg", "g": g * ratio},
        }
    return {"type": "twolobe", "weight": w, "g1": g, "g2": g * ratio}


def check_phase(spp=4096):
    """Mitsuba's single scattering (`volpath`, `max_depth` 2) of a semi-infinite homogeneous
    slab (σ_t 2, albedo 0.95) under a constant sky of radiance 1, seen from 0°, 45° and 70° off
    its normal (an 8×8-pixel, 2° view of its surface), over the closed form
    `a ∫_{l·n > 0} p(d·l) μ_l/(μ_l + μ_v) dl` (a 2,000 × 2,000 midpoint sum), with `TwoLobe`
    and with Mitsuba's `blendphase`: {"twolobe": [..], "blendphase": [..]} (1 = exact)."""
    T = mi.ScalarTransform4f
    meta = {"g": 0.75, "back_weight": 0.2, "back_ratio": -0.4}
    a, sigma = 0.95, 2.0

    def hg(mu, g):
        d = 1.0 + g * g - 2.0 * g * mu
        return (1.0 - g * g) / (4.0 * np.pi * d**1.5)

    def closed(mv):
        n = 2000
        mu = (np.arange(n) + 0.5) / n
        phi = (np.arange(n) + 0.5) / n * 2.0 * np.pi
        m, p = np.meshgrid(mu, phi, indexing="ij")
        # The view travels down at cos mv; l toward the sky at cos m to the normal.
        c = np.sqrt(1.0 - mv * mv) * np.sqrt(1.0 - m * m) * np.cos(p) - mv * m
        phase = 0.8 * hg(c, 0.75) + 0.2 * hg(c, -0.3)
        return a * float(np.sum(phase * m / (m + mv))) * (2.0 * np.pi) / (n * n)

    def render(view_deg, blendphase):
        th = np.radians(view_deg)
        eye = [-5.0 * float(np.sin(th)), 5.0 * float(np.cos(th)), 0.0]
        scene = mi.load_dict({
            "type": "scene",
            "integrator": {"type": "volpath", "max_depth": 2},
            "sensor": {
                "type": "perspective",
                "fov": 2.0,
                "to_world": T().look_at(origin=eye, target=[0, 0, 0], up=[0, 0, 1]),
                "film": {"type": "hdrfilm", "width": 8, "height": 8,
                         "rfilter": {"type": "box"}, "pixel_format": "rgb"},
                "sampler": {"type": "independent", "sample_count": spp},
            },
            "sky": {"type": "constant", "radiance": {"type": "rgb", "value": [1, 1, 1]}},
            "slab": {
                "type": "cube",
                "bsdf": {"type": "null"},
                "to_world": T().translate([0, -15, 0]).scale([200, 15, 200]),
                "interior": {"type": "homogeneous", "albedo": a, "sigma_t": sigma,
                             "phase": phase_dict(meta, blendphase)},
            },
        })
        return float(np.array(mi.render(scene, spp=spp))[..., 1].mean())

    views = (0, 45, 70)
    out = {"views_deg": list(views)}
    for name, blend in (("twolobe", False), ("blendphase", True)):
        out[name] = [round(render(v, blend) / closed(np.cos(np.radians(v))), 4) for v in views]
    return out


def pick_variant():
    """`llvm_ad_rgb` when its kernels compile here, else `scalar_rgb` (same image, slower).

    Dr.Jit with too old an LLVM aborts the whole process at the first volume kernel ("LLVM
    ERROR: Cannot select"), which no `try` can catch: a child process tries first.
    """
    probe = subprocess.run([sys.executable, "-c", PROBE], capture_output=True)
    variant = "llvm_ad_rgb" if probe.returncode == 0 else "scalar_rgb"
    mi.set_variant(variant)
    register_two_lobe()
    return variant


def load(d, name, shape):
    return np.fromfile(os.path.join(d, name), dtype="<f4").reshape(shape)


def read_vol(path):
    """A Mitsuba `.vol` grid: (values (z, y, x, 1), box min, box max)."""
    raw = open(path, "rb").read()
    assert raw[:3] == b"VOL" and raw[3] == 3, f"{path}: not a version-3 .vol file"
    enc, nx, ny, nz, ch = np.frombuffer(raw, "<i4", 5, 4)
    assert enc == 1 and ch == 1, f"{path}: expected one float32 channel"
    box = np.frombuffer(raw, "<f4", 6, 24).astype(float)
    vals = np.frombuffer(raw, "<f4", nx * ny * nz, 48).reshape(nz, ny, nx, 1)
    return np.ascontiguousarray(vals), box[:3], box[3:]


def sky_emitter(meta, sky):
    """The sky: nephele's as a map (sky.f32), or the scene's own EXR (meta "envmap": the same
    file nephele read, turned about +Y by rotate_deg and scaled by intensity)."""
    env = meta.get("envmap")
    if env is None:
        return {"type": "envmap", "bitmap": mi.Bitmap(sky)}
    return {
        "type": "envmap",
        "filename": env["file"],
        "scale": env["intensity"],
        "to_world": mi.ScalarTransform4f().rotate([0, 1, 0], env["rotate_deg"]),
    }


def scene_dict(meta, vol, sky, max_depth, spp, seed):
    T = mi.ScalarTransform4f
    grid, lo, hi = vol
    return {
        "type": "scene",
        "integrator": {"type": "volpath", "max_depth": max_depth},
        "sensor": {
            "type": "perspective",
            "fov": meta["fov_deg"],
            "fov_axis": "y",
            "to_world": T().look_at(
                origin=meta["position"], target=meta["look_at"], up=meta["up"]
            ),
            "film": {
                "type": "hdrfilm",
                "width": meta["width"],
                "height": meta["height"],
                "rfilter": {"type": "box"},
                "pixel_format": "rgb",
            },
            "sampler": {"type": "independent", "sample_count": spp, "seed": seed},
        },
        "sun": {
            "type": "directional",
            "direction": meta["sun_dir"],
            "irradiance": {"type": "rgb", "value": meta["sun_irradiance"]},
        },
        "sky": sky_emitter(meta, sky),
        "cloud": {
            "type": "cube",
            "bsdf": {"type": "null"},
            "to_world": T().translate(((lo + hi) / 2).tolist()).scale(((hi - lo) / 2).tolist()),
            "interior": {
                "type": "heterogeneous",
                "albedo": meta["albedo"],
                "scale": 1.0,
                "sigma_t": {
                    "type": "gridvolume",
                    "grid": mi.VolumeGrid(grid),
                    "to_world": T().translate(lo.tolist()).scale((hi - lo).tolist()),
                },
                "phase": phase_dict(meta, BLENDPHASE),
            },
        },
    }


def render(meta, grid, sky, max_depth, spp, seed):
    scene = mi.load_dict(scene_dict(meta, grid, sky, max_depth, spp, seed))
    start = time.time()
    img = np.array(mi.render(scene, spp=spp, seed=seed))
    return img[..., :3], time.time() - start


def aces(x):
    x = np.maximum(x, 0.0)
    return np.clip((x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14), 0.0, 1.0)


def lum(rgb):
    return 0.2126 * rgb[..., 0] + 0.7152 * rgb[..., 1] + 0.0722 * rgb[..., 2]


def srgb8(x):
    x = np.clip(x, 0.0, 1.0)
    s = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)
    return (s * 255 + 0.5).astype(np.uint8)


def base_top(l, mask):
    rows = np.nonzero(mask.any(axis=1))[0]
    top, bottom = rows.min(), rows.max()
    q = max(1, (bottom - top + 1) // 4)
    tmask, bmask = mask.copy(), mask.copy()
    tmask[top + q :] = False
    bmask[: bottom - q + 1] = False
    return float(l[bmask].mean() / l[tmask].mean())


def reference_comparison(d, shape, full, cloud):
    """Nephele's `quality: Reference` (two path seeds) against Mitsuba's full transport (two
    seeds), linear luminance over the cloud's pixels: the relative RMSE with both renderers'
    noise excluded (each the variance of its two-seed mean, `((a − b)/2)²`), raw, each noise,
    the mean ratio; through the blobs (`ref_*`) and through grid.vol (`ref_same_grid_*`)."""
    out = {}
    ma, mb = (lum(x)[cloud] for x in full)
    m = 0.5 * (ma + mb)
    m_noise = float(np.mean((ma - mb) ** 2)) / 4.0
    scale = float(m.mean())
    meta_path = os.path.join(d, "reference.json")
    if os.path.exists(meta_path):
        meta = json.load(open(meta_path))
        out["ref_spp"] = meta["spp"]
        out["ref_max_depth"] = meta.get("max_depth", 64)
        out["seconds_nephele_ref"] = meta["seconds"]
        out["ref_evaluations_per_path"] = round(meta["evaluations"] / meta["paths"], 1)
    for key, stem in (("ref", "nephele_ref"), ("ref_same_grid", "nephele_grid_ref")):
        a_path, b_path = (os.path.join(d, f"{stem}{s}.f32") for s in ("", "2"))
        if not (os.path.exists(a_path) and os.path.exists(b_path)):
            continue
        na, nb = (lum(load(d, os.path.basename(p), shape)[..., :3])[cloud] for p in (a_path, b_path))
        n = 0.5 * (na + nb)
        n_noise = float(np.mean((na - nb) ** 2)) / 4.0
        mse = float(np.mean((n - m) ** 2))
        out[f"{key}_rel_rmse"] = round(np.sqrt(max(mse - n_noise - m_noise, 0.0)) / scale, 4)
        out[f"{key}_rel_rmse_raw"] = round(np.sqrt(mse) / scale, 4)
        out[f"{key}_noise"] = round(np.sqrt(n_noise) / scale, 4)
        out[f"{key}_mean_ratio"] = round(float(n.mean()) / scale, 4)
    out["ref_mitsuba_noise"] = round(np.sqrt(m_noise) / scale, 4)
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("dir", nargs="?")
    ap.add_argument(
        "--check-phase",
        action="store_true",
        help="only check the phase function against a slab's closed form (check_phase)",
    )
    ap.add_argument("--spp", type=int, default=256)
    ap.add_argument("--picture")
    ap.add_argument(
        "--reuse",
        action="store_true",
        help="reuse Mitsuba renders saved in DIR by an earlier run (same grid and spp)",
    )
    ap.add_argument("--only-ss", action="store_true", help="single scattering only")
    ap.add_argument(
        "--blendphase",
        action="store_true",
        help="Mitsuba's own blendphase (biased under MIS in 3.6.4), as references made before",
    )
    args = ap.parse_args()
    global BLENDPHASE
    BLENDPHASE = args.blendphase
    variant = pick_variant()
    if args.check_phase:
        print(json.dumps({"variant": variant, **check_phase()}, indent=1))
        return
    if args.dir is None:
        ap.error("DIR is needed (all but --check-phase)")
    meta = json.load(open(os.path.join(args.dir, "meta.json")))
    w, h = meta["width"], meta["height"]
    grid = read_vol(os.path.join(args.dir, "grid.vol"))
    sw, sh = meta["sky_size"]
    sky = load(args.dir, "sky.f32", (sh, sw, 3))
    n_ss = load(args.dir, "nephele_ss.f32", (h, w, 4))
    n_ms = load(args.dir, "nephele_ms.f32", (h, w, 4))
    alpha = n_ss[..., 3]
    gain = 2.0 ** meta["exposure"]

    out = {"variant": variant, "spp": args.spp}
    ref = {}
    for name, depth in (("ss", 2), ("full", 64))[: 1 if args.only_ss else 2]:
        pair, times = [], []
        for seed in (1, 2):
            # Renders with Mitsuba's `blendphase` keep the names they had; `TwoLobe`'s are
            # marked, so that --reuse never mixes the two.
            tag = "" if args.blendphase else "_twolobe"
            path = os.path.join(args.dir, f"mitsuba_{name}_{args.spp}spp_seed{seed}{tag}.f32")
            if args.reuse and os.path.exists(path):
                img, t = load(args.dir, os.path.basename(path), (h, w, 3)), float("nan")
            else:
                img, t = render(meta, grid, sky, depth, args.spp, seed)
                img.astype("<f4").tofile(path)
            pair.append(img)
            times.append(t)
        (a, b), (ta, tb) = pair, times
        ref[name] = (a, b)
        out[f"seconds_mitsuba_{name}_{args.spp}spp"] = round(ta, 2)
        out[f"seconds_mitsuba_{name}_2x{args.spp}spp"] = round(ta + tb, 2)
    out["seconds_nephele_ss"] = round(meta["nephele_seconds_ss"], 3)
    out["seconds_nephele_ms"] = round(meta["nephele_seconds_ms"], 3)

    # Single scattering: linear luminance over the cloud's pixels.
    cloud = alpha > 0.02
    a_ss, b_ss = (lum(x)[cloud] for x in ref["ss"])

    def rel_rmse(img, pair=None):
        """(relative RMSE with the reference's noise excluded, raw, noise, mean ratio) of the
        linear image `img` (or its luminance over the cloud) against the mean of `pair` (two
        renders with different seeds; default Mitsuba's single scattering)."""
        a, b = pair if pair is not None else (a_ss, b_ss)
        m = 0.5 * (a + b)
        n = img if img.ndim == 1 else lum(img[..., :3])[cloud]
        mse = float(np.mean((n - m) ** 2))
        noise = float(np.mean((a - b) ** 2)) / 4.0  # variance of the mean of two renders
        scale = float(m.mean())
        return (
            round(np.sqrt(max(mse - noise, 0.0)) / scale, 4),
            round(np.sqrt(mse) / scale, 4),
            round(np.sqrt(noise) / scale, 4),
            round(float(n.mean()) / scale, 4),
        )

    rmse, raw, noise, ratio = rel_rmse(n_ss)
    out["ss_rel_rmse"], out["ss_rel_rmse_raw"], out["ss_ref_noise"] = rmse, raw, noise
    out["ss_mean_ratio"] = ratio
    grid_path = os.path.join(args.dir, "nephele_grid_ss.f32")
    if os.path.exists(grid_path):
        n_grid = load(args.dir, "nephele_grid_ss.f32", (h, w, 4))
        out["ss_same_grid_rel_rmse"], _, _, out["ss_same_grid_mean_ratio"] = rel_rmse(n_grid)
    if "full" in ref:
        # The full image (single + multiple scattering) against full transport, per pixel.
        a_full, b_full = (lum(x)[cloud] for x in ref["full"])
        (
            out["full_rel_rmse"],
            out["full_rel_rmse_raw"],
            out["full_ref_noise"],
            out["full_mean_ratio"],
        ) = rel_rmse(n_ms, (a_full, b_full))
        # The multiple-scattering term alone (full minus single scattering, nephele's and
        # Mitsuba's; the noise of the difference of two independent renders per seed).
        n_term = lum(n_ms[..., :3])[cloud] - lum(n_ss[..., :3])[cloud]
        (
            out["ms_rel_rmse"],
            out["ms_rel_rmse_raw"],
            out["ms_ref_noise"],
            out["ms_mean_ratio"],
        ) = rel_rmse(n_term, (a_full - a_ss, b_full - b_ss))
    # Coverage: do both see the same cloud? (background pixels equal the sky in both)
    bg = alpha < 1e-4
    sky_ref = lum(0.5 * (ref["ss"][0] + ref["ss"][1]))[bg]
    out["background_rel_error"] = round(
        float(np.abs(lum(n_ss[..., :3])[bg] - sky_ref).mean() / max(sky_ref.mean(), 1e-9)), 4
    )

    # Looks after tone mapping (as the PNG shows them): mean cloud luminance, base/top.
    opaque = alpha > 0.5
    tm = {
        "nephele_ss": aces(n_ss[..., :3] * gain),
        "nephele_ms": aces(n_ms[..., :3] * gain),
        "mitsuba_ss": aces(0.5 * (ref["ss"][0] + ref["ss"][1]) * gain),
    }
    if "full" in ref:
        tm["mitsuba_full"] = aces(0.5 * (ref["full"][0] + ref["full"][1]) * gain)
    for k, v in tm.items():
        l = lum(v)
        out[f"mean_lum_{k}"] = round(float(l[opaque].mean()), 4)
        out[f"base_top_{k}"] = round(base_top(l, opaque), 4)
    ref_meta = os.path.join(args.dir, "reference.json")
    depth = json.load(open(ref_meta)).get("max_depth", 64) if os.path.exists(ref_meta) else 64
    against = "ss" if depth == 2 else "full"
    if against in ref:
        out.update(reference_comparison(args.dir, (h, w, 4), ref[against], cloud))
    print(json.dumps(out, indent=1))

    if args.picture and "full" in ref:
        top = np.concatenate([tm["nephele_ss"], tm["mitsuba_ss"]], axis=1)
        bottom = np.concatenate([tm["nephele_ms"], tm["mitsuba_full"]], axis=1)
        sheet = srgb8(np.concatenate([top, bottom], axis=0))
        mi.Bitmap(np.ascontiguousarray(sheet)).write(args.picture)


if __name__ == "__main__":
    main()
