"""Type stubs of the extension module `nephele._nephele` (re-exported by `nephele`).

The TypedDicts (`Layers`, `Mattes`, `ProgressReport`, `ShotReport`) exist for type checkers
only: at run time these are plain dicts (import them under `typing.TYPE_CHECKING`)."""

import os
import sys
from typing import (
    Any, Callable, Dict, Iterator, List, Mapping, Optional, Sequence, Tuple, Union, final,
)

if sys.version_info >= (3, 11):
    from typing import Literal, NotRequired, TypedDict
else:
    from typing_extensions import Literal, NotRequired, TypedDict

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
class ModelError(NepheleError):
    """A model file or blob array that is not a usable model. From ``Model.from_blobs``, a bad
    blob also sets ``row`` (0-based) and ``columns`` (names of ``Model.COLUMNS``)."""
    row: int
    columns: List[str]

_Bounds = Tuple[Tuple[float, float, float], Tuple[float, float, float]]

@final
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
    def bounds(self) -> _Bounds: ...
    def __len__(self) -> int: ...
    def save(self, path: _Path) -> None: ...
    @staticmethod
    def load(path: _Path) -> "Model": ...
    @staticmethod
    def from_blobs(
        blobs: npt.ArrayLike,
        threshold: float = 1.0,
        source: str = "python",
        seed: int = 0,
        primitive: Literal["ellipsoid", "sphere"] = "ellipsoid",
        bounds: Optional[_Bounds] = None,
    ) -> "Model":
        """The model of an (N, 12) array with ``COLUMNS`` (the inverse of ``blobs``, exact);
        checked as a model file is (``ModelError`` naming the row and column); an array of
        anything but real numbers is a ``TypeError``, a wrong shape a ``ValueError``."""

def fit(
    mesh: _Path,
    blobs: Optional[int] = None,
    seed: Optional[int] = None,
    candidates: Optional[int] = None,
    samples: Optional[int] = None,
    primitive: Literal["ellipsoid", "sphere"] = "ellipsoid",
    progress: Optional[Callable[[str], Any]] = None,
) -> Model:
    """Fit a blob model to a mesh file or ``builtin:NAME``; ``progress(stage)`` gets
    ``"load"``, ``"winding"``, ``"samples"``, ``"grow"``, ``"select"``, ``"optimise"``,
    ``"done"`` as each starts (an exception it raises is raised once the fit is over)."""

@final
class Scene:
    @staticmethod
    def load(
        path: _Path, set: Sequence[str] = (), size: Optional[str] = None
    ) -> "Scene":
        """Read, parse and validate a scene file, with the CLI's overrides: ``size``
        (``"1920x1080"``, as ``--size``) first, then each ``set`` (``"KEY=VALUE"``, as
        ``--set``) in order."""
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

class Mattes(TypedDict):
    """A frame's Cryptomatte layer (``render_passes(frame)["mattes"]``)."""
    layer: str
    """The layer name, ``"CryptoObject"``."""
    key: str
    """The EXR header's key of the layer (``cryptomatte/<key>/…``)."""
    names: List[str]
    """The shot's matte names (one per piece of the animation); a matte's index is its place."""
    ids: List[float]
    """Each name's Cryptomatte id (MurmurHash3 as float32)."""
    manifest: Dict[str, str]
    """Name -> the id's bits as 8 hex digits, the EXR's manifest."""
    index: npt.NDArray[np.int32]
    """(H, W, 6): each rank's matte (into ``names``), -1 where empty."""
    id: npt.NDArray[np.float32]
    """(H, W, 6): each rank's id as the EXR stores it (ranks 2s, 2s+1 in ``{layer}0s.R``, ``.B``; 0 where empty)."""
    coverage: npt.NDArray[np.float32]
    """(H, W, 6): each rank's coverage, largest first, summing to the pixel's alpha."""

class Layers(TypedDict):
    """``render_passes``' layers; the passes and mattes only when the shot has passes."""
    rgba: npt.NDArray[np.float32]
    depth: npt.NDArray[np.float32]
    sun: NotRequired[npt.NDArray[np.float32]]
    sky: NotRequired[npt.NDArray[np.float32]]
    multiple: NotRequired[npt.NDArray[np.float32]]
    mattes: NotRequired[Mattes]

class ProgressReport(TypedDict):
    """What ``render_all``'s ``progress`` gets after each frame."""
    frame: int
    of: int
    skipped: bool
    seconds: float
    index: int
    count: int

class ShotReport(TypedDict):
    dir: str
    rendered: int
    skipped: int
    out_of_date: List[Tuple[str, int]]

_Frames = Union[None, str, int, Sequence[int]]

@final
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
    def render_passes(self, frame: int) -> Layers:
        """``rgba`` (H, W, 4), ``depth`` (H, W), and with passes ``sun``, ``sky``,
        ``multiple`` (H, W, 3) and the Cryptomatte ``mattes``."""
    def frames_iter(self, frames: _Frames = None, layers: bool = False) -> "FrameIter":
        """``(frame, image)`` in order through one renderer (holds and still clouds reused);
        ``image`` is ``render``'s array, or ``render_passes``' dict with ``layers=True``."""
    def blobs(self, frame: int) -> npt.NDArray[np.float64]: ...
    def camera(self, frame: int) -> Dict[str, Any]: ...
    def render_all(
        self, progress: Optional[Callable[[ProgressReport], Any]] = None
    ) -> ShotReport: ...

@final
class FrameIter(Iterator[Tuple[int, Any]]):
    """``Shot.frames_iter``'s iterator: each ``next()`` renders the next frame."""
    def __iter__(self) -> "FrameIter": ...
    def __next__(self) -> Tuple[int, Any]: ...
    def __len__(self) -> int:
        """Frames left."""
    @property
    def frames(self) -> List[int]: ...
    @property
    def reuse(self) -> Optional[Literal["frame", "light_grid", "buffers"]]:
        """What the last frame took from the one before (``None`` before the first)."""

def version() -> str: ...

def main(argv: Sequence[str]) -> int:
    """Run the ``nephele`` command (``argv`` as ``sys.argv``: the program's name first); the
    exit code. The wheel's ``nephele`` script calls it."""
