"""The Dask batch on a 2-worker LocalCluster: one failing job is reported while the others
finish, outputs land whole, a re-run skips the finished jobs, each material is analysed once."""

import json
import os

import pytest

from btfsynth import batch
from conftest import BUNNY, PHOTO, ROOT, read_png

pytest.importorskip("dask.distributed", reason="pip install 'btfsynth[dask]'")

SMALL = {"analysis": {"textons": 32, "levels": 2}, "vertices": 1500, "render_size": 48, "export_size": 64}


def test_a_failing_job_is_reported_and_a_rerun_skips_the_finished(scratch):
    out = ROOT / scratch / "batch"
    jobs = batch.jobs_for([PHOTO], [BUNNY], seeds=[0, 1], **SMALL)
    jobs.append(batch.jobs_for([PHOTO], ["data/missing-mesh.obj"], **SMALL)[0])
    # A job of another material, so that two analyses run; its analysis fails.
    jobs.append(batch.jobs_for(["data/missing-photo.png"], [BUNNY], **SMALL)[0])
    first = batch.run(jobs, out, workers=2)
    assert sorted(first.done) == sorted(j.name for j in jobs[:2])
    assert set(first.failed) == {jobs[2].name, jobs[3].name}
    assert "FileError" in first.failed[jobs[2].name] and "missing-mesh.obj" in first.failed[jobs[2].name]
    assert "missing-photo.png" in first.failed[jobs[3].name]
    assert first.analyses == 2
    for job in jobs[:2]:
        folder = out / job.name
        assert sorted(os.listdir(folder)) == ["render.png", "surface.glb", "surface.ply"]
        assert (folder / "surface.glb").read_bytes()[:4] == b"glTF"
        assert read_png(folder / "render.png").shape == (48, 48, 4)
    assert not [p for p in os.listdir(out) if p.startswith(".")], "a temporary folder was left"
    assert json.loads((out / "report.json").read_text())["failed"].keys() == first.failed.keys()
    # The two seeds are two different surfaces.
    plys = [(out / j.name / "surface.ply").read_bytes() for j in jobs[:2]]
    assert plys[0] != plys[1]

    second = batch.run(jobs, out, workers=2)
    assert sorted(second.skipped) == sorted(first.done) and not second.done
    assert set(second.failed) == set(first.failed) and second.analyses == 2
    # Only finished jobs: nothing to run, no cluster started.
    third = batch.run(jobs[:2], out)
    assert sorted(third.skipped) == sorted(first.done) and not third.done and not third.failed


def test_the_sequential_run_writes_the_same_files(scratch):
    jobs = batch.jobs_for([PHOTO], [BUNNY], seeds=[0], **SMALL)
    report = batch.run_sequential(jobs, ROOT / scratch / "seq")
    assert report.done == [jobs[0].name] and report.analyses == 1
    ply = (ROOT / scratch / "seq" / jobs[0].name / "surface.ply").read_bytes()
    assert ply.startswith(b"ply")
