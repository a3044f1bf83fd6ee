"""numpy in and out: stacks from arrays and photos, read-only views of the Rust data,
pickling, renders and exports from arrays."""

import pickle

import numpy as np

import btfsynth
from conftest import BUNNY, PHOTO, read_png


def test_a_uint8_photo_array_is_the_photo_file():
    from_file = btfsynth.Stack.open(PHOTO)
    from_array = btfsynth.Stack.from_image(read_png(PHOTO)[..., :3])
    assert len(from_file) == 1 and (from_file.height, from_file.width) == (128, 128)
    assert np.array_equal(from_file.images, from_array.images)
    assert np.array_equal(from_array.view, np.zeros((1, 2), np.float32))
    # Float input is linear: the stack keeps it (to f16 precision).
    linear = from_file.images[0]
    assert np.allclose(btfsynth.Stack.from_image(linear).images[0], linear, rtol=1e-3)


def test_a_stack_from_arrays_round_trips_and_analyses():
    rng = np.random.default_rng(0)
    images = rng.random((4, 32, 32, 3), dtype=np.float32)
    view = np.array([[0, 0], [0, 0], [30, 90], [30, 90]], np.float32)
    light = np.array([[0, 0], [45, 0], [0, 0], [45, 0]], np.float64)
    stack = btfsynth.Stack.from_arrays(images, view, light)
    assert np.allclose(stack.images, images, rtol=1e-3) and np.array_equal(stack.light, light)
    analysis = btfsynth.analyze(stack, textons=16, levels=2)
    plane = btfsynth.synthesize_plane(analysis, (40, 40))
    assert plane.uv.min() >= 0 and plane.uv.max() < 32
    lit = plane.image(view=(30, 90), light=(45, 0))
    assert lit.dtype == np.float32 and lit.shape == (40, 40, 3)
    u, v = plane.uv[..., 0], plane.uv[..., 1]
    assert np.allclose(lit, images[3][v, u], rtol=1e-3)


def test_results_are_read_only_views_of_their_object(analysis):
    textons = analysis.texton_map(0)
    assert textons.dtype == np.uint16 and textons.shape == analysis.levels[0]
    assert not textons.flags.writeable and textons.base is analysis
    plane = btfsynth.synthesize_plane(analysis, (16, 16))
    assert plane.uv.base is plane and not plane.uv.flags.owndata
    gamma = analysis.gamma(1)
    assert gamma.shape == (analysis.textons[1] + 1,) * 2 and np.allclose(gamma, gamma.T, atol=1e-5)


def test_an_analysis_pickles_as_its_directory(analysis):
    copy = pickle.loads(pickle.dumps(analysis))
    assert np.array_equal(copy.texton_map(1), analysis.texton_map(1))
    a = btfsynth.synthesize_plane(copy, (48, 48), seed=5)
    b = btfsynth.synthesize_plane(analysis, (48, 48), seed=5)
    assert np.array_equal(a.uv, b.uv) and np.array_equal(a.image(), b.image())


def test_a_mesh_from_arrays_renders_and_exports(analysis):
    # A 20×20 grid of two triangles per cell in the unit square of the ground (y = 0),
    # facing up (+y, where the camera at θ = 0 looks from).
    n = 21
    xs, zs = np.meshgrid(np.linspace(0, 1, n), np.linspace(0, 1, n))
    vertices = np.stack([xs.ravel(), np.zeros(n * n), zs.ravel()], axis=1)
    cells = [(z * n + x, (z + 1) * n + x, z * n + x + 1) for z in range(n - 1) for x in range(n - 1)]
    cells += [(z * n + x + 1, (z + 1) * n + x, (z + 1) * n + x + 1) for z in range(n - 1) for x in range(n - 1)]
    faces = np.array(cells, np.int64)
    surface = btfsynth.synthesize_surface(analysis, vertices, faces, vertices=2000, levels=1)
    assert surface.vertices.shape[1] == 3 and surface.faces.max() < len(surface.vertices)
    assert surface.uv.shape == (len(surface.vertices), 2) and surface.frames.shape == surface.vertices.shape
    # One level from patches: most vertices lie between texels, each within half a texel.
    places = surface.subtexel
    assert places.shape == surface.uv.shape and places.dtype == np.float32 and np.abs(places).max() < 0.5
    assert (places != 0).any(axis=1).mean() > 0.25
    frame = btfsynth.render(surface, size=(48, 64), view=(0, 0), light=(0, 0), spp=1)
    assert frame.shape == (48, 64, 4) and frame.dtype == np.float32
    assert frame[..., 3].max() == 1.0 and frame[24, 32, :3].sum() > 0
    glb = btfsynth.export_gltf(surface, size=64)
    assert glb[:4] == b"glTF" and int.from_bytes(glb[8:12], "little") == len(glb)


def test_the_bunny_renders_under_the_sky(analysis):
    surface = btfsynth.synthesize_surface(analysis, BUNNY, vertices=2000, levels=1)
    plain = btfsynth.render(surface, size=(32, 32), spp=1)
    sky = btfsynth.render(surface, size=(32, 32), spp=1, env="sky")
    covered = plain[..., 3] > 0
    assert covered.sum() > 100 and (sky[..., :3][covered].sum() > plain[..., :3][covered].sum())


def test_a_patch_map_keeps_the_mesh_and_renders(analysis):
    mapped = btfsynth.synthesize_surface(analysis, BUNNY, method="soler2002", rotations=5)
    assert isinstance(mapped, btfsynth.PatchMap)
    faces, corners = mapped.faces, mapped.corner_uv
    assert corners.shape == (len(faces), 3, 2) and corners.dtype == np.float32 and corners.base is mapped
    assert faces.max() < len(mapped.vertices) and mapped.cluster.shape == mapped.level.shape == (len(faces),)
    # A sample that does not tile is never left: texel centres from 0 to 127.
    assert corners.min() >= -0.5 and corners.max() <= 127.5
    assert mapped.report["faces"] == len(faces)
    # Shaded by the analysis, or by a stack of the same size: another picture.
    frame = btfsynth.render(mapped, size=(64, 64), spp=1)
    dark = btfsynth.Stack.from_image(np.full((128, 128, 3), 20, np.uint8))
    other = btfsynth.render(mapped, dark, size=(64, 64), spp=1)
    covered = frame[..., 3] > 0
    assert covered.sum() > 200 and np.array_equal(frame[..., 3], other[..., 3])
    assert other[..., :3][covered].mean() < frame[..., :3][covered].mean()
