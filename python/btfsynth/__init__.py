"""btfsynth from Python: analysis and synthesis of bidirectional texture functions (BTFs)
on planes and meshes, rendering and glTF export, numpy in and out.

The functions call the same library as the ``btfsynth`` command line, in memory: the same
inputs and seed give the CLI's values (and, once saved, its files). Long calls release the
GIL, stop on Ctrl-C, and report progress to ``progress=``: a callable
``progress(done, total, stage)``, or ``"tqdm"`` for a bar (``pip install tqdm``).

    >>> import btfsynth, numpy as np
    >>> analysis = btfsynth.analyze("data/gravel-128.png")   # or Stack.from_image(uint8 array)
    >>> plane = btfsynth.synthesize_plane(analysis, (512, 512), seed=0)
    >>> picture = plane.image()                                       # float32 [512, 512, 3]
    >>> surface = btfsynth.synthesize_surface(analysis, "bunny.obj", vertices=20000)
    >>> glb = btfsynth.export_gltf(surface, "bunny.glb")
    >>> patches = btfsynth.synthesize_surface(analysis, "bunny.obj", method="soler2002")
    >>> frame = btfsynth.render(patches, size=(256, 256))          # float32 [256, 256, 4]

Errors are :class:`btfsynth.Error` (see :mod:`btfsynth.errors`); batch runs on Dask are in
:mod:`btfsynth.batch`.
"""

import functools as _functools
import inspect as _inspect

from . import _native
from ._native import Analysis, PatchMap, Plane, Stack, Surface, presets, render
from .errors import (
    Error,
    FileError,
    InternalError,
    OutputError,
    ParameterError,
    TooLargeError,
    UnavailableError,
)

__version__ = _native.__version__


class _TqdmBars:
    """One tqdm bar per stage of a long call."""

    def __init__(self):
        try:
            from tqdm.auto import tqdm
        except ImportError as e:
            raise ImportError('progress="tqdm" needs tqdm: pip install tqdm') from e
        self._tqdm = tqdm
        self._bar = None
        self._stage = None

    def __call__(self, done, total, stage):
        if self._bar is None or stage != self._stage:
            self.close()
            self._bar = self._tqdm(total=total, desc=stage, leave=False)
            self._stage = stage
        self._bar.update(done - self._bar.n)

    def close(self):
        if self._bar is not None:
            self._bar.close()
        self._bar = None


def _with_progress(native):
    """``native`` taking ``progress="tqdm"`` (or ``True``) as well as a callable."""

    @_functools.wraps(native)
    def call(*args, progress=None, **kwargs):
        bars = None
        if progress == "tqdm" or progress is True:
            progress = bars = _TqdmBars()
        elif progress is not None and not callable(progress):
            raise TypeError(f'progress: expected a callable progress(done, total, stage), "tqdm" or None, got {type(progress).__name__}')
        try:
            return native(*args, progress=progress, **kwargs)
        finally:
            if bars is not None:
                bars.close()

    return call


analyze = _with_progress(_native.analyze)
synthesize_plane = _with_progress(_native.synthesize_plane)
map_patches = _with_progress(_native.map_patches)
export_gltf = _with_progress(_native.export_gltf)
_synthesize_vertices = _with_progress(_native.synthesize_surface)

#: The methods ``synthesize_surface`` takes, as the CLI's ``synth --method``.
METHODS = ("vertex", "soler2002")


def synthesize_surface(analysis, mesh, faces=None, *, method="vertex", **options):
    """Synthesizes ``analysis`` on a mesh (a path, or vertices ``[V, 3]`` with ``faces``
    ``[F, 3]``) as ``btfsynth synth ANALYSIS MESH --method METHOD`` does.

    ``method="vertex"`` (the default): the per-vertex engine on a remeshed copy of the mesh;
    returns a :class:`Surface`. Its keywords: ``vertices``, ``texels_across`` or ``scale``
    (the density), ``preset`` or ``recipe``, ``seed``, ``levels``, ``k``, ``neighborhood``,
    ``search``, ``orient``, ``progress`` (see ``help(btfsynth._native.synthesize_surface)``).

    ``method="soler2002"``: hierarchical pattern mapping (Soler et al. 2002) on the mesh as it
    is; returns a :class:`PatchMap`. Its keywords: ``scale`` or ``texels_across``, ``seed``,
    ``rotations``, ``band``, ``max_distortion``, ``fit_threshold``, ``colour_space``,
    ``relax``, ``keep_borders``, ``first_face``, ``orientation``, ``progress`` (see
    ``help(btfsynth.map_patches)``).
    """
    natives = {"vertex": (_synthesize_vertices, _native.synthesize_surface), "soler2002": (map_patches, _native.map_patches)}
    if method in natives:
        call, native = natives[method]
        known = _inspect.signature(native).parameters
        for key in options:
            if key not in known or known[key].kind is not _inspect.Parameter.KEYWORD_ONLY:
                takes = ", ".join(n for n, p in known.items() if p.kind is _inspect.Parameter.KEYWORD_ONLY)
                raise TypeError(f"{key}: not a keyword of method={method!r}; it takes {takes}")
        return call(analysis, mesh, faces, **options)
    error = ParameterError(f"method: '{method}': expected one of {', '.join(METHODS)}")
    error.param = "method"
    raise error

__all__ = [
    "Analysis",
    "Error",
    "FileError",
    "InternalError",
    "METHODS",
    "OutputError",
    "ParameterError",
    "PatchMap",
    "Plane",
    "Stack",
    "Surface",
    "TooLargeError",
    "UnavailableError",
    "analyze",
    "export_gltf",
    "map_patches",
    "presets",
    "render",
    "synthesize_plane",
    "synthesize_surface",
]
