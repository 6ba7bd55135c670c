"""Errors a TD can act on: each names what is wrong and where, and survives pickling."""

import multiprocessing
import pickle

import numpy as np
import pytest

import nephele

BASE = {"target": {"Fit": {"mesh": "builtin:duck"}}}


# --- Scene.from_dict -------------------------------------------------------------------------

def test_from_dict_nan_names_the_key_path():
    with pytest.raises(nephele.SceneError) as e:
        nephele.Scene.from_dict({**BASE, "shot": {"fps": float("nan")}}, path="d.ron")
    assert str(e.value) == "d.ron: shot.fps: got NaN; scene values must be finite numbers"
    assert (e.value.path, e.value.field, e.value.line) == ("d.ron", "shot.fps", None)
    with pytest.raises(nephele.SceneError) as e:
        nephele.Scene.from_dict({**BASE, "frames": [1, float("inf")]}, path="d.ron")
    assert e.value.field == "frames[1]" and "got inf" in str(e.value)
    # Not plain data: the key path and the type.
    with pytest.raises(nephele.SceneError) as e:
        nephele.Scene.from_dict({**BASE, "camera": {"Auto": {"fov_deg": np.float16(3)}}})
    assert e.value.field == "camera.Auto.fov_deg" and "float16" in str(e.value)


def test_from_dict_wrong_type_names_the_key_and_what_it_takes():
    with pytest.raises(nephele.SceneError) as e:
        nephele.Scene.from_dict({"target": 5}, path="d.ron")
    msg = str(e.value)
    assert e.value.field == "target" and msg.startswith("d.ron: target: ")
    assert "integer `5`" in msg, msg
    assert "`Model`" in msg and "`Fit`" in msg and "one-key dict" in msg, msg
    assert "expected value" not in msg
    # A nested enum and a plain wrong type are named at their path.
    with pytest.raises(nephele.SceneError) as e:
        nephele.Scene.from_dict({**BASE, "animation": 3})
    assert e.value.field == "animation" and "`Diffusion`" in str(e.value), str(e.value)
    with pytest.raises(nephele.SceneError) as e:
        nephele.Scene.from_dict({**BASE, "shot": {"width": "64"}})
    assert e.value.field == "shot.width" and "expected u32" in str(e.value), str(e.value)


# --- fit arguments ---------------------------------------------------------------------------

def test_fit_counts_out_of_range_are_value_errors_naming_the_parameter():
    with pytest.raises(ValueError) as e:
        nephele.fit("builtin:duck", blobs=-5)
    assert str(e.value) == "fit: blobs must be an integer ≥ 1, got -5"
    assert not isinstance(e.value, OverflowError)
    with pytest.raises(ValueError, match="fit: samples must be an integer ≥ 100, got -5"):
        nephele.fit("builtin:duck", samples=-5)
    # A count the library's types hold is the library's to judge: a FitError with its rule.
    with pytest.raises(nephele.FitError, match="blobs must be at least 1, got 0"):
        nephele.fit("builtin:duck", blobs=0)
    with pytest.raises(ValueError, match=r"fit: seed must be an integer ≥ 0, got -1"):
        nephele.fit("builtin:duck", seed=-1)
    with pytest.raises(ValueError, match=f"fit: candidates must be an integer ≥ 1, got {10**30}"):
        nephele.fit("builtin:duck", candidates=10**30)
    with pytest.raises(TypeError, match=r"fit: blobs must be an integer ≥ 1, got 2\.5 \(float\)"):
        nephele.fit("builtin:duck", blobs=2.5)


def test_a_frame_outside_the_shot_is_a_value_error(tiny_scene):
    shot = nephele.Scene.load(tiny_scene).shot()
    for frame in (-1, 9, 2**40):
        with pytest.raises(ValueError, match=rf"frame {frame} is outside the shot \(frames 1..3\)"):
            shot.render(frame)


# --- Model.from_blobs ------------------------------------------------------------------------

def test_bad_blobs_name_row_and_column_never_a_rust_dump(duck_model):
    model, _ = duck_model
    cases = [
        ((3, 1), np.nan, "row 3, cy is NaN (every value must be finite)", ["cy"]),
        ((0, 9), -0.5, "row 0, sz is -0.5 (a semi-axis must be ≥ 0)", ["sz"]),
        ((5, 2), np.inf, "row 5, cz is inf (every value must be finite)", ["cz"]),
        ((1, 10), -1.0, "row 1, a is -1 (it must be > 0)", ["a"]),
    ]
    for (row, col), value, message, columns in cases:
        bad = model.blobs.copy()
        bad[row, col] = value
        with pytest.raises(nephele.ModelError) as e:
            nephele.Model.from_blobs(bad)
        assert str(e.value) == f"Model.from_blobs: {message}"
        assert (e.value.row, e.value.columns) == (row, columns)
        for rust in ("Blob {", "DVec3", "DQuat"):
            assert rust not in str(e.value)


def test_from_blobs_refuses_arrays_of_non_real_numbers(duck_model):
    model, _ = duck_model
    good = model.blobs
    for bad, dtype in ((good.astype(str), "<U"), (good.astype(complex), "complex128"),
                       (good > 0, "bool"), (good.astype(object), "object")):
        with pytest.raises(TypeError, match="Model.from_blobs: blobs must be real numbers") as e:
            nephele.Model.from_blobs(bad)
        assert dtype in str(e.value)
    with pytest.raises(TypeError, match="real numbers"):
        nephele.Model.from_blobs([["1.0"] * 12])
    # Integers are real numbers.
    ints = np.zeros((1, 12), dtype=np.int64)
    ints[0, 6] = ints[0, 7:11] = 1
    assert nephele.Model.from_blobs(ints).blobs.dtype == np.float64


# --- pickling --------------------------------------------------------------------------------

def _scene_error():
    try:
        nephele.Scene.from_str("Scene(\n    target: 5,\n)\n", path="bad.ron")
    except nephele.SceneError as e:
        return e
    raise AssertionError("no SceneError")


def _raise_scene_error(_):
    """A worker's failure: a located SceneError."""
    raise _scene_error()


def test_exceptions_pickle_with_their_attributes(duck_model):
    e = _scene_error()
    again = pickle.loads(pickle.dumps(e))
    assert type(again) is nephele.SceneError and str(again) == str(e)
    assert (again.path, again.line, again.column, again.field) == (e.path, e.line, e.column,
                                                                   e.field)
    assert again.line == 2
    assert type(e).__module__ == "nephele"
    model, _ = duck_model
    bad = model.blobs.copy()
    bad[0, 0] = np.nan
    with pytest.raises(nephele.ModelError) as m:
        nephele.Model.from_blobs(bad)
    again = pickle.loads(pickle.dumps(m.value))
    assert (type(again), str(again), again.row) == (nephele.ModelError, str(m.value), 0)
    for cls in (nephele.NepheleError, nephele.MeshError, nephele.FitError):
        again = pickle.loads(pickle.dumps(cls("x")))
        assert type(again) is cls and str(again) == "x"
    with pytest.raises(nephele.SceneError) as d:
        nephele.Scene.from_dict({"target": 5})
    assert pickle.loads(pickle.dumps(d.value)).field == "target"


def test_a_worker_error_reaches_its_parent():
    ctx = multiprocessing.get_context("spawn")
    with ctx.Pool(1) as pool:
        with pytest.raises(nephele.SceneError) as e:
            pool.map(_raise_scene_error, [0])
    want = _scene_error()
    assert str(e.value) == str(want)
    assert (e.value.path, e.value.line, e.value.column) == (want.path, want.line, want.column)
