"""Type stubs of gridrt's compiled module (see the package docstring)."""

from os import PathLike
from typing import Any, Dict, Literal, Optional, Sequence, Tuple, TypedDict, Union

import numpy as np
import numpy.typing as npt

Subdivision = Literal["loop", "flat"]
Mode = Literal["grid", "triangles"]
BackendName = Literal["auto", "cpu", "gpu"]
ShadingName = Literal["eye", "normal", "primitive", "ao", "lit", "depth", "cost", "level"]
Point = Union[Sequence[float], npt.NDArray[np.floating]]

class Camera(TypedDict, total=False):
    """The CLI's camera options, in the mesh file's units; what is left out is chosen from the
    mesh's bounds (the whole mesh in view, from the front-right, somewhat above)."""

    eye: Point
    target: Point
    up: Point
    fov: float
    azimuth: float
    elevation: float
    distance: float

class GridrtError(Exception):
    """What gridrt refuses or fails at, with the CLI's one-line message."""

class Hits:
    """The closest hit of each ray, as arrays of one entry per ray."""

    t: npt.NDArray[np.float32]
    """(N,) distance along the ray in units of its direction's length; inf on a miss."""
    prim: npt.NDArray[np.int64]
    """(N,) the base triangle hit; -1 on a miss."""
    micro: npt.NDArray[np.int64]
    """(N,) the micro-triangle within the base triangle; -1 on a miss."""
    u: npt.NDArray[np.float32]
    """(N,) barycentric weight of the micro-triangle's second corner."""
    v: npt.NDArray[np.float32]
    """(N,) barycentric weight of the micro-triangle's third corner."""
    normal: npt.NDArray[np.float32]
    """(N, 3) the micro-triangle's unit geometric normal; zero on a miss."""
    def __len__(self) -> int: ...

class Scene:
    """A mesh built as grids of micro-triangles (or the baseline's triangle list), ready to
    trace on its backend. On a GPU it is uploaded once, when built, and every call after
    traces those buffers; a scene the adapter cannot bind is refused then."""

    @staticmethod
    def from_arrays(
        vertices: npt.ArrayLike,
        faces: npt.ArrayLike,
        *,
        levels: int = 3,
        subdivision: Subdivision = "loop",
        crease_angle: Optional[float] = None,
        mode: Mode = "grid",
        lod: Optional[int] = None,
        backend: BackendName = "auto",
    ) -> Scene:
        """A scene of a mesh given as arrays: vertices (N, 3) float32/float64, faces (M, 3)
        integer indices; options as for `load`."""
    def intersect(
        self,
        origins: npt.NDArray[np.floating],
        directions: npt.NDArray[np.floating],
        t_max: Union[None, float, npt.NDArray[np.floating]] = None,
    ) -> Hits:
        """The closest hit of each ray; origins and directions (N, 3) float32/float64."""
    def occluded(
        self,
        origins: npt.NDArray[np.floating],
        directions: npt.NDArray[np.floating],
        t_max: Union[float, npt.NDArray[np.floating]],
    ) -> npt.NDArray[np.bool_]:
        """Whether anything lies along each ray before t_max."""
    def render(
        self,
        width: int = 640,
        height: int = 480,
        *,
        shading: ShadingName = "eye",
        camera: Optional[Camera] = None,
        ao_samples: int = 16,
    ) -> npt.NDArray[np.uint8]:
        """An image (height, width, 4) of RGBA bytes."""
    def camera_rays(
        self, width: int = 640, height: int = 480, *, camera: Optional[Camera] = None
    ) -> Tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
        """The primary ray of every pixel, row by row from the top: (origins, directions),
        each (height * width, 3)."""
    @property
    def memory(self) -> int:
        """Bytes of the scene's structure."""
    @property
    def backend_kind(self) -> Literal["cpu", "gpu"]: ...
    @property
    def device(self) -> str:
        """One line naming the device."""
    @property
    def bounds(self) -> Tuple[Tuple[float, float, float], Tuple[float, float, float]]:
        """The scene's box (min, max) in the file's units."""

def load(
    path: Union[None, str, PathLike[str]] = None,
    *,
    levels: int = 3,
    subdivision: Subdivision = "loop",
    crease_angle: Optional[float] = None,
    mode: Mode = "grid",
    lod: Optional[int] = None,
    backend: BackendName = "auto",
) -> Scene:
    """Loads a mesh file (.obj, .ply, .gltf, .glb; a displaced micro-mesh as displaced grids)
    or, with no path, the built-in scene, and builds it."""

def write_png(path: Union[str, PathLike[str]], image: npt.NDArray[np.uint8]) -> None:
    """Writes a (height, width, 4) uint8 RGBA image as PNG."""

def bake(
    reference: Union[str, PathLike[str]],
    output: Union[str, PathLike[str]],
    *,
    levels: int = 3,
    base: Union[None, str, PathLike[str]] = None,
    base_triangles: Optional[int] = None,
    fit_rounds: Optional[int] = None,
    compress_values: Optional[float] = None,
    plain_values: bool = False,
    max_bytes: Optional[float] = None,
    max_error: Optional[float] = None,
    within_bytes: Optional[int] = None,
    nv_blocks: bool = False,
    samples: int = 1_000_000,
) -> Dict[str, Any]:
    """Bakes the detailed mesh `reference` into a displaced micro-mesh written to `output`
    (glTF, with its .bin and .bary beside it), as `gridrt bake` does with the same options;
    returns the bake's summary (`gridrt bake --json`'s object) with its notes and warnings."""
