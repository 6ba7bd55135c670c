"""Type stubs of the extension module `nephele._nephele` (re-exported by `nephele`)."""

import os
from typing import Any, Callable, Dict, List, Mapping, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

_Path = Union[str, "os.PathLike[str]"]

class NepheleError(Exception):
    """Base class of every error nephele raises."""

class SceneError(NepheleError):
    """A scene that cannot be read, validated, prepared or rendered.

    ``str(e)`` is the CLI's message (``file:line:column: …`` or ``file: field: …``)."""
    path: Optional[str]
    line: Optional[int]
    column: Optional[int]
    field: Optional[str]

class MeshError(NepheleError): ...
class FitError(NepheleError): ...
class ModelError(NepheleError): ...

class Model:
    """A fitted blob model."""
    COLUMNS: List[str]
    @property
    def blobs(self) -> npt.NDArray[np.float64]:
        """(N, 12): centre x y z, quaternion x y z w, semi-axes x y z, a, b."""
    @property
    def threshold(self) -> float: ...
    @property
    def seed(self) -> int: ...
    @property
    def primitive(self) -> str: ...
    @property
    def source(self) -> str: ...
    @property
    def bounds(self) -> Tuple[Tuple[float, float, float], Tuple[float, float, float]]: ...
    def __len__(self) -> int: ...
    def save(self, path: _Path) -> None: ...
    @staticmethod
    def load(path: _Path) -> "Model": ...

def fit(
    mesh: _Path,
    blobs: Optional[int] = None,
    seed: Optional[int] = None,
    candidates: Optional[int] = None,
    samples: Optional[int] = None,
    primitive: str = "ellipsoid",
    progress: Optional[Callable[[str], Any]] = None,
) -> Model:
    """Fit a blob model to a mesh file or ``builtin:NAME``; ``progress(stage)`` gets
    ``"load"``, ``"fit"``, ``"done"``."""

class Scene:
    @staticmethod
    def load(path: _Path) -> "Scene": ...
    @staticmethod
    def from_str(text: str, path: _Path = "scene.ron") -> "Scene": ...
    @staticmethod
    def from_dict(data: Mapping[str, Any], path: _Path = "scene.ron") -> "Scene": ...
    def to_dict(self) -> Dict[str, Any]: ...
    def to_ron(self) -> str: ...
    @staticmethod
    def _from_json(json: str, path: _Path) -> "Scene": ...
    def _to_json(self) -> str: ...
    @property
    def path(self) -> str: ...
    @property
    def name(self) -> str: ...
    @property
    def output_dir(self) -> str: ...
    def shot(
        self,
        preview: bool = False,
        passes: bool = False,
        frames: Union[None, str, int, Sequence[int]] = None,
        output: Optional[_Path] = None,
        formats: Optional[Sequence[str]] = None,
        force: bool = False,
        region: Optional[str] = None,
        dump_blobs: bool = False,
    ) -> "Shot": ...

class Shot:
    @property
    def frames(self) -> List[int]: ...
    @property
    def all_frames(self) -> List[int]: ...
    @property
    def size(self) -> Tuple[int, int]: ...
    @property
    def fps(self) -> float: ...
    @property
    def shutter(self) -> float: ...
    @property
    def dir(self) -> str: ...
    @property
    def passes(self) -> bool: ...
    @property
    def target(self) -> Model: ...
    def frame_paths(self, frame: int) -> List[str]: ...
    def render(self, frame: int) -> npt.NDArray[np.float32]:
        """(H, W, 4) linear premultiplied RGBA, the EXR's R, G, B, A bit for bit."""
    def render_passes(self, frame: int) -> Dict[str, npt.NDArray[np.float32]]:
        """``rgba`` (H, W, 4), ``depth`` (H, W), and with passes ``sun``, ``sky``,
        ``multiple`` (H, W, 3)."""
    def blobs(self, frame: int) -> npt.NDArray[np.float64]: ...
    def camera(self, frame: int) -> Dict[str, Any]: ...
    def render_all(
        self, progress: Optional[Callable[[Dict[str, Any]], Any]] = None
    ) -> Dict[str, Any]: ...

def version() -> str: ...
