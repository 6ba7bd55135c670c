"""nephele: fit ellipsoidal blobs to a triangle mesh, and render target-shaped cloud shots.

A thin Python layer over the Rust library (module ``nephele._nephele``)::

    import nephele
    model = nephele.fit("builtin:duck", blobs=120, seed=1)
    model.blobs                      # (N, 12) float64, columns nephele.Model.COLUMNS
    nephele.Model.from_blobs(model.blobs)   # and back
    scene = nephele.Scene.load("scenes/duck-diffusion.ron")
    shot = scene.shot(preview=True)
    rgba = shot.render(shot.frames[0])   # (H, W, 4) float32 linear RGBA, as the EXR
    for frame, rgba in shot.frames_iter():   # a sequence, holds reused
        ...

See README.md beside this package for the whole API and its conventions.
"""

from __future__ import annotations

import json
import os
from typing import Any, Dict, Mapping, Union

import numpy as np

from ._nephele import (
    FitError,
    FrameIter,
    MeshError,
    Model,
    ModelError,
    NepheleError,
    Scene,
    SceneError,
    Shot,
    fit,
    version,
)

__all__ = [
    "FitError",
    "FrameIter",
    "MeshError",
    "Model",
    "ModelError",
    "NepheleError",
    "Scene",
    "SceneError",
    "Shot",
    "fit",
    "matte_coverage",
    "scene_from_dict",
    "scene_to_dict",
    "version",
    "BLOB_COLUMNS",
]

#: Columns of the (N, 12) blob arrays of :attr:`Model.blobs` and :meth:`Shot.blobs`.
BLOB_COLUMNS = tuple(Model.COLUMNS)

PathLike = Union[str, "os.PathLike[str]"]


def matte_coverage(mattes: Mapping[str, Any], name: str) -> "np.ndarray":
    """The (H, W) float32 coverage of the matte ``name`` in a frame's Cryptomatte layer
    (``render_passes(frame)["mattes"]``): the sum of its ranks' coverage, 0 where it is not
    seen. Raises ``KeyError`` for a name the shot does not have."""
    names = list(mattes["names"])
    if name not in names:
        raise KeyError(f"{name!r} is not a matte of this shot (its mattes: {', '.join(names)})")
    k = names.index(name)
    return np.where(mattes["index"] == k, mattes["coverage"], np.float32(0)).sum(
        axis=-1, dtype=np.float32)


def scene_from_dict(data: Mapping[str, Any], path: PathLike = "scene.ron") -> Scene:
    """A scene from a dict that mirrors the RON scene file.

    Structs are dicts of their fields (``{"shot": {"width": 64, "height": 36}}``); enum
    variants are one-key dicts (``{"target": {"Fit": {"mesh": "builtin:duck"}}}``,
    ``{"animation": {"Diffusion": {"hold_seconds": 0.5}}}``, ``{"target": {"Model": "m.ron"}}``)
    or, without data, strings (``"formats": ["Exr", "Vdb"]``); vectors and tuples are lists.
    ``Scene.to_dict()`` gives this form for any scene. The dict is read into the scene file's
    own types, written as RON and loaded like a file named ``path`` (relative target paths
    resolve against its folder; the default output folder is ``renders/<its stem>``), so the
    validation and its messages are the file's.
    """
    try:
        text = json.dumps(data, allow_nan=False)
    except (TypeError, ValueError) as e:
        where, what = _not_plain(data, "") or (".", f"the dict is not plain data: {e}")
        raise _scene_error(os.fspath(path), where or ".", what) from None
    return Scene._from_json(text, os.fspath(path))


def _scene_error(path: str, field: str, what: str) -> SceneError:
    """A ``SceneError`` about the value at key path ``field`` of the scene ``path``, located
    as the extension's are (``path``, ``field``; ``line`` and ``column`` None)."""
    e = SceneError(f"{path}: {field}: {what}")
    e.path, e.line, e.column, e.field = path, None, None, field
    return e


_PLAIN = "dicts, lists, strings, numbers, booleans and None"


def _not_plain(value: Any, where: str):
    """The key path (``shot.fps``, ``output.formats[0]``: the form of ``SceneError.field``) and
    what is wrong of the first value of ``value`` that JSON cannot carry, or None."""
    if isinstance(value, float):
        if value != value:
            return where, "got NaN; scene values must be finite numbers"
        if value in (float("inf"), float("-inf")):
            return where, f"got {value}; scene values must be finite numbers"
        return None
    if value is None or isinstance(value, (str, int)):
        return None
    if isinstance(value, dict):
        for key, item in value.items():
            if not isinstance(key, (str, int, float, bool)) and key is not None:
                return where or ".", f"the key {key!r} is not a string"
            found = _not_plain(item, f"{where}.{key}" if where else str(key))
            if found:
                return found
        return None
    if isinstance(value, (list, tuple)):
        for i, item in enumerate(value):
            found = _not_plain(item, f"{where}[{i}]")
            if found:
                return found
        return None
    return where or ".", (f"got {value!r} ({type(value).__name__}), which is not plain data: "
                          f"a scene dict holds only {_PLAIN}")


def scene_to_dict(scene: Scene) -> Dict[str, Any]:
    """The scene file of ``scene`` as a dict (the form :func:`scene_from_dict` reads)."""
    return json.loads(scene._to_json())


def _from_dict(data: Mapping[str, Any], path: PathLike = "scene.ron") -> Scene:
    return scene_from_dict(data, path)


def _to_dict(self: Scene) -> Dict[str, Any]:
    return scene_to_dict(self)


# Scene.from_dict / scene.to_dict, on the extension class's Python-side namespace.
Scene.from_dict = staticmethod(_from_dict)  # type: ignore[attr-defined]
Scene.to_dict = _to_dict  # type: ignore[attr-defined]
