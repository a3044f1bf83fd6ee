from typing import Any, Callable, Literal, Optional, Union

from . import batch as batch
from . import errors as errors
from ._native import Analysis as Analysis
from ._native import Plane as Plane
from ._native import Stack as Stack
from ._native import Surface as Surface
from ._native import analyze as _analyze
from ._native import export_gltf as _export_gltf
from ._native import presets as presets
from ._native import render as render
from ._native import synthesize_plane as _synthesize_plane
from ._native import synthesize_surface as _synthesize_surface
from .errors import Error as Error
from .errors import FileError as FileError
from .errors import InternalError as InternalError
from .errors import OutputError as OutputError
from .errors import ParameterError as ParameterError
from .errors import TooLargeError as TooLargeError
from .errors import UnavailableError as UnavailableError

# The same signatures as the native functions; `progress` also takes "tqdm" (or True).
analyze = _analyze
synthesize_plane = _synthesize_plane
synthesize_surface = _synthesize_surface
export_gltf = _export_gltf
__version__: str
