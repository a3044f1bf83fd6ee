#!/usr/bin/env python3
"""Checks btfsynth's Bonn .btf files against an independent reader, btf-extractor.

btfsynth writes small DFMF files with `convert --to btf` (half and float scalars, colour
models 0 and 11, with and without the rotation block), decodes them back with
`convert FILE.btf -o DIR` (EXR), and compares every image with what btf-extractor
(PyPI; a C++ reader derived from Zdravko Velinov's free BTF library) decodes from the
same file.

Known differences of btf-extractor, undone here before comparing:
- it returns BGR and flips rows (OpenGL's bottom-left origin); btfsynth keeps btflib's
  layout (row 0 on top);
- for colour model 11 it clamps RGB to [0, 1] and computes U as u·Y + ε where btflib
  has u·(Y + ε) (a difference of about 1e-5);
- it rounds angles to 0.1°.
It cannot read files whose light count differs from the view count (it assumes lights²
rows); that variant is checked only for btfsynth's own round trip here, and against
btflib's documented layout by hand-made bytes in tests/formats.rs.

Install: pip install cython poetry-core setuptools OpenEXR
         pip install --no-build-isolation btf-extractor
Run:     python3 scripts/check_btf_extractor.py --btfsynth target/release/btfsynth
"""

import argparse
import json
import os
import subprocess
import sys
import tempfile

import numpy as np
import OpenEXR


def run(btfsynth, *args):
    result = subprocess.run([btfsynth, "-q", *args], capture_output=True, text=True)
    if result.returncode != 0:
        sys.exit(f"btfsynth {' '.join(args)} failed: {result.stderr.strip()}")
    return result.stderr


def read_folder(folder):
    """btfsynth's decoded images: {(θl, φl, θv, φv): float32 RGB array [h, w, 3]}."""
    with open(os.path.join(folder, "btf.json")) as f:
        manifest = json.load(f)
    images = {}
    for entry in manifest["images"]:
        with OpenEXR.File(os.path.join(folder, entry["file"])) as exr:
            rgb = exr.channels()["RGB"].pixels.astype(np.float32)
        images[tuple(entry["light"] + entry["view"])] = rgb
    return images


def angle_distance(a, b):
    """Largest difference of two (θl, φl, θv, φv) tuples in degrees; φ wraps, and is
    irrelevant at θ = 0."""
    worst = 0.0
    for t in (0, 2):
        worst = max(worst, abs(a[t] - b[t]))
        if a[t] > 0.05:
            d = abs(a[t + 1] - b[t + 1]) % 360.0
            worst = max(worst, min(d, 360.0 - d))
    return worst


def compare(path, ours, model):
    from btf_extractor import Ubo2014

    reader = Ubo2014(path)
    angles = list(reader.angles_set)
    if len(angles) != len(ours):
        return f"btf-extractor sees {len(angles)} images, btfsynth {len(ours)}"
    worst = 0.0
    for key, mine in ours.items():
        match = min(angles, key=lambda a: angle_distance(a, key))
        if angle_distance(match, key) > 0.06:
            return f"no btf-extractor image for the angles {key} (nearest {match})"
        theirs = reader.angles_to_image(*match)[::-1, :, ::-1]
        if model == 11:
            mine = np.clip(mine, 0.0, 1.0)
        # f16 rounding of btfsynth's output, plus model 11's ε difference.
        tolerance = 2.0 ** -10 * np.abs(theirs) + (5e-5 if model == 11 else 1e-6)
        excess = np.abs(mine - theirs) - tolerance
        worst = max(worst, float(np.max(np.abs(mine - theirs))))
        if np.any(excess > 0):
            y, x, c = np.unravel_index(np.argmax(excess), excess.shape)
            return f"image {key} pixel ({x}, {y}) channel {c}: btfsynth {mine[y, x, c]}, btf-extractor {theirs[y, x, c]}"
    return worst


def lights_not_views_stack(btfsynth, stack, tmp):
    """A manifest over the first 3 view directions only: 6 lights × 3 views."""
    with open(os.path.join(stack, "btf.json")) as f:
        manifest = json.load(f)
    views = []
    for entry in manifest["images"]:
        if entry["view"] not in views:
            views.append(entry["view"])
    keep = [dict(e, file=os.path.join(os.path.abspath(stack), e["file"])) for e in manifest["images"] if e["view"] in views[:3]]
    # The manifest's folder counts as an input (its images are named relative to it), so the
    # manifest gets a folder of its own, apart from the outputs.
    os.makedirs(os.path.join(tmp, "subset"))
    subset = os.path.join(tmp, "subset", "subset.json")
    with open(subset, "w") as f:
        json.dump({"images": keep}, f)
    return subset, len(keep)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--btfsynth", default="target/release/btfsynth", help="the btfsynth binary")
    args = parser.parse_args()
    passed, failures = 0, 0
    with tempfile.TemporaryDirectory() as tmp:
        stack = os.path.join(tmp, "stack")
        run(args.btfsynth, "gen", "pebbles", "--size", "16", "--directions", "grid:6", "--spp", "1", "-o", stack)
        for precision in ("half", "float"):
            for model in (0, 11):
                for rotation in (True, False):
                    name = f"{precision}-model{model}-{'R' if rotation else 'noR'}"
                    path = os.path.join(tmp, name + ".btf")
                    extra = [] if rotation else ["--no-rotation-block"]
                    run(args.btfsynth, "convert", stack, "-o", path, "--components", "12", "--precision", precision,
                        "--colour-model", str(model), *extra)
                    decoded = os.path.join(tmp, name)
                    run(args.btfsynth, "convert", path, "-o", decoded)
                    result = compare(path, read_folder(decoded), model)
                    if isinstance(result, str):
                        failures += 1
                        print(f"FAIL {name}: {result}")
                    else:
                        passed += 1
                        print(f"ok   {name}: 36 images agree with btf-extractor (largest difference {result:.2e})")
        subset, count = lights_not_views_stack(args.btfsynth, stack, tmp)
        path = os.path.join(tmp, "lights-not-views.btf")
        run(args.btfsynth, "convert", subset, "-o", path, "--components", "18", "--precision", "float")
        probe = subprocess.run([sys.executable, "-c", f"from btf_extractor import Ubo2014; Ubo2014({path!r})"],
                               capture_output=True, text=True)
        verdict = "cannot read it" if probe.returncode != 0 else "opened it"
        run(args.btfsynth, "convert", path, "-o", os.path.join(tmp, "subset-back"))
        back = read_folder(os.path.join(tmp, "subset-back"))
        print(f"note lights ≠ views (6 lights × 3 views, {count} images): btf-extractor {verdict}; "
              f"btfsynth reads back {len(back)} images (checked against btflib's layout in tests/formats.rs)")
        if len(back) != count:
            failures += 1
            print("FAIL lights ≠ views: btfsynth lost images")
    print(f"btf-extractor check: {passed} of {passed + failures} variants agree")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
