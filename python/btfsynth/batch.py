"""Batch runs on Dask distributed: many material × mesh × preset × seed jobs, each to a
``.glb``, a surface ``.ply`` and a render, on a cluster (``pip install "btfsynth[dask]"``).

    >>> from btfsynth import batch
    >>> jobs = batch.jobs_for(["gravel.png", "bark.png"], ["bunny.obj", "cow.obj"], seeds=[0, 1])
    >>> report = batch.run(jobs, "out/")                         # a LocalCluster of 2 workers
    >>> report = batch.run(jobs, "out/", address="tcp://scheduler:8786")   # a real cluster

Each material is analysed once, as a task of its own; every job on that material takes the
analysis from the cluster (Dask sends it to the workers that need it, pickled as its
directory's files), so nothing is analysed twice. A job returns its files' bytes to this
process, which writes them into ``OUT/<job name>/`` through a temporary folder renamed into
place: a folder there is always a finished job, and a re-run skips it. A failed job is
reported with its error (in the returned :class:`Report` and ``OUT/report.json``) while the
others finish. The workers need the inputs at the same paths (a shared file system, or the
same files on each), not the output folder.
"""

import hashlib
import json
import os
import shutil
import struct
import tempfile
import time
import uuid
import zlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Dict, Iterable, List, Optional, Sequence, Tuple

import numpy as np

import btfsynth

#: What a job can write: ``glb`` (glTF with baked textures), ``ply`` (the surface map the
#: CLI's ``synth`` writes), ``png`` (a CPU render, 8-bit sRGB).
OUTPUTS = ("glb", "ply", "png")
_FILES = {"glb": "surface.glb", "ply": "surface.ply", "png": "render.png"}


@dataclass(frozen=True)
class Job:
    """One synthesis: ``material`` (any stack path the CLI reads: a photo, a folder, a
    ``.btf``, a zip) on ``mesh`` (OBJ/OFF/PLY) with ``preset`` and ``seed``.

    ``vertices`` sets the finest mesh's vertex count (default: the CLI's density, 4 × the
    sample's width across the mesh); ``analysis`` holds ``analyze()`` keyword arguments as
    ``(name, value)`` pairs; ``render_size`` and ``export_size`` are the render's side in
    pixels and the glTF atlas' side in texels.
    """

    material: str
    mesh: str
    preset: str = "appearance"
    seed: int = 0
    vertices: Optional[int] = None
    outputs: Tuple[str, ...] = OUTPUTS
    analysis: Tuple[Tuple[str, object], ...] = ()
    render_size: int = 256
    export_size: Optional[int] = 256

    @property
    def name(self) -> str:
        """The job's folder under the output folder: material, mesh, preset and seed."""
        stem = lambda p: Path(p).stem or Path(p).name  # noqa: E731
        name = f"{stem(self.material)}--{stem(self.mesh)}--{self.preset}--seed{self.seed}"
        return name if self.vertices is None else f"{name}--v{self.vertices}"

    @property
    def material_key(self) -> str:
        """What identifies the job's analysis: the material's path and the analysis settings."""
        text = json.dumps([os.path.abspath(self.material), sorted(self.analysis)], default=str)
        return hashlib.sha256(text.encode()).hexdigest()[:16]

    def files(self) -> List[str]:
        """The files a finished job's folder holds."""
        return [_FILES[o] for o in self.outputs]


def jobs_for(
    materials: Iterable[str],
    meshes: Iterable[str],
    presets: Sequence[str] = ("appearance",),
    seeds: Sequence[int] = (0,),
    **options,
) -> List[Job]:
    """Every material × mesh × preset × seed as a :class:`Job` (``options``: its other
    fields; ``analysis`` may be a dict)."""
    if isinstance(options.get("analysis"), dict):
        options["analysis"] = tuple(sorted(options["analysis"].items()))
    meshes = list(meshes)
    return [
        Job(str(m), str(mesh), preset, seed, **options)
        for m in materials
        for mesh in meshes
        for preset in presets
        for seed in seeds
    ]


@dataclass
class Report:
    """What a run did: jobs finished now, skipped (finished before), failed (with errors)."""

    done: List[str] = field(default_factory=list)
    skipped: List[str] = field(default_factory=list)
    failed: Dict[str, str] = field(default_factory=dict)
    analyses: int = 0
    seconds: float = 0.0

    def __str__(self):
        lines = [
            f"{len(self.done)} done, {len(self.skipped)} skipped (finished before), {len(self.failed)} failed;"
            f" {self.analyses} analyses; {self.seconds:.1f} s"
        ]
        lines += [f"  failed {name}: {error}" for name, error in sorted(self.failed.items())]
        return "\n".join(lines)


def analyze(material: str, analysis: Tuple[Tuple[str, object], ...]) -> "btfsynth.Analysis":
    """The task that analyses one material (once per run, whatever its job count)."""
    return btfsynth.analyze(material, **dict(analysis))


def synthesize(job: Job, analysis: "btfsynth.Analysis") -> Dict[str, bytes]:
    """The task that runs one job: its files' names and bytes."""
    surface = btfsynth.synthesize_surface(analysis, job.mesh, preset=job.preset, seed=job.seed, vertices=job.vertices)
    files = {}
    if "glb" in job.outputs:
        files[_FILES["glb"]] = btfsynth.export_gltf(surface, size=job.export_size)
    if "ply" in job.outputs:
        with tempfile.TemporaryDirectory() as tmp:
            path = surface.save_ply(os.path.join(tmp, _FILES["ply"]))
            files[_FILES["ply"]] = Path(path).read_bytes()
    if "png" in job.outputs:
        frame = btfsynth.render(surface, size=(job.render_size, job.render_size))
        files[_FILES["png"]] = png_bytes(frame)
    return files


def png_bytes(rgba: np.ndarray) -> bytes:
    """A linear RGBA float frame (premultiplied, as ``render`` gives) as an 8-bit sRGB PNG."""
    alpha = np.clip(rgba[..., 3:4], 0.0, 1.0)
    colour = np.where(alpha > 0, rgba[..., :3] / np.maximum(alpha, 1e-12), 0.0)
    c = np.clip(colour, 0.0, 1.0)
    srgb = np.where(c <= 0.0031308, 12.92 * c, 1.055 * np.power(c, 1 / 2.4) - 0.055)
    pixels = np.concatenate([srgb, alpha], axis=-1)
    data = np.round(pixels * 255.0).astype(np.uint8)
    h, w = data.shape[:2]
    raw = b"".join(b"\x00" + data[y].tobytes() for y in range(h))

    def chunk(kind, body):
        return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body) & 0xFFFFFFFF)

    header = struct.pack(">IIBBBBB", w, h, 8, 6, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", zlib.compress(raw, 6)) + chunk(b"IEND", b"")


def _finished(out: Path, job: Job) -> bool:
    folder = out / job.name
    return folder.is_dir() and all((folder / f).is_file() for f in job.files())


def _commit(out: Path, job: Job, files: Dict[str, bytes]) -> None:
    """Writes ``files`` into ``OUT/<job name>/`` through a temporary sibling renamed into place."""
    target = out / job.name
    staging = out / f".{job.name}.tmp-{uuid.uuid4().hex[:8]}"
    staging.mkdir()
    try:
        for name, data in files.items():
            (staging / name).write_bytes(data)
        if target.exists():  # an unfinished folder from elsewhere: replaced by the finished one
            shutil.rmtree(target)
        os.rename(staging, target)
    finally:
        if staging.exists():
            shutil.rmtree(staging, ignore_errors=True)


def _write_report(out: Path, report: Report) -> None:
    text = json.dumps(
        {"done": report.done, "skipped": report.skipped, "failed": report.failed, "analyses": report.analyses,
         "seconds": report.seconds},
        indent=2,
    )
    tmp = out / f".report.json.tmp-{uuid.uuid4().hex[:8]}"
    tmp.write_text(text)
    os.replace(tmp, out / "report.json")


def _plan(jobs: Iterable[Job], out_dir) -> Tuple[Path, List[Job], Report]:
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    jobs = list(jobs)
    names = [j.name for j in jobs]
    if len(set(names)) != len(names):
        raise ValueError("jobs: two jobs have the same name (material, mesh, preset, seed and vertices)")
    for job in jobs:
        unknown = set(job.outputs) - set(OUTPUTS)
        if unknown or not job.outputs:
            raise ValueError(f"jobs: {job.name}: outputs must be some of {OUTPUTS}, got {job.outputs}")
    report = Report(skipped=[j.name for j in jobs if _finished(out, j)])
    pending = [j for j in jobs if not _finished(out, j)]
    return out, pending, report


def _record(out: Path, report: Report, job: Job, outcome) -> None:
    if isinstance(outcome, BaseException):
        report.failed[job.name] = f"{type(outcome).__name__}: {outcome}"
    else:
        _commit(out, job, outcome)
        report.done.append(job.name)


def run(
    jobs: Iterable[Job],
    out_dir,
    *,
    client=None,
    address: Optional[str] = None,
    workers: int = 2,
    threads_per_worker: int = 1,
    on_result=None,
) -> Report:
    """Runs ``jobs`` on Dask distributed into ``out_dir`` (see the module documentation).

    The cluster: ``client`` (a ``dask.distributed.Client`` already connected), else
    ``address`` (a scheduler, e.g. ``tcp://host:8786``, whose workers were started with
    ``dask worker tcp://host:8786``), else a ``LocalCluster`` of ``workers`` processes with
    ``threads_per_worker`` task threads each (each task's own work runs on all the worker's
    cores). ``on_result(name, error_or_None)`` is called as each job ends.
    """
    from dask.distributed import Client, LocalCluster, as_completed

    started = time.perf_counter()
    out, pending, report = _plan(jobs, out_dir)
    if not pending:  # everything finished before: no cluster to start
        report.seconds = time.perf_counter() - started
        _write_report(out, report)
        return report
    owned = []
    try:
        if client is None:
            if address is not None:
                client = Client(address)
                owned.append(client)
            else:
                cluster = LocalCluster(
                    n_workers=workers, threads_per_worker=threads_per_worker, processes=True, dashboard_address=None
                )
                client = Client(cluster)
                owned += [client, cluster]
        token = uuid.uuid4().hex[:8]
        analyses = {}
        for job in pending:
            if job.material_key not in analyses:
                key = f"btfsynth-analyze-{job.material_key}-{token}"
                analyses[job.material_key] = client.submit(analyze, job.material, job.analysis, key=key)
        report.analyses = len(analyses)
        futures = {
            client.submit(synthesize, job, analyses[job.material_key], key=f"btfsynth-job-{i}-{token}"): job
            for i, job in enumerate(pending)
        }
        for future in as_completed(futures):
            job = futures[future]
            try:
                outcome = future.result()
            except Exception as e:  # noqa: BLE001 - every job's failure is reported, none stops the run
                outcome = e
            _record(out, report, job, outcome)
            if on_result is not None:
                on_result(job.name, outcome if isinstance(outcome, BaseException) else None)
    finally:
        for thing in owned:
            thing.close()
    report.seconds = time.perf_counter() - started
    _write_report(out, report)
    return report


def run_sequential(jobs: Iterable[Job], out_dir) -> Report:
    """The same jobs one after another in this process, without Dask: the same tasks (each
    material analysed once), the same outputs, the same skipping and failure reports."""
    started = time.perf_counter()
    out, pending, report = _plan(jobs, out_dir)
    analyses = {}
    for job in pending:
        if job.material_key not in analyses:
            try:
                analyses[job.material_key] = analyze(job.material, job.analysis)
            except Exception as e:  # noqa: BLE001 - its jobs fail with it, as on Dask
                analyses[job.material_key] = e
        analysis = analyses[job.material_key]
        try:
            if isinstance(analysis, BaseException):
                raise analysis
            outcome = synthesize(job, analysis)
        except Exception as e:  # noqa: BLE001 - as in run(): reported, the others go on
            outcome = e
        _record(out, report, job, outcome)
    report.analyses = len(analyses)
    report.seconds = time.perf_counter() - started
    _write_report(out, report)
    return report
