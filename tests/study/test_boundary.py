"""The study stays outside the product: the engine, the add-on and its scripts never import it
(not even inside a function), and the engine's command line no longer offers its commands."""

import ast
import os
import pathlib
import subprocess
import sys

ROOT = pathlib.Path(__file__).resolve().parents[2]
PRODUCT = [
    "virtual_reflections",
    "operators",
    "ui",
    "__init__.py",
    "preferences.py",
    "render_shot.py",
]


def product_files():
    for name in PRODUCT:
        path = ROOT / name
        yield from sorted(path.rglob("*.py")) if path.is_dir() else [path]


def imported_names(tree):
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            yield from (alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            yield node.module
        elif (  # importlib.import_module("...") / __import__("...") with a literal name
            isinstance(node, ast.Call)
            and getattr(node.func, "attr", getattr(node.func, "id", None))
            in ("import_module", "__import__")
            and node.args
            and isinstance(node.args[0], ast.Constant)
            and isinstance(node.args[0].value, str)
        ):
            yield node.args[0].value


def test_the_product_never_imports_the_study():
    files = list(product_files())
    assert len(files) > 20
    offenders = [
        f"{path.relative_to(ROOT)}: {name}"
        for path in files
        for name in imported_names(ast.parse(path.read_text(), str(path)))
        if name == "study" or name.startswith("study.")
    ]
    assert not offenders, offenders


def test_the_engine_cli_has_no_study_commands():
    for command in ("evaluate", "bench"):
        r = subprocess.run(
            [sys.executable, "-m", "virtual_reflections", command],
            cwd=ROOT,
            capture_output=True,
            text=True,
            timeout=60,
        )
        assert r.returncode == 2 and "invalid choice" in r.stderr, r.stderr


def test_the_study_cli_rejects_bad_input_in_one_line(tmp_path):
    # the Poly Haven HDRIs neither in VR_POLYHAVEN_DIR nor fetchable: no npm on PATH
    no_npm = dict(os.environ, VR_POLYHAVEN_DIR=str(tmp_path / "none"), PATH=str(tmp_path))
    polyhaven = ("scenes", "--cases", "polyhaven", "--mirror-only")
    for args in ((), ("frobnicate",), ("bench", "--repeat", "x"), polyhaven):
        r = subprocess.run(
            [sys.executable, "-m", "study", *args],
            cwd=ROOT,
            env=no_npm if args is polyhaven else None,
            capture_output=True,
            text=True,
            timeout=60,
        )
        assert r.returncode == 2, r.stderr
        assert len(r.stderr.strip().splitlines()) == 1 and "Traceback" not in r.stderr
        if args is polyhaven:
            assert "need npm" in r.stderr and "VR_POLYHAVEN_DIR" in r.stderr
