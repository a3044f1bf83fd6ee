from typing import Any, Literal, Optional, Tuple, Union, overload

import numpy.typing as npt

from . import batch as batch
from . import errors as errors
from ._native import Analysis as Analysis
from ._native import PatchMap as PatchMap
from ._native import PathLike, Progress
from ._native import Plane as Plane
from ._native import Stack as Stack
from ._native import Surface as Surface
from ._native import analyze as analyze
from ._native import export_gltf as export_gltf
from ._native import map_patches as map_patches
from ._native import presets as presets
from ._native import render as render
from ._native import synthesize_plane as synthesize_plane
from .errors import Error as Error
from .errors import FileError as FileError
from .errors import InternalError as InternalError
from .errors import OutputError as OutputError
from .errors import ParameterError as ParameterError
from .errors import TooLargeError as TooLargeError
from .errors import UnavailableError as UnavailableError

__version__: str
METHODS: Tuple[str, ...]

# method="vertex": the keywords of _native.synthesize_surface; method="soler2002": those of
# map_patches. The wrappers take progress="tqdm" (or True) as well as a callable.
@overload
def synthesize_surface(
    analysis: Analysis,
    mesh: Union[PathLike, npt.ArrayLike],
    faces: Optional[npt.ArrayLike] = None,
    *,
    method: Literal["vertex"] = "vertex",
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
@overload
def synthesize_surface(
    analysis: Analysis,
    mesh: Union[PathLike, npt.ArrayLike],
    faces: Optional[npt.ArrayLike] = None,
    *,
    method: Literal["soler2002"],
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
