"""Library errors are btfsynth exceptions with the library's one-line message; bad arrays
are TypeError/ValueError naming the argument; nothing panics."""

import numpy as np
import pytest

import btfsynth
from btfsynth import errors
from conftest import BUNNY, PHOTO


def test_the_hierarchy_derives_from_the_builtin_classes():
    assert issubclass(errors.ParameterError, ValueError) and issubclass(errors.ParameterError, btfsynth.Error)
    assert issubclass(errors.FileError, OSError) and issubclass(errors.FileError, btfsynth.Error)
    assert issubclass(errors.TooLargeError, errors.ParameterError)
    assert issubclass(errors.OutputError, errors.FileError)


def test_an_unreadable_file_is_a_file_error_naming_it():
    with pytest.raises(btfsynth.FileError) as e:
        btfsynth.analyze("data/no-such-photo.png")
    assert isinstance(e.value, OSError) and "no-such-photo.png" in str(e.value)
    assert "\n" not in str(e.value)
    with pytest.raises(btfsynth.FileError, match="no-such.obj"):
        btfsynth.synthesize_surface(btfsynth.analyze(PHOTO, textons=16, levels=1), "data/no-such.obj")


def test_out_of_range_parameters_are_parameter_errors(analysis):
    with pytest.raises(btfsynth.ParameterError, match="preset") as e:
        btfsynth.synthesize_plane(analysis, (32, 32), preset="nonesuch")
    assert isinstance(e.value, ValueError)
    with pytest.raises(btfsynth.ParameterError, match="levels") as e:
        btfsynth.synthesize_plane(analysis, (32, 32), levels=5)
    assert e.value.param == "levels"
    with pytest.raises(btfsynth.ParameterError, match="plane size"):
        btfsynth.synthesize_plane(analysis, (0, 32))
    with pytest.raises(ValueError, match="neighborhood"):
        btfsynth.synthesize_plane(analysis, (32, 32), neighborhood=8)
    with pytest.raises(ValueError, match="textons"):
        btfsynth.analyze(PHOTO, textons=0)
    with pytest.raises(btfsynth.ParameterError, match="recipe"):
        btfsynth.synthesize_plane(analysis, (32, 32), recipe={"name": "mine", "passes": "no"})


def test_a_recipe_dict_runs_as_its_preset(analysis):
    recipe = next(p["recipe"] for p in btfsynth.presets() if p["name"] == "tong2002")
    by_dict = btfsynth.synthesize_plane(analysis, (32, 32), recipe=recipe, seed=2)
    by_name = btfsynth.synthesize_plane(analysis, (32, 32), preset="tong2002", seed=2)
    assert np.array_equal(by_dict.uv, by_name.uv)


def test_bad_arrays_name_the_argument():
    good_view = np.zeros((2, 2), np.float32)
    with pytest.raises(TypeError, match="images: .*float32.*float64"):
        btfsynth.Stack.from_arrays(np.zeros((2, 8, 8, 3)), good_view, good_view)
    with pytest.raises(TypeError, match="images: expected a numpy array"):
        btfsynth.Stack.from_arrays([[1.0]], good_view, good_view)
    with pytest.raises(ValueError, match=r"images: expected shape \[N, H, W, 3\]"):
        btfsynth.Stack.from_arrays(np.zeros((2, 8, 8, 4), np.float32), good_view, good_view)
    with pytest.raises(ValueError, match=r"light: expected shape \[2, 2\]"):
        btfsynth.Stack.from_arrays(np.zeros((2, 8, 8, 3), np.float32), good_view, np.zeros((3, 2)))
    with pytest.raises(ValueError, match="view: row 1"):
        btfsynth.Stack.from_arrays(np.zeros((2, 8, 8, 3), np.float32), np.array([[0, 0], [95, 0]], np.float32), good_view)
    with pytest.raises(ValueError, match="images: expected finite"):
        btfsynth.Stack.from_arrays(np.full((2, 8, 8, 3), np.nan, np.float32), good_view, np.array([[0, 0], [30, 0]]) * 1.0)
    with pytest.raises(TypeError, match="image: .*uint8"):
        btfsynth.Stack.from_image(np.zeros((8, 8, 3), np.int16))
    with pytest.raises(ValueError, match="faces: index 99"):
        btfsynth.synthesize_surface(btfsynth.analyze(PHOTO, textons=16, levels=1), np.zeros((3, 3)), np.array([[0, 1, 99]]))
    with pytest.raises(TypeError, match="stack: expected a Stack or a path"):
        btfsynth.analyze(42)


def test_a_tiny_sample_is_refused_without_a_panic():
    tiny = btfsynth.Stack.from_image(np.zeros((5, 5, 3), np.uint8))
    with pytest.raises(btfsynth.ParameterError):
        btfsynth.analyze(tiny)


def test_an_existing_output_is_refused(analysis, scratch):
    analysis.save(scratch / "a")
    with pytest.raises(btfsynth.OutputError, match="already exists"):
        analysis.save(scratch / "a")
    analysis.save(scratch / "a", overwrite=True)
    surface = btfsynth.synthesize_surface(analysis, BUNNY, vertices=1000, levels=1)
    with pytest.raises(ValueError, match="path: .*glb"):
        btfsynth.export_gltf(surface, scratch / "x.gltf")


def test_a_method_and_its_keywords_are_checked(analysis):
    with pytest.raises(btfsynth.ParameterError, match="method") as e:
        btfsynth.synthesize_surface(analysis, BUNNY, method="tong")
    assert e.value.param == "method"
    with pytest.raises(TypeError, match="vertices: not a keyword of method='soler2002'"):
        btfsynth.synthesize_surface(analysis, BUNNY, method="soler2002", vertices=1000)
    with pytest.raises(TypeError, match="rotations: not a keyword of method='vertex'"):
        btfsynth.synthesize_surface(analysis, BUNNY, rotations=5)
    with pytest.raises(ValueError, match="colour_space"):
        btfsynth.map_patches(analysis, BUNNY, colour_space="xyz")
    with pytest.raises(btfsynth.ParameterError, match="rotations"):
        btfsynth.map_patches(analysis, BUNNY, rotations=0)
    with pytest.raises(btfsynth.ParameterError, match="first face|first_face"):
        btfsynth.map_patches(analysis, BUNNY, first_face=10**6)
    with pytest.raises(ValueError, match="path: .*ply or .obj"):
        btfsynth.map_patches(analysis, BUNNY, rotations=3).save("x.glb")


def test_render_and_export_name_a_wrong_argument(analysis):
    mapped = btfsynth.map_patches(analysis, BUNNY, rotations=3)
    with pytest.raises(TypeError, match="surface: expected a Surface or a PatchMap"):
        btfsynth.render(analysis)
    with pytest.raises(TypeError, match="material: expected an Analysis or a Stack"):
        btfsynth.render(mapped, "gravel.png")
    with pytest.raises(ValueError, match="material: a 8x8 sample"):
        btfsynth.render(mapped, btfsynth.Stack.from_image(np.zeros((8, 8, 3), np.uint8)))
    with pytest.raises(TypeError, match="surface: expected a Surface: a PatchMap"):
        btfsynth.export_gltf(mapped)
