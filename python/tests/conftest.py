"""Shared fixtures: the repository, the nephele CLI, a small fitted duck and a tiny scene."""

import os
import subprocess
from pathlib import Path

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


def tiny_scene_text(model_path, shutter=0.0, extra=""):
    """A 3-frame, 48×27 diffusion shot of `model_path` at preview quality."""
    return f"""Scene(
    target: Model("{model_path}"),
    animation: Diffusion((grow_seconds: 0.05, final_grow_seconds: 0.05, hold_seconds: 0.0)),
    camera: Auto((azimuth_deg: 35.0, elevation_deg: 15.0, distance: 0.9, fov_deg: 35.0, orbit_deg: 20.0)),
    shot: (width: 48, height: 27, fps: 24, seconds: 0.125, shutter: {shutter}),
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
