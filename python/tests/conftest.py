"""Shared fixtures: the repository, the nephele CLI, a small fitted duck and a tiny scene."""

import os
import subprocess
from pathlib import Path

import numpy as np
import pytest

import nephele

REPO = Path(__file__).resolve().parents[2]


def cli_path():
    """The `nephele` binary: $NEPHELE_BIN, else the repository's target/release/nephele."""
    env = os.environ.get("NEPHELE_BIN")
    path = Path(env) if env else REPO / "target" / "release" / "nephele"
    if not path.exists():
        if env:
            pytest.fail(f"NEPHELE_BIN={env} does not exist")
        pytest.skip(f"no nephele binary at {path}: build it with `cargo build --release` "
                    "(python/ci.sh does) or set NEPHELE_BIN")
    return path


@pytest.fixture(scope="session")
def cli():
    path = cli_path()

    def run(*args, cwd=None, check=True):
        proc = subprocess.run([str(path), *map(str, args)], cwd=cwd, capture_output=True,
                              text=True)
        if check and proc.returncode != 0:
            raise AssertionError(f"nephele {' '.join(map(str, args))} failed:\n{proc.stderr}")
        return proc

    return run


@pytest.fixture(scope="session")
def duck_model(tmp_path_factory):
    """A small duck (fast to fit), saved as a model file."""
    model = nephele.fit("builtin:duck", blobs=60, samples=5000, candidates=500, seed=3)
    path = tmp_path_factory.mktemp("model") / "duck.ron"
    model.save(path)
    return model, path


def tiny_scene_text(model_path, shutter=0.0, extra="", seconds=0.125, hold=0.0, orbit=20.0):
    """A 48×27 diffusion shot of `model_path` at preview quality: 3 frames at 24 fps by
    default, the cloud holding still for its last `hold` seconds, the camera orbiting `orbit`
    degrees over the shot."""
    return f"""Scene(
    target: Model("{model_path}"),
    animation: Diffusion((grow_seconds: 0.05, final_grow_seconds: 0.05, hold_seconds: {hold})),
    camera: Auto((azimuth_deg: 35.0, elevation_deg: 15.0, distance: 0.9, fov_deg: 35.0, orbit_deg: {orbit})),
    shot: (width: 48, height: 27, fps: 24, seconds: {seconds}, shutter: {shutter}),
    quality: Preview,
    output: (formats: [Exr]{extra}),
    seed: 5,
)
"""


@pytest.fixture
def tiny_scene(tmp_path, duck_model):
    """A tiny scene file beside a copy of the duck model (relative target path)."""
    _, model_path = duck_model
    (tmp_path / "duck.ron").write_bytes(Path(model_path).read_bytes())
    path = tmp_path / "tiny.ron"
    path.write_text(tiny_scene_text("duck.ron"))
    return path


def read_exr(path):
    """Channels (name -> 2D array) and header of an EXR, read by OpenEXR's own module (the
    test skips when the OpenEXR package is missing; python/ci.sh installs it)."""
    OpenEXR = pytest.importorskip(
        "OpenEXR", reason="the OpenEXR package (pip install OpenEXR) reads the CLI's frames")
    with OpenEXR.File(str(path), separate_channels=True) as f:
        channels = {name: np.array(c.pixels) for name, c in f.channels().items()}
        header = dict(f.header())
    return channels, header


def exr_rgba(channels):
    """The (H, W, 4) R, G, B, A of an EXR's channels."""
    return np.stack([channels[c] for c in "RGBA"], axis=-1)


def same_bits(a, b):
    """True when two float32 arrays are equal bit for bit (NaNs and signed zeros included)."""
    a, b = np.asarray(a), np.asarray(b)
    return a.shape == b.shape and a.dtype == b.dtype and np.array_equal(
        a.view(np.uint32), b.view(np.uint32))
