"""The exceptions btfsynth raises: every library error is a :class:`Error`.

Each carries the library's one-line message (the line the CLI prints after ``error:``).
Parameter errors are also ``ValueError`` (``param`` names the parameter), file errors also
``OSError`` (``filename`` names the file), so code that catches the built-in classes keeps
working.
"""


class Error(Exception):
    """Base class of every btfsynth error."""


class ParameterError(Error, ValueError):
    """A value out of its range or not fitting the input at hand (a recipe that cannot run,
    a mesh that cannot be remeshed, an analysis of another sample). ``param`` names the
    parameter where one is at fault."""

    param = None


class TooLargeError(ParameterError):
    """The work would need more than a limit allows (memory, vertices); the message says
    how to ask for less."""


class FileError(Error, OSError):
    """A file that cannot be read or written, or whose contents are not what it claims to
    be. ``filename`` names it."""

    def __str__(self):
        # The library's line, not OSError's "[Errno None] None: 'filename'".
        return str(self.args[0]) if self.args else ""


class OutputError(FileError):
    """An output that exists (and overwriting was not allowed) or cannot go where asked."""


class UnavailableError(Error, RuntimeError):
    """The work cannot be done the way it was asked (a GPU that is missing), but another
    way works; the message says which."""


class InternalError(Error, RuntimeError):
    """A broken invariant of the library's own: a bug, please report it."""


__all__ = [
    "Error",
    "ParameterError",
    "TooLargeError",
    "FileError",
    "OutputError",
    "UnavailableError",
    "InternalError",
]
