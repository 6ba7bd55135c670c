"""Model.from_blobs: the inverse of Model.blobs, checked as a model file is."""

import numpy as np
import pytest

import nephele
from conftest import tiny_scene_text


def test_from_blobs_inverts_blobs_bit_for_bit(duck_model, tmp_path):
    model, _ = duck_model
    b = model.blobs
    again = nephele.Model.from_blobs(b, threshold=model.threshold, source=model.source,
                                     seed=model.seed, bounds=model.bounds)
    assert again.blobs.dtype == np.float64
    assert np.array_equal(again.blobs.view(np.uint64), b.view(np.uint64))
    assert (again.threshold, again.source, again.seed, again.bounds, again.primitive) == (
        model.threshold, model.source, model.seed, model.bounds, model.primitive)
    # Through a model file and back: the same bits again.
    path = tmp_path / "again.ron"
    again.save(path)
    loaded = nephele.Model.load(path)
    assert np.array_equal(loaded.blobs.view(np.uint64), b.view(np.uint64))
    # Any array-like of rows: a list of lists, float32 (converted), a non-contiguous view.
    assert np.array_equal(nephele.Model.from_blobs(b.tolist()).blobs, b)
    assert np.array_equal(nephele.Model.from_blobs(np.asfortranarray(b)).blobs, b)
    assert np.array_equal(nephele.Model.from_blobs(b.astype(np.float32)).blobs,
                          b.astype(np.float32).astype(np.float64))


def test_from_blobs_defaults_and_edits(duck_model):
    model, _ = duck_model
    b = model.blobs.copy()
    m = nephele.Model.from_blobs(b)
    assert (m.threshold, m.source, m.seed, m.primitive) == (1.0, "python", 0, "ellipsoid")
    assert len(m) == len(b)
    # Default bounds: the box of the blobs' ellipsoids, so it holds every centre.
    lo, hi = map(np.array, m.bounds)
    assert (b[:, :3] >= lo).all() and (b[:, :3] <= hi).all()
    # An edit made in numpy is the model's: twice the semi-axes, one blob hidden (b = 0).
    b[:, 7:10] *= 2.0
    b[0, 11] = 0.0
    edited = nephele.Model.from_blobs(b, primitive="sphere")
    assert np.array_equal(edited.blobs, b) and edited.primitive == "sphere"
    assert edited.bounds != m.bounds


def test_from_blobs_checks_like_a_model_file(duck_model):
    model, _ = duck_model
    good = model.blobs
    with pytest.raises(ValueError, match=r"\(N, 12\)"):
        nephele.Model.from_blobs(good[:, :11])
    with pytest.raises(ValueError, match=r"\(N, 12\)"):
        nephele.Model.from_blobs(good[0])
    with pytest.raises(nephele.ModelError, match="no blobs"):
        nephele.Model.from_blobs(np.zeros((0, 12)))
    bad = good.copy()
    bad[2, 3:7] = [0.0, 0.0, 0.0, 2.0]
    with pytest.raises(nephele.ModelError,
                       match="row 2, qx qy qz qw is not a unit quaternion"):
        nephele.Model.from_blobs(bad)
    bad = good.copy()
    bad[4, 10] = 0.0
    with pytest.raises(nephele.ModelError, match=r"row 4, a is 0 \(it must be > 0\)"):
        nephele.Model.from_blobs(bad)
    bad = good.copy()
    bad[1, 0] = np.nan
    with pytest.raises(nephele.ModelError, match="row 1, cx is NaN"):
        nephele.Model.from_blobs(bad)
    with pytest.raises(nephele.ModelError, match="threshold must be positive"):
        nephele.Model.from_blobs(good, threshold=0.0)
    with pytest.raises(ValueError, match="primitive"):
        nephele.Model.from_blobs(good, primitive="cube")
    with pytest.raises(nephele.ModelError) as e:
        nephele.Model.from_blobs(bad)
    assert str(e.value).startswith("Model.from_blobs: ")


def test_a_model_from_blobs_renders_as_the_fitted_one(duck_model, tmp_path):
    """A scene whose target is the round-tripped model has the fitted model's frames."""
    model, model_path = duck_model
    again = tmp_path / "again.ron"
    nephele.Model.from_blobs(model.blobs, threshold=model.threshold).save(again)
    shots = [nephele.Scene.from_str(tiny_scene_text(p), path=tmp_path / f"{n}.ron").shot()
             for n, p in (("fitted", model_path), ("again", again))]
    for frame in (1, 3):
        assert np.array_equal(shots[0].blobs(frame), shots[1].blobs(frame))
    assert np.array_equal(shots[0].render(3).view(np.uint32), shots[1].render(3).view(np.uint32))
