"""Fixtures: the repository's bundled data, the CLI binary to compare with, small analyses."""

import os
import shutil
import struct
import subprocess
import zlib
from pathlib import Path

import numpy as np
import pytest

import btfsynth

ROOT = Path(__file__).resolve().parents[2]
PHOTO = "data/gravel-128.png"
BUNNY = "data/bunny-1k8.obj"
# Small settings so that each comparison with the CLI takes about a second.
ANALYSIS = {"textons": 64, "levels": 2}


def cli_path():
    """The btfsynth binary: $BTFSYNTH_CLI, else the workspace's release build."""
    given = os.environ.get("BTFSYNTH_CLI")
    if given:
        return Path(given)
    return ROOT / "target" / "release" / "btfsynth"


@pytest.fixture(scope="session")
def cli():
    """Runs the CLI in the repository root; skips (one line) where it has not been built,
    unless $BTFSYNTH_CLI names it (CI), where its absence fails."""
    path = cli_path()
    if not path.is_file():
        if os.environ.get("BTFSYNTH_CLI"):
            pytest.fail(f"BTFSYNTH_CLI={path} is not a file")
        pytest.skip(f"the CLI is absent ({path}); cargo build --release builds it")

    def run(*args):
        done = subprocess.run([str(path), "-q", *map(str, args)], cwd=ROOT, capture_output=True, text=True)
        assert done.returncode == 0, done.stderr
        return done

    return run


@pytest.fixture(autouse=True)
def in_root(monkeypatch):
    """Every test runs in the repository root, where the CLI runs, so recorded paths agree."""
    monkeypatch.chdir(ROOT)


@pytest.fixture(scope="session")
def analysis():
    """The bundled photograph analysed in memory with the small settings."""
    return btfsynth.analyze(PHOTO, **ANALYSIS)


@pytest.fixture(scope="session")
def cli_analysis(cli):
    """The CLI's analysis of the bundled photograph with the small settings, written once
    (relative to the repository root) for every comparison with the CLI."""
    folder = ROOT / "target" / "pytest-scratch" / f"cli-analysis-{os.urandom(4).hex()}"
    cli("analyze", PHOTO, "-o", folder.relative_to(ROOT), *cli_flags(ANALYSIS))
    yield folder.relative_to(ROOT)
    shutil.rmtree(folder, ignore_errors=True)


def cli_flags(values):
    """A dict of settings as the CLI's flags."""
    return [x for k, v in values.items() for x in (f"--{k}", v)]


@pytest.fixture
def scratch():
    """A folder inside the repository's target/ (so relative paths to the analysis hold),
    removed afterwards."""
    folder = ROOT / "target" / "pytest-scratch" / os.urandom(4).hex()
    folder.mkdir(parents=True)
    yield folder.relative_to(ROOT)
    shutil.rmtree(folder, ignore_errors=True)


def read_png(path):
    """An 8-bit RGB or RGBA PNG's pixels as uint8 [h, w, c] (enough for the CLI's outputs)."""
    data = Path(path).read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    pos, idat, header = 8, b"", None
    while pos < len(data):
        (length,) = struct.unpack(">I", data[pos : pos + 4])
        kind, body = data[pos + 4 : pos + 8], data[pos + 8 : pos + 8 + length]
        if kind == b"IHDR":
            header = struct.unpack(">IIBBBBB", body)
        elif kind == b"IDAT":
            idat += body
        pos += 12 + length
    w, h, depth, colour, _, _, interlace = header
    assert depth == 8 and colour in (2, 6) and interlace == 0, header
    c = 3 if colour == 2 else 4
    raw = zlib.decompress(idat)
    out = np.zeros((h, w * c), np.int32)
    stride = w * c + 1
    for y in range(h):
        kind, line = raw[y * stride], np.frombuffer(raw[y * stride + 1 : (y + 1) * stride], np.uint8).astype(np.int32)
        up = out[y - 1] if y else np.zeros(w * c, np.int32)
        row = np.zeros(w * c, np.int32)
        for x in range(w * c):
            left = row[x - c] if x >= c else 0
            corner = up[x - c] if x >= c else 0
            if kind == 0:
                pred = 0
            elif kind == 1:
                pred = left
            elif kind == 2:
                pred = up[x]
            elif kind == 3:
                pred = (left + up[x]) // 2
            else:
                p = left + up[x] - corner
                pa, pb, pc = abs(p - left), abs(p - up[x]), abs(p - corner)
                pred = left if pa <= pb and pa <= pc else (up[x] if pb <= pc else corner)
            row[x] = (line[x] + pred) & 0xFF
        out[y] = row
    return out.reshape(h, w, c).astype(np.uint8)


def to_srgb8(linear):
    """Linear RGB in [0, 1] as 8-bit sRGB, the CLI's pictures' curve."""
    c = np.clip(linear.astype(np.float64), 0.0, 1.0)
    s = np.where(c <= 0.0031308, 12.92 * c, 1.055 * np.power(c, 1 / 2.4) - 0.055)
    return np.round(s * 255.0).astype(np.uint8)
