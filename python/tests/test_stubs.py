"""The type stubs say what the module does, and help() shows documentation: each stub's
parameters (names, kinds, defaults) are the runtime's, and every public name has both."""

import ast
import inspect
import pydoc
from pathlib import Path

import pytest

import btfsynth
from btfsynth import _native

STUBS = Path(btfsynth.__file__).parent / "_native.pyi"


def stub_functions():
    """Top-level functions and class methods of _native.pyi: {qualified name: ast node}."""
    tree = ast.parse(STUBS.read_text())
    found = {}
    for node in tree.body:
        if isinstance(node, ast.FunctionDef):
            found[node.name] = node
        elif isinstance(node, ast.ClassDef):
            for item in node.body:
                if isinstance(item, ast.FunctionDef):
                    found[f"{node.name}.{item.name}"] = item
    return found


def stub_parameters(node):
    """(name, kind, default) of a stub's parameters, as inspect names them."""
    a, P = node.args, inspect.Parameter
    decorators = {d.id for d in node.decorator_list if isinstance(d, ast.Name)}
    positional = a.posonlyargs + a.args
    if "staticmethod" not in decorators and "property" not in decorators and positional and positional[0].arg == "self":
        positional = positional[1:]
    defaults = [P.empty] * (len(a.posonlyargs + a.args) - len(a.defaults)) + [ast.literal_eval(d) for d in a.defaults]
    defaults = defaults[len(defaults) - len(positional) :]
    out = [(p.arg, P.POSITIONAL_OR_KEYWORD, d) for p, d in zip(positional, defaults)]
    kw_defaults = [P.empty if d is None else ast.literal_eval(d) for d in a.kw_defaults]
    out += [(p.arg, P.KEYWORD_ONLY, d) for p, d in zip(a.kwonlyargs, kw_defaults)]
    return out


def runtime(name):
    obj = _native
    for part in name.split("."):
        obj = getattr(obj, part)
    return obj


def runtime_parameters(obj):
    P = inspect.Parameter
    kinds = {P.POSITIONAL_ONLY: P.POSITIONAL_OR_KEYWORD}
    params = list(inspect.signature(obj).parameters.values())
    if params and params[0].name == "self":  # an unbound method's receiver; the stub drops it too
        params = params[1:]
    return [(p.name, kinds.get(p.kind, p.kind), p.default) for p in params]


CALLABLES = sorted(n for n, node in stub_functions().items() if not any(
    isinstance(d, ast.Name) and d.id == "property" for d in node.decorator_list) and not n.split(".")[-1].startswith("__"))


@pytest.mark.parametrize("name", CALLABLES)
def test_a_stub_has_the_runtime_signature(name):
    node = stub_functions()[name]
    assert stub_parameters(node) == runtime_parameters(runtime(name)), name


def test_every_runtime_name_has_a_stub():
    stubbed = set(stub_functions())
    classes = {n for n in dir(_native) if isinstance(getattr(_native, n), type)}
    for name in dir(_native):
        obj = getattr(_native, name)
        if name.startswith("__"):
            continue
        if name in classes:
            members = [m for m in vars(obj) if not m.startswith("__")]
            missing = [m for m in members if f"{name}.{m}" not in stubbed]
            assert not missing, (name, missing)
        elif callable(obj):
            assert name in stubbed, name


def test_help_shows_the_documentation():
    for name in btfsynth.__all__:
        obj = getattr(btfsynth, name)
        if not callable(obj):
            continue
        doc = inspect.getdoc(obj)
        assert doc and len(doc) > 20, name
        assert doc.splitlines()[0] in pydoc.render_doc(obj), name
    # The signature help() prints, with the defaults written out.
    text = pydoc.render_doc(btfsynth.render)
    assert "size=(512, 512)" in text and "material=None" in text
    assert "appearance_dims=16" in pydoc.render_doc(btfsynth.analyze)
    assert "soler2002" in pydoc.render_doc(btfsynth.synthesize_surface)
    for cls in (btfsynth.Analysis, btfsynth.Surface, btfsynth.PatchMap, btfsynth.Plane, btfsynth.Stack):
        for member, value in vars(cls).items():
            if not member.startswith("_"):
                assert inspect.getdoc(value), f"{cls.__name__}.{member}"
