"""Type stubs of the extension module (see btfsynth/__init__.py for the package)."""

import os
from typing import Any, Callable, Literal, Optional, Tuple, Union

import numpy as np
import numpy.typing as npt

# A callable progress(done, total, stage); the package's wrappers also take "tqdm" or True.
Progress = Union[None, Callable[[int, int, str], Any], Literal["tqdm", True]]
PathLike = Union[str, os.PathLike]

__version__: str

class Stack:
    """A BTF stack: ``len`` images of ``height × width`` linear RGB with their view and
    light directions (θ, φ in degrees)."""

    @staticmethod
    def from_arrays(images: npt.NDArray[np.float32], view: npt.ArrayLike, light: npt.ArrayLike) -> "Stack": ...
    @staticmethod
    def from_image(image: npt.NDArray[Any]) -> "Stack": ...
    @staticmethod
    def open(path: PathLike, crop: Optional[Tuple[int, int, int, int]] = None, progress: Progress = None) -> "Stack": ...
    @property
    def width(self) -> int: ...
    @property
    def height(self) -> int: ...
    def __len__(self) -> int: ...
    @property
    def images(self) -> npt.NDArray[np.float32]: ...
    @property
    def view(self) -> npt.NDArray[np.float32]: ...
    @property
    def light(self) -> npt.NDArray[np.float32]: ...

class Analysis:
    """The texton analysis of a stack; picklable, shared by every synthesis made from it."""

    @staticmethod
    def load(dir: PathLike) -> "Analysis": ...
    def save(self, dir: PathLike, overwrite: bool = False) -> str: ...
    @property
    def levels(self) -> list[Tuple[int, int]]: ...
    @property
    def textons(self) -> list[int]: ...
    @property
    def sample_shape(self) -> Tuple[int, int, int]: ...
    @property
    def k(self) -> int: ...
    @property
    def manifest(self) -> dict[str, Any]: ...
    def texton_map(self, level: int = 0) -> npt.NDArray[np.uint16]: ...
    def gamma(self, level: int = 0) -> npt.NDArray[np.float32]: ...
    def knn(self, level: int = 0) -> npt.NDArray[np.uint32]: ...

class Plane:
    """A synthesized plane: per texel the sample texel it copies and its texton."""

    @property
    def uv(self) -> npt.NDArray[np.int32]: ...
    @property
    def textons(self) -> npt.NDArray[np.uint16]: ...
    @property
    def shape(self) -> Tuple[int, int]: ...
    @property
    def tileable(self) -> bool: ...
    @property
    def reports(self) -> list[dict[str, Any]]: ...
    @property
    def params(self) -> dict[str, Any]: ...
    def image(self, view: Optional[Tuple[float, float]] = None, light: Optional[Tuple[float, float]] = None) -> npt.NDArray[np.float32]: ...

class Surface:
    """A synthesized surface: the remeshed mesh with a sample texel, texton and frame per vertex."""

    @property
    def vertices(self) -> npt.NDArray[np.float32]: ...
    @property
    def faces(self) -> npt.NDArray[np.uint32]: ...
    @property
    def uv(self) -> npt.NDArray[np.int32]: ...
    @property
    def subtexel(self) -> npt.NDArray[np.float32]: ...
    @property
    def textons(self) -> npt.NDArray[np.uint16]: ...
    @property
    def frames(self) -> npt.NDArray[np.float32]: ...
    @property
    def texel(self) -> float: ...
    @property
    def reports(self) -> list[dict[str, Any]]: ...
    @property
    def params(self) -> dict[str, Any]: ...
    def save_ply(self, path: PathLike, overwrite: bool = False) -> str: ...

class PatchMap:
    """A pattern-mapped mesh (``method="soler2002"``): the mesh as given, with the sample
    texel at every face corner and the patch that textured each face."""

    @property
    def vertices(self) -> npt.NDArray[np.float32]: ...
    @property
    def faces(self) -> npt.NDArray[np.uint32]: ...
    @property
    def corner_uv(self) -> npt.NDArray[np.float32]: ...
    @property
    def cluster(self) -> npt.NDArray[np.uint32]: ...
    @property
    def level(self) -> npt.NDArray[np.uint8]: ...
    @property
    def texel(self) -> float: ...
    @property
    def report(self) -> dict[str, Any]: ...
    @property
    def params(self) -> dict[str, Any]: ...
    def save(self, path: PathLike, overwrite: bool = False) -> str: ...

def analyze(
    stack: Union[Stack, PathLike],
    *,
    textons: int = 400,
    selected: int = 400,
    levels: int = 3,
    k: int = 11,
    neighborhood: int = 5,
    tileable: bool = False,
    basis: int = 32,
    appearance_dims: int = 16,
    seed: int = 0,
    filters: Optional[PathLike] = None,
    crop: Optional[Tuple[int, int, int, int]] = None,
    progress: Progress = None,
) -> Analysis: ...
def synthesize_plane(
    analysis: Analysis,
    size: Tuple[int, int],
    *,
    preset: str = "appearance",
    recipe: Optional[dict[str, Any]] = None,
    seed: int = 0,
    tileable: bool = False,
    levels: Optional[int] = None,
    k: Optional[int] = None,
    neighborhood: int = 7,
    search: str = "kcoherence",
    progress: Progress = None,
) -> Plane: ...
def synthesize_surface(
    analysis: Analysis,
    mesh: Union[PathLike, npt.ArrayLike],
    faces: Optional[npt.ArrayLike] = None,
    *,
    vertices: Optional[int] = None,
    texels_across: Optional[float] = None,
    scale: Optional[float] = None,
    preset: str = "appearance",
    recipe: Optional[dict[str, Any]] = None,
    seed: int = 0,
    levels: Optional[int] = None,
    k: Optional[int] = None,
    neighborhood: int = 7,
    search: str = "kcoherence",
    orient: str = "smooth",
    progress: Progress = None,
) -> Surface: ...
def map_patches(
    analysis: Analysis,
    mesh: Union[PathLike, npt.ArrayLike],
    faces: Optional[npt.ArrayLike] = None,
    *,
    scale: Optional[float] = None,
    texels_across: Optional[float] = None,
    seed: int = 0,
    rotations: int = 19,
    band: float = 6.0,
    max_distortion: float = 0.1,
    fit_threshold: float = 0.3,
    colour_space: Literal["lab", "hsv", "rgb", "appearance"] = "lab",
    relax: bool = True,
    keep_borders: bool = False,
    first_face: Optional[int] = None,
    orientation: Optional[float] = None,
    progress: Progress = None,
) -> PatchMap: ...
def render(
    surface: Union[Surface, PatchMap],
    material: Union[Analysis, Stack, None] = None,
    *,
    size: Tuple[int, int] = (512, 512),
    view: Tuple[float, float] = (70.0, 0.0),
    light: Tuple[float, float] = (45.0, 45.0),
    env: Optional[str] = None,
    ambient: float = 0.0,
    spp: int = 4,
    shadows: bool = True,
    mode: Literal["pixel", "vertex"] = "pixel",
    orthographic: bool = False,
) -> npt.NDArray[np.float32]: ...
def export_gltf(
    surface: Surface,
    path: Optional[PathLike] = None,
    *,
    size: Optional[int] = None,
    light: Optional[Tuple[float, float]] = None,
    vertex_colors: bool = False,
    name: Optional[str] = None,
    overwrite: bool = False,
    progress: Progress = None,
) -> bytes: ...
def presets() -> list[dict[str, Any]]: ...
def _running() -> int: ...
def _analysis_from_files(files: dict[str, bytes]) -> Analysis: ...
