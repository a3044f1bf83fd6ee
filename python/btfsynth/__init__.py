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

Errors are :class:`btfsynth.Error` (see :mod:`btfsynth.errors`); batch runs on Dask are in
:mod:`btfsynth.batch`.
"""

import functools as _functools

from . import _native
from ._native import Analysis, Plane, Stack, Surface, presets, render
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
synthesize_surface = _with_progress(_native.synthesize_surface)
export_gltf = _with_progress(_native.export_gltf)

__all__ = [
    "Analysis",
    "Error",
    "FileError",
    "InternalError",
    "OutputError",
    "ParameterError",
    "Plane",
    "Stack",
    "Surface",
    "TooLargeError",
    "UnavailableError",
    "analyze",
    "export_gltf",
    "presets",
    "render",
    "synthesize_plane",
    "synthesize_surface",
]
