"""The Python path gives the CLI's results for the same inputs and seed: the same bytes for
the analysis directory and the surface map, the same values for a plane."""

from pathlib import Path

import numpy as np

import btfsynth
from conftest import BUNNY, ROOT, read_png, to_srgb8


def test_the_saved_analysis_is_the_cli_directory_byte_for_byte(cli_analysis, analysis, scratch):
    analysis.save(scratch / "py")
    ours, theirs = ROOT / scratch / "py", ROOT / cli_analysis
    names = sorted(p.name for p in theirs.iterdir())
    assert names == sorted(p.name for p in ours.iterdir())
    assert "analysis.json" in names and "level0_textons.npy" in names
    for name in names:
        assert (ours / name).read_bytes() == (theirs / name).read_bytes(), name


def test_a_plane_is_the_cli_plane(cli, cli_analysis, analysis, scratch):
    cli("synth", cli_analysis, "--plane", "96x64", "--seed", "3", "-o", scratch / "plane")
    plane = btfsynth.synthesize_plane(analysis, (64, 96), seed=3)
    out = ROOT / scratch / "plane"
    assert np.array_equal(plane.uv, np.load(out / "uv.npy").astype(np.int32))
    assert np.array_equal(plane.textons, np.load(out / "labels.npy"))
    # result.png: the head-on image through uv, as 8-bit sRGB.
    assert np.array_equal(to_srgb8(plane.image()), read_png(out / "result.png"))
    # Another seed is another plane (the comparison can fail).
    other = btfsynth.synthesize_plane(analysis, (64, 96), seed=4)
    assert not np.array_equal(other.uv, plane.uv)


def test_a_surface_map_is_the_cli_ply_byte_for_byte(cli, cli_analysis, analysis, scratch):
    flags = ["--vertices", "3000", "--seed", "1", "--preset", "tong2002"]
    cli("synth", cli_analysis, BUNNY, *flags, "-o", scratch / "cli.ply")
    loaded = btfsynth.Analysis.load(cli_analysis)
    surface = btfsynth.synthesize_surface(loaded, BUNNY, vertices=3000, seed=1, preset="tong2002")
    surface.save_ply(scratch / "py.ply")
    theirs = (ROOT / scratch / "cli.ply").read_bytes()
    assert (ROOT / scratch / "py.ply").read_bytes() == theirs
    # From the analysis in memory: the same values (the header names no directory).
    in_memory = btfsynth.synthesize_surface(analysis, BUNNY, vertices=3000, seed=1, preset="tong2002")
    assert np.array_equal(in_memory.uv, surface.uv) and np.array_equal(in_memory.textons, surface.textons)
    assert np.array_equal(in_memory.vertices, surface.vertices)


def test_the_glb_is_the_cli_export(cli, cli_analysis, scratch):
    cli("synth", cli_analysis, BUNNY, "--vertices", "3000", "-o", scratch / "s.ply")
    cli("export", scratch / "s.ply", "-o", scratch / "cli.glb", "--size", "128")
    surface = btfsynth.synthesize_surface(btfsynth.Analysis.load(cli_analysis), BUNNY, vertices=3000)
    glb = btfsynth.export_gltf(surface, scratch / "py.glb", size=128)
    assert glb[:4] == b"glTF" and (ROOT / scratch / "py.glb").read_bytes() == glb
    theirs = (ROOT / scratch / "cli.glb").read_bytes()
    # The JSON chunk names the inputs (the CLI's surface file, ours "(in memory)"); the
    # binary chunk — geometry, UVs and the baked texture — is the same.
    assert binary_chunk(glb) == binary_chunk(theirs)


def binary_chunk(glb):
    json_length = int.from_bytes(glb[12:16], "little")
    return glb[20 + json_length :]


def test_a_patch_map_is_the_cli_uvmap_byte_for_byte(cli, cli_analysis, analysis, scratch):
    cli("synth", cli_analysis, BUNNY, "--method", "soler2002", "--seed", "2", "--rotations", "7", "-o", scratch / "cli.ply")
    loaded = btfsynth.Analysis.load(cli_analysis)
    mapped = btfsynth.synthesize_surface(loaded, BUNNY, method="soler2002", seed=2, rotations=7)
    mapped.save(scratch / "py.ply")
    assert (ROOT / scratch / "py.ply").read_bytes() == (ROOT / scratch / "cli.ply").read_bytes()
    # From the analysis in memory: the same coordinates (the header names no directory).
    in_memory = btfsynth.map_patches(analysis, BUNNY, seed=2, rotations=7)
    assert np.array_equal(in_memory.corner_uv, mapped.corner_uv)
    assert np.array_equal(in_memory.cluster, mapped.cluster)


def test_a_patch_map_on_appearance_vectors_is_the_cli_obj(cli, cli_analysis, scratch):
    flags = ["--colour-space", "appearance", "--scale", "40", "--keep-borders", "--no-relax", "--rotations", "5"]
    cli("synth", cli_analysis, BUNNY, "--method", "soler2002", *flags, "-o", scratch / "cli.obj")
    mapped = btfsynth.synthesize_surface(
        btfsynth.Analysis.load(cli_analysis), BUNNY, method="soler2002", colour_space="appearance", scale=40,
        keep_borders=True, relax=False, rotations=5,
    )
    mapped.save(scratch / "py.obj")
    assert (ROOT / scratch / "py.obj").read_bytes() == (ROOT / scratch / "cli.obj").read_bytes()
    assert mapped.params["colour_space"] == "appearance" and mapped.params["relax"] is False
