"""The typed package against what it ships and runs: `mbs/_native.pyi` and
`mbs/py.typed` are installed with the package, and the stub says exactly what
the native module has (read from the stub's source, so that neither can
drift from the other): the same public names, each function's parameters,
kinds and defaults as the runtime's signatures, the same docstrings, and
result dicts with the keys and dtypes the stub's typed dicts declare.
"""

from __future__ import annotations

import ast
import inspect
import os
import subprocess
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import mbs
from mbs import _native

STUB = Path(_native.__file__).with_name("_native.pyi")
MBS_TOOL = os.environ.get("MBS_TOOL", "target/debug/mbs-tool")


def stub_tree() -> ast.Module:
    return ast.parse(STUB.read_text(), str(STUB))


def defined(body: list[ast.stmt]) -> dict[str, ast.stmt]:
    """The names a stub's module or class body defines (not those it imports)."""
    names: dict[str, ast.stmt] = {}
    for node in body:
        if isinstance(node, (ast.FunctionDef, ast.ClassDef)):
            names[node.name] = node
        elif isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name):
            names[node.target.id] = node
        elif isinstance(node, ast.Assign):
            names.update({target.id: node for target in node.targets if isinstance(target, ast.Name)})
    return names


def public(names: Iterable[str]) -> set[str]:
    return {name for name in names if not name.startswith("_")}


def test_the_stub_and_the_marker_are_installed_with_the_package() -> None:
    assert STUB.is_file(), f"{STUB} is missing: the wheel must carry mbs/_native.pyi"
    marker = Path(mbs.__file__).with_name("py.typed")
    assert marker.is_file(), f"{marker} is missing: the wheel must carry mbs/py.typed"


def test_the_stub_names_what_the_native_module_has() -> None:
    names = defined(stub_tree().body)
    assert public(names) == public(dir(_native)), "mbs/_native.pyi and python/src/*.rs name different things"
    stub_all = names["__all__"]
    assert isinstance(stub_all, ast.Assign)
    assert ast.literal_eval(stub_all.value) == _native.__all__
    host_batches = names["HostBatches"]
    assert isinstance(host_batches, ast.ClassDef)
    assert public(defined(host_batches.body)) == public(dir(_native.HostBatches))


def parameters(function: ast.FunctionDef, skip_first: bool = False) -> list[tuple[str, str, object]]:
    """Name, kind and default (``inspect.Parameter.empty`` if none) of each parameter."""
    arguments = function.args
    positional = arguments.posonlyargs + arguments.args
    defaults: list[object] = [inspect.Parameter.empty] * (len(positional) - len(arguments.defaults))
    defaults += [ast.literal_eval(default) for default in arguments.defaults]
    out = [
        (arg.arg, "POSITIONAL_ONLY" if arg in arguments.posonlyargs else "POSITIONAL_OR_KEYWORD", default)
        for arg, default in zip(positional, defaults)
    ]
    if arguments.vararg:
        out.append((arguments.vararg.arg, "VAR_POSITIONAL", inspect.Parameter.empty))
    for arg, kw_default in zip(arguments.kwonlyargs, arguments.kw_defaults):
        value = inspect.Parameter.empty if kw_default is None else ast.literal_eval(kw_default)
        out.append((arg.arg, "KEYWORD_ONLY", value))
    if arguments.kwarg:
        out.append((arguments.kwarg.arg, "VAR_KEYWORD", inspect.Parameter.empty))
    return out[1:] if skip_first else out


def runtime_parameters(function: Any) -> list[tuple[str, str, object]]:
    return [(p.name, p.kind.name, p.default) for p in inspect.signature(function).parameters.values()]


def stub_functions() -> list[tuple[str, ast.FunctionDef, Any, bool]]:
    """Each stub function or method (name, node, runtime object, whether its
    first parameter is ``self``/``cls``), ``HostBatches.__new__`` as the class."""
    functions: list[tuple[str, ast.FunctionDef, Any, bool]] = []
    for name, node in defined(stub_tree().body).items():
        if isinstance(node, ast.FunctionDef):
            functions.append((name, node, getattr(_native, name), False))
        elif isinstance(node, ast.ClassDef) and not name.startswith("_"):
            cls = getattr(_native, name)
            for method_name, method in defined(node.body).items():
                if isinstance(method, ast.FunctionDef):
                    runtime = cls if method_name == "__new__" else getattr(cls, method_name)
                    functions.append((f"{name}.{method_name}", method, runtime, True))
    return functions


def test_the_stub_signatures_are_the_runtime_ones() -> None:
    functions = stub_functions()
    assert len(functions) == len(_native.__all__) + 1  # HostBatches' constructor and batch()
    for name, node, runtime, method in functions:
        expected = runtime_parameters(runtime)
        if method and not name.endswith(".__new__"):
            expected = expected[1:]  # self; inspect.signature(cls) leaves out cls itself
        assert parameters(node, skip_first=method) == expected, name


def test_the_stub_docstrings_are_the_runtime_ones() -> None:
    tree = stub_tree()
    assert ast.get_docstring(tree) == inspect.cleandoc(_native.__doc__ or "")
    classes = [node for node in tree.body if isinstance(node, ast.ClassDef) and not node.name.startswith("_")]
    for cls in classes:
        assert ast.get_docstring(cls) == inspect.cleandoc(getattr(_native, cls.name).__doc__), cls.name
    for name, node, runtime, _ in stub_functions():
        if name.endswith(".__new__"):
            continue  # pyo3 keeps no docstring of #[new]: the class's says it all
        assert ast.get_docstring(node) == inspect.cleandoc(runtime.__doc__), name


def declared(typed_dict: str) -> dict[str, str]:
    """A stub typed dict's keys and the source of each annotation, aliases resolved."""
    names = defined(stub_tree().body)
    aliases = {
        name: ast.unparse(node.value)
        for name, node in names.items()
        if isinstance(node, ast.AnnAssign) and node.value is not None
    }
    node = names[typed_dict]
    assert isinstance(node, ast.ClassDef)
    keys = {}
    for item in node.body:
        if isinstance(item, ast.AnnAssign) and isinstance(item.target, ast.Name):
            source = ast.unparse(item.annotation)
            for alias, value in aliases.items():
                source = source.replace(alias, value)
            keys[item.target.id] = source
    return keys


def assert_matches(typed_dict: str, value: dict[str, Any]) -> None:
    """``value`` has exactly the keys of the stub's ``typed_dict``; each array
    has its declared dtype, each list holds what its annotation says, and
    ``None`` is only where the annotation allows it."""
    keys = declared(typed_dict)
    assert set(value) == set(keys), typed_dict
    for key, annotation in keys.items():
        where = (typed_dict, key, annotation)
        items = value[key] if annotation.startswith("list[") else [value[key]]
        if annotation.startswith("list["):
            assert isinstance(value[key], list), where
        if annotation.removesuffix("]").endswith(" | None"):
            items = [item for item in items if item is not None]
        if "npt.NDArray[np." in annotation:
            dtype = np.dtype(getattr(np, annotation.split("npt.NDArray[np.")[1].split("]")[0]))
            assert items, where
            for item in items:
                assert isinstance(item, np.ndarray) and item.dtype == dtype, where
        elif annotation == "float | None":
            assert all(isinstance(item, float) for item in items), where
        elif annotation == "list[str]":
            assert all(isinstance(item, str) for item in items), where
        elif annotation == "list[tuple[str, str]]":
            assert all(isinstance(item, tuple) and list(map(type, item)) == [str, str] for item in items), where
        elif annotation.startswith("list[Literal["):
            allowed = ast.literal_eval(annotation[len("list[Literal[") : -len("]]")])
            assert items and all(item in allowed for item in items), where
        else:
            raise AssertionError(f"{where}: no check for this annotation")


def test_result_dicts_have_the_stubs_keys_and_dtypes(tmp_path: Path) -> None:
    scene = mbs.synth_scene(seed=1, views=2, width=48, height=24, focal=24.0)
    assert_matches("_SynthScene", dict(scene))
    left, right = scene["views"]
    assert_matches("_Extrapolated", dict(mbs.extrapolate(left, right, max_disparity=16)))
    ranged = mbs.mono_views(left, scene["depth"][0], "metric-depth")
    assert isinstance(ranged["drawn_fraction"], float) and ranged["masks"][1] is None
    assert_matches("_MonoViews", dict(ranged))
    as_is = mbs.mono_views(left, scene["disparity"][0], "disparity", views=3, reference=0)
    assert as_is["drawn_fraction"] is None and as_is["masks"][0] is None
    assert_matches("_MonoViews", dict(as_is))
    done = subprocess.run(
        [MBS_TOOL, "synth", "--out", str(tmp_path), "--weathers", "ClearNoon", "--no-checksums", "--seed", "2"]
        + ["--frames", "1", "--towns", "Town01", "--width", "64", "--height", "32", "--focal", "32"],
        capture_output=True,
        text=True,
    )
    assert done.returncode == 0, done.stdout + done.stderr
    batches = _native.HostBatches(tmp_path / "manifest.json", 2, 16, 32, 0)
    assert_matches("_HostBatch", dict(batches.batch(0)))


@pytest.mark.parametrize("function", ["read_rgb", "read_pfm", "read_kitti_disparity", "read_exr"])
def test_readers_return_the_stubs_dtype(tmp_path: Path, function: str) -> None:
    """Each reader's return annotation names the dtype it returns."""
    node = defined(stub_tree().body)[function]
    assert isinstance(node, ast.FunctionDef) and node.returns is not None
    expected = {"_Bytes": np.uint8, "_Map": np.float32}[ast.unparse(node.returns)]
    path = tmp_path / {"read_pfm": "file.pfm", "read_exr": "file.exr"}.get(function, "file.png")
    if function == "read_rgb":
        mbs.write_rgb(path, np.zeros((2, 3, 3), np.uint8))
    else:
        writer = getattr(mbs, function.replace("read_", "write_"))
        writer(path, np.ones((2, 3), np.float32))
    assert getattr(mbs, function)(path).dtype == expected
