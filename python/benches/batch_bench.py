"""The 12-job batch (3 materials × 2 meshes × 2 seeds) on a 2-worker LocalCluster against
the same jobs one after another in one process. A benchmark, not a test.

    python python/benches/batch_bench.py OUT_DIR [--shared ../shared/data]

Each run writes into a fresh folder under OUT_DIR; a second Dask run over the first's folder
shows the skipping. Prints one line per run.
"""

import argparse
import shutil
import time
from pathlib import Path

from btfsynth import batch


def jobs(shared: Path):
    materials = ["data/gravel-128.png", str(shared / "textures/skimage-brick.png"), str(shared / "textures/gimp-Stone_stone33.png")]
    meshes = ["data/bunny-1k8.obj", str(shared / "meshes/teapot.obj")]
    return batch.jobs_for(
        materials,
        meshes,
        seeds=[0, 1],
        analysis={"crop": (0, 0, 128, 128), "textons": 100, "levels": 2},
        vertices=5_000,
        render_size=128,
        export_size=128,
    )


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("out", type=Path)
    parser.add_argument("--shared", type=Path, default=Path("../shared/data"))
    parser.add_argument("--runs", type=int, default=1)
    args = parser.parse_args()
    todo = jobs(args.shared)
    assert len(todo) == 12
    for r in range(args.runs):
        for name, run in [("dask", lambda out: batch.run(todo, out, workers=2)), ("sequential", lambda out: batch.run_sequential(todo, out))]:
            out = args.out / f"{name}-{r}"
            shutil.rmtree(out, ignore_errors=True)
            started = time.perf_counter()
            report = run(out)
            print(f"{name} run {r}: {time.perf_counter() - started:.1f} s wall; {report}", flush=True)
        started = time.perf_counter()
        again = batch.run(todo, args.out / f"dask-{r}", workers=2)
        print(f"dask re-run {r}: {time.perf_counter() - started:.1f} s wall; {again}", flush=True)


if __name__ == "__main__":
    main()
