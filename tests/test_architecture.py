"""The extension's import graph stays clean. Source is parsed with `ast`; nothing is imported.

The package is the repository root: its `__init__.py`, `preferences.py` and every top-level
folder that is a Python package (`operators/`, `ui/`, `virtual_reflections/`, ...). Modules are
named by dotted path from the root ("" is the root package itself, "operators.generate" is
operators/generate.py) and reported by file path.

Every `import` / `from ... import` counts, at module level and inside functions or classes. An
import points at the module it names: `from . import x` at the submodule x when x is one, else
at the package; `from .x import name` at x.name when that is a submodule, else at x. (Parent
packages that Python initialises on the way are not edges, as in import-linter's graph: the
cycles reported are the ones the code spells out.)

Rules:
1. no import cycle among the package's modules;
2. no module uses another module's private name (`from .x import _name`, `x._name`);
3. the engine `virtual_reflections/` never imports bpy (or other Blender-only modules), the
   add-on's `operators`, `ui`, `preferences` or its root `__init__.py`;
4. the product never imports a research package: `study`, `benchmarks`, `tests`, or any other
   top-level package of the repository that is not part of the product.

And one rule on every Python file of the repository (hidden folders such as `.venv` aside):
5. every command-line parser (`argparse.ArgumentParser(...)`, a subclass of it defined in the
   file, a sub-command's `add_parser(...)`) passes `allow_abbrev=False`: argparse's prefix
   matching takes `--ou` for `--out`, which bypassed the farm's refusal of `--out` after `--`
   (issue 40, row 30).

And three on the product (its modules and render_shot.py), issue 43 items 1 and 5:
7. each choice list (the methods, the Surroundings, the combine modes) is spelled once, in
   `virtual_reflections/methods.py`: no other literal lists all of one (argparse's `choices`,
   Blender's enum items, a list to check against), and none lists two methods or two looks
   (what a method or a look does is asked of that module, not re-decided by name);
8. the triangles limit (1024) is written once, there too (`MAX_TRIANGLES`);
9. the command-line layer is defined once, in `virtual_reflections/cli_common.py`: no other
   `EXIT_... = n`, `Terminated` or argparse parser class.

And one on the engine's lookup tables (issue 43, item 2):
10. a table writes its texels through its layers (`virtual_reflections/layers.py`): no field
    of `LookupTable` but `fill` is optional (`X | None`), and no engine module tests a table's
    attribute against None but its `fill` (the ladder of `if table.X is not None` that
    applied seven optional payloads).

And one on the engine's public surface:
6. every function or class in `virtual_reflections.__all__` (and every public function of a
   module listed there, as `cache`) has a numpydoc docstring: a one-line summary and, for a
   function that takes parameters, a Parameters section (issue 43, item 7).
11. code outside the engine (every Python file but `virtual_reflections/` and `tests/`, which
    test its insides) imports from it only what its `__all__` names: a name of the package
    (`from virtual_reflections import Params`) or a module listed there
    (`from virtual_reflections.imagefiles import read_rgba`, also by name in
    `import_module`); the engine's other modules are its own. What it imports from a listed
    module carries a numpydoc docstring, as rule 6's (issue 43, item 4).

And one on the Blender layer's rooms (issue 43, item 4):
12. `operators/` imports one way between its rooms: `scene/` (the scene's data) imports no
    other room of it, `node_trees/` only `scene/`, the modules at the top of `operators/` (the
    map pipeline and the features) only those two, and `batch/` and `ops.py` (the two entries)
    anything but each other; a room's `__init__.py` imports nothing of the add-on.

And one on every Python file of the repository but the tests (issue 43, item 6):
13. no function or method is longer than MAX_FUNCTION_LINES (80) lines, from its `def` to its
    last line: a longer one is split where a reader loses the thread.
"""

from __future__ import annotations

import ast
from dataclasses import dataclass
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]

# Top-level names of the product: the root package "" is its __init__.py.
PRODUCT = ("", "dependencies", "preferences", "operators", "ui", "virtual_reflections")
RESEARCH = ("study", "benchmarks", "tests")
ENGINE = "virtual_reflections"
BLENDER_ONLY = (
    "bpy", "bpy_extras", "bpy_types", "bmesh", "mathutils", "gpu", "gpu_extras", "blf",
    "bl_math", "bl_ui", "bl_operators", "idprop", "aud", "freestyle",
)  # fmt: skip
# "": the add-on's root __init__.py
NOT_IN_ENGINE = ("operators", "ui", "preferences", "dependencies", "")
SKIP_DIRS = {"__pycache__", "node_modules"}


# --- the checker ---------------------------------------------------------------------------


def discover(root: Path) -> dict[str, Path]:
    """{module name: file} of the package at `root`: its __init__.py, its top-level .py files
    that are part of it (those of `top_modules`) and every package folder below it."""
    modules = {}
    if (root / "__init__.py").is_file():
        modules[""] = root / "__init__.py"
    for path in sorted(root.glob("*.py")):
        if path.stem != "__init__" and path.stem in top_modules(root):
            modules[path.stem] = path
    for folder in top_packages(root):
        for path in sorted((root / folder).rglob("*.py")):
            parts = path.relative_to(root).with_suffix("").parts
            if any(p in SKIP_DIRS or p.startswith(".") for p in parts):
                continue
            # Only files whose every folder is a package (has an __init__.py).
            if not all(
                (root.joinpath(*parts[:i]) / "__init__.py").is_file() for i in range(1, len(parts))
            ):
                continue
            if parts[-1] == "__init__":
                parts = parts[:-1]
            modules[".".join(parts)] = path
    return modules


def top_packages(root: Path) -> list[str]:
    """Top-level folders of `root` that are Python packages (hidden folders skipped)."""
    return sorted(
        p.name
        for p in root.iterdir()
        if p.is_dir()
        and not p.name.startswith(".")
        and p.name not in SKIP_DIRS
        and (p / "__init__.py").is_file()
    )


def top_modules(root: Path) -> set[str]:
    """Top-level .py modules that belong to the package (the others are scripts)."""
    return {name for name in PRODUCT if name and (root / f"{name}.py").is_file()}


def display(name: str, modules: dict[str, Path], root: Path) -> str:
    """A module's file path relative to the root (or the dotted name if it has no file)."""
    path = modules.get(name)
    return path.relative_to(root).as_posix() if path else (name or "__init__.py")


@dataclass(frozen=True)
class Import:
    """One import of a file.

    target:  dotted name from the package root ("" the root package) for the package's own and
             relative imports, else the absolute name as written (e.g. "bpy.props").
    names:   what `from ... import` took from `target` that is not a submodule.
    binding: (local name, dotted module) when the statement binds a name to a module.
    internal: the target is inside the repository (relative, or absolute from a top-level
             name of it); only internal targets are resolved against the package's modules.
    """

    target: str
    line: int
    names: tuple[str, ...] = ()
    binding: tuple[str, str] | None = None
    internal: bool = True


def _package_of(name: str, path: Path) -> str:
    """The package a module's relative imports start from."""
    if path.name == "__init__.py":
        return name
    return name.rpartition(".")[0]


def _join(*parts: str) -> str:
    return ".".join(p for p in parts if p)


def _resolve_from(node: ast.ImportFrom, name: str, path: Path) -> str | None:
    """The dotted module a `from ... import` reads from; None when it climbs above the root."""
    if node.level == 0:
        return node.module or ""
    package = _package_of(name, path)
    parts = package.split(".") if package else []
    up = node.level - 1
    if up > len(parts):
        return None
    return _join(".".join(parts[: len(parts) - up]), node.module or "")


def file_imports(name: str, modules: dict[str, Path], local: set[str]) -> list[Import]:
    """Every import of module `name`, anywhere in its file, resolved (see module docstring).

    `local`: top-level names that belong to the repository, so that absolute imports such as
    `import operators` or `from virtual_reflections import x` resolve like relative ones.
    """
    path = modules[name]
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                # `import a.b` binds a to module a; `import a.b as c` binds c to a.b.
                if alias.asname:
                    binding = (alias.asname, alias.name)
                else:
                    top = alias.name.split(".")[0]
                    binding = (top, top)
                internal = alias.name.split(".")[0] in local
                found.append(Import(alias.name, node.lineno, (), binding, internal))
        elif isinstance(node, ast.ImportFrom):
            base = _resolve_from(node, name, path)
            if base is None:
                continue
            if node.level == 0 and base.split(".")[0] not in local:
                names = tuple(a.name for a in node.names)
                found.append(Import(base, node.lineno, names, None, False))
                continue
            names = []
            for alias in node.names:
                sub = _join(base, alias.name)
                if alias.name != "*" and sub in modules:
                    found.append(Import(sub, node.lineno, (), (alias.asname or alias.name, sub)))
                else:
                    names.append(alias.name)
            if names:
                found.append(Import(base, node.lineno, tuple(names)))
    return found


def all_imports(modules: dict[str, Path], root: Path) -> dict[str, list[Import]]:
    local = set(top_packages(root)) | top_modules(root) | set(RESEARCH)
    return {name: file_imports(name, modules, local) for name in modules}


def known_module(target: str, modules: dict[str, Path]) -> str | None:
    """The package module an import target names: itself, or its longest existing prefix
    (never the root package for a target below it: `tests.x` is no import of __init__.py)."""
    if target == "":
        return "" if "" in modules else None
    parts = target.split(".")
    for i in range(len(parts), 0, -1):
        candidate = ".".join(parts[:i])
        if candidate in modules:
            return candidate
    return None


def import_graph(modules: dict[str, Path], imports: dict[str, list[Import]]):
    """{module: set of the package's modules it imports} (self-imports dropped)."""
    graph = {name: set() for name in modules}
    for name, found in imports.items():
        for imp in found:
            if not imp.internal:
                continue
            target = known_module(imp.target, modules)
            if target is not None and target != name:
                graph[name].add(target)
    return graph


def find_cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Every elementary cycle of `graph`, each starting at its smallest module and closed
    (["a", "b", "a"]), sorted by length then name."""
    cycles = []
    order = sorted(graph)
    rank = {n: i for i, n in enumerate(order)}
    for start in order:
        # Simple paths from `start` through modules ranked above it, back to `start`.
        stack = [(start, iter(sorted(graph[start])))]
        path, on_path = [start], {start}
        while stack:
            node, children = stack[-1]
            for child in children:
                if child == start:
                    cycles.append(path + [start])
                elif child not in on_path and rank.get(child, -1) > rank[start]:
                    path.append(child)
                    on_path.add(child)
                    stack.append((child, iter(sorted(graph.get(child, ())))))
                    break
            else:
                stack.pop()
                on_path.discard(path.pop())
    return sorted(cycles, key=lambda c: (len(c), c))


def _private(name: str) -> bool:
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


def private_uses(modules: dict[str, Path], imports: dict[str, list[Import]], root: Path):
    """Messages for every use of another module's private name: `from .x import _name` and
    `x._name` where x is bound to one of the package's modules in that file."""
    problems = []
    for name, found in imports.items():
        where = display(name, modules, root)
        bound = {}  # local name -> package module, from every import in the file
        for imp in found:
            if imp.internal and imp.binding is not None and imp.binding[1] in modules:
                bound[imp.binding[0]] = imp.binding[1]
            owner = known_module(imp.target, modules) if imp.internal else None
            if owner is None or owner == name:
                continue
            for n in imp.names:
                if _private(n):
                    problems.append(
                        (
                            name,
                            imp.line,
                            f"{where}:{imp.line} imports {n} from "
                            f"{display(owner, modules, root)} (private)",
                        )
                    )
        tree = ast.parse(modules[name].read_text(encoding="utf-8"))
        for node in ast.walk(tree):
            if isinstance(node, ast.Attribute) and _private(node.attr):
                owner = _module_expr(node.value, bound, modules)
                if owner is not None and owner != name:
                    problems.append(
                        (
                            name,
                            node.lineno,
                            f"{where}:{node.lineno} uses {ast.unparse(node)}, "
                            f"a private name of {display(owner, modules, root)}",
                        )
                    )
    return [message for *_, message in sorted(set(problems))]


def _module_expr(node: ast.expr, bound: dict[str, str], modules: dict[str, Path]) -> str | None:
    """The package module an expression names (`x`, `x.sub`), or None."""
    if isinstance(node, ast.Name):
        return bound.get(node.id)
    if isinstance(node, ast.Attribute):
        owner = _module_expr(node.value, bound, modules)
        if owner is not None and _join(owner, node.attr) in modules:
            return _join(owner, node.attr)
    return None


def _top(target: str) -> str:
    return target.split(".")[0] if target else ""


def forbidden_imports(modules, imports, root, importers, forbidden, why):
    """Messages for imports by modules whose top-level name is in `importers` of targets whose
    top-level name is in `forbidden` ("" is the root package)."""
    problems = []
    for name, found in imports.items():
        if _top(name) not in importers:
            continue
        for imp in found:
            if _top(imp.target) in forbidden:
                shown = display(imp.target, modules, root) if imp.target in modules else imp.target
                if imp.names:
                    shown += f" ({', '.join(imp.names)})"
                problems.append(
                    (
                        name,
                        imp.line,
                        f"{display(name, modules, root)}:{imp.line} imports {shown} ({why})",
                    )
                )
    return [message for *_, message in sorted(set(problems))]


def check(root: Path) -> dict[str, list[str]]:
    """All four rules on the package at `root`: {rule: problem messages}."""
    modules = discover(root)
    imports = all_imports(modules, root)
    graph = import_graph(modules, imports)
    cycles = [" -> ".join(display(n, modules, root) for n in cycle) for cycle in find_cycles(graph)]
    research = (set(top_packages(root)) - set(PRODUCT)) | set(RESEARCH)
    return {
        "cycles": cycles,
        "private": private_uses(modules, imports, root),
        "engine": forbidden_imports(
            modules,
            imports,
            root,
            {ENGINE},
            set(BLENDER_ONLY) | set(NOT_IN_ENGINE),
            "the engine must not import Blender or the add-on",
        ),
        "research": forbidden_imports(
            modules,
            imports,
            root,
            set(PRODUCT),
            research,
            "the product must not import research code",
        ),
    }


def _report(title: str, problems: list[str]) -> str:
    return f"{len(problems)} {title}:\n  " + "\n  ".join(problems)


# --- the rules on the repository -----------------------------------------------------------


@pytest.fixture(scope="module")
def repo_problems():
    return check(REPO)


def test_the_checker_sees_the_whole_extension():
    modules = discover(REPO)
    for name in ("", "dependencies", "preferences", "operators", "ui", "virtual_reflections"):
        assert name in modules, f"{name or '__init__'} not found"
    for package in ("operators", "ui", "virtual_reflections"):
        assert any(m.startswith(package + ".") for m in modules), f"no modules in {package}/"
    assert not set(PRODUCT) & set(RESEARCH)  # research is never part of the product


def test_no_import_cycles(repo_problems):
    cycles = repo_problems["cycles"]
    assert not cycles, _report("import cycles (break each one)", cycles)


def test_no_private_names_across_modules(repo_problems):
    private = repo_problems["private"]
    assert not private, _report("uses of another module's private name", private)


def test_engine_never_imports_blender_or_the_addon(repo_problems):
    engine = repo_problems["engine"]
    assert not engine, _report("engine imports of Blender or the add-on", engine)


def test_product_never_imports_research(repo_problems):
    research = repo_problems["research"]
    assert not research, _report("product imports of research packages", research)


# --- the checker on synthetic packages -----------------------------------------------------


def _package(root: Path, files: dict[str, str]) -> Path:
    for rel, text in files.items():
        path = root / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text, encoding="utf-8")
    return root


def test_a_cycle_through_a_function_level_import_is_found(tmp_path):
    root = _package(
        tmp_path,
        {
            "__init__.py": "from . import operators\n",
            "operators/__init__.py": "from . import a\n",
            "operators/a.py": "from . import b\n",
            "operators/b.py": "def f():\n    from .a import thing\n    return thing\n",
        },
    )
    assert check(root)["cycles"] == ["operators/a.py -> operators/b.py -> operators/a.py"]


def test_a_cycle_across_packages_and_every_cycle_is_listed(tmp_path):
    root = _package(
        tmp_path,
        {
            "__init__.py": "",
            "preferences.py": "from .ui.properties import ITEMS\n",
            "ui/__init__.py": "",
            "ui/properties.py": "ITEMS = ()\ndef f():\n    from ..operators import live\n",
            "operators/__init__.py": "",
            "operators/live.py": "from . import generate\n",
            "operators/generate.py": "def g():\n    from .. import preferences\n"
            "    from . import live\n",
        },
    )
    assert check(root)["cycles"] == [
        "operators/generate.py -> operators/live.py -> operators/generate.py",
        "operators/generate.py -> preferences.py -> ui/properties.py -> operators/live.py"
        " -> operators/generate.py",
    ]


def test_a_clean_package_passes(tmp_path):
    root = _package(
        tmp_path,
        {
            "__init__.py": "from . import operators, preferences\n",
            "preferences.py": "import bpy\nfrom .operators import generate\n",
            "operators/__init__.py": "from . import generate\n",
            "operators/generate.py": (
                "import bpy\nfrom ..virtual_reflections import segment\n"
                "from ..virtual_reflections.layouts import map_shape as shape\n"
                "from . import maps\n\ndef f():\n    return maps.store(shape), maps.__name__\n"
            ),
            "operators/maps.py": "import os\ndef store(x):\n    return os.sep, _helper()\n"
            "def _helper():\n    return 1\n",
            "virtual_reflections/__init__.py": "from .segmentation import segment\n",
            "virtual_reflections/segmentation.py": "import numpy as np\n"
            "from .layouts import map_shape\ndef segment():\n    return np._NoValue\n",
            "virtual_reflections/layouts.py": "def map_shape():\n    pass\n",
            "tests/test_x.py": "from virtual_reflections import segment\n",
            "benchmarks/bench.py": "import operators\n",
        },
    )
    assert check(root) == {"cycles": [], "private": [], "engine": [], "research": []}


def test_private_names_are_flagged_both_ways(tmp_path):
    root = _package(
        tmp_path,
        {
            "__init__.py": "",
            "operators/__init__.py": "",
            "operators/a.py": "_x = 1\n__version__ = 2\ndef _f():\n    pass\n",
            "operators/b.py": "from .a import _x, __version__\n",
            "operators/c.py": "from . import a\n\ndef g():\n    return a._f(), a.__name__\n",
            "operators/d.py": "from . import a\nfrom .. import operators as ops\n"
            "print(a.public, ops.a.__doc__)\n",
            "ui/__init__.py": "",
            "ui/panel.py": "def h():\n    from ..operators import a as mod\n"
            "    import operators.a\n    return mod._x, operators.a._f\n",
        },
    )
    assert check(root)["private"] == [
        "operators/b.py:1 imports _x from operators/a.py (private)",
        "operators/c.py:4 uses a._f, a private name of operators/a.py",
        "ui/panel.py:4 uses mod._x, a private name of operators/a.py",
        "ui/panel.py:4 uses operators.a._f, a private name of operators/a.py",
    ]


def test_from_package_import_module_then_public_attribute_is_fine(tmp_path):
    root = _package(
        tmp_path,
        {
            "__init__.py": "",
            "operators/__init__.py": "",
            "operators/a.py": "public = 1\n_hidden = 2\n",
            "operators/b.py": "from . import a\nvalue = a.public\n",
            "operators/c.py": "def f(self):\n    return self._cache, _local._x\n_local = None\n",
        },
    )
    assert check(root)["private"] == []


def test_engine_and_research_rules(tmp_path):
    root = _package(
        tmp_path,
        {
            "__init__.py": "from .operators import x\n",
            "preferences.py": "def f():\n    from .study import runs\n",
            "ui/__init__.py": "import benchmarks.speed\n",
            "operators/__init__.py": "",
            "operators/x.py": "from ..tests import helpers\n",
            "study/__init__.py": "from ..operators import x\n",
            "study/runs.py": "",
            "virtual_reflections/__init__.py": "",
            "virtual_reflections/a.py": "def f():\n    import bpy.props\n"
            "    from .. import preferences\n",
            "virtual_reflections/b.py": "from ..ui import panel\nfrom ..operators.x import y\n"
            "import mathutils\n",
        },
    )
    problems = check(root)
    assert problems["cycles"] == []  # `from ..tests import` is no edge to __init__.py
    assert problems["engine"] == [
        "virtual_reflections/a.py:2 imports bpy.props "
        "(the engine must not import Blender or the add-on)",
        "virtual_reflections/a.py:3 imports preferences.py "
        "(the engine must not import Blender or the add-on)",
        "virtual_reflections/b.py:1 imports ui/__init__.py (panel) "
        "(the engine must not import Blender or the add-on)",
        "virtual_reflections/b.py:2 imports operators/x.py (y) "
        "(the engine must not import Blender or the add-on)",
        "virtual_reflections/b.py:3 imports mathutils "
        "(the engine must not import Blender or the add-on)",
    ]
    assert problems["research"] == [
        "operators/x.py:1 imports tests (helpers) (the product must not import research code)",
        "preferences.py:2 imports study/runs.py (the product must not import research code)",
        "ui/__init__.py:1 imports benchmarks.speed (the product must not import research code)",
    ]


# --- rule 5: no abbreviated options ----------------------------------------------------------


def python_files(root: Path) -> list[Path]:
    """Every .py file under root, hidden folders (.venv, .git) and SKIP_DIRS aside."""
    return [
        path
        for path in sorted(root.rglob("*.py"))
        if not any(p in SKIP_DIRS or p.startswith(".") for p in path.relative_to(root).parts)
    ]


def _called_name(func: ast.expr) -> str | None:
    return func.attr if isinstance(func, ast.Attribute) else getattr(func, "id", None)


def abbreviating_parsers(root: Path) -> list[str]:
    """`file:line` of each parser made without `allow_abbrev=False` (rule 5)."""
    problems = []
    for path in python_files(root):
        where = path.relative_to(root).as_posix()
        tree = ast.parse(path.read_text(encoding="utf-8"), filename=where)
        parsers = {"ArgumentParser"} | {
            node.name
            for node in ast.walk(tree)
            if isinstance(node, ast.ClassDef)
            and any(_called_name(base) == "ArgumentParser" for base in node.bases)
        }
        for node in ast.walk(tree):
            if not isinstance(node, ast.Call):
                continue
            name = _called_name(node.func)
            if name in parsers or (name == "add_parser" and isinstance(node.func, ast.Attribute)):
                if not any(
                    k.arg == "allow_abbrev"
                    and isinstance(k.value, ast.Constant)
                    and k.value.value is False
                    for k in node.keywords
                ):
                    problems.append(f"{where}:{node.lineno} {name}(...)")
    return problems


def test_no_parser_takes_abbreviated_options():
    problems = abbreviating_parsers(REPO)
    assert not problems, _report("parsers without allow_abbrev=False (add it)", problems)


def test_the_parser_rule_sees_subclasses_and_sub_commands(tmp_path):
    root = _package(
        tmp_path,
        {
            "a.py": "import argparse\nclass P(argparse.ArgumentParser):\n    pass\n"
            "p = P(prog='a')\nq = argparse.ArgumentParser(allow_abbrev=False)\n"
            "s = q.add_subparsers().add_parser('x')\n",
            "b/c.py": "from argparse import ArgumentParser\nArgumentParser(allow_abbrev=True)\n",
            ".venv/d.py": "import argparse\nargparse.ArgumentParser()\n",
        },
    )
    assert abbreviating_parsers(root) == [
        "a.py:4 P(...)",
        "a.py:6 add_parser(...)",
        "b/c.py:2 ArgumentParser(...)",
    ]


# --- the engine's public names are documented (numpydoc) -----------------------------------


def engine_public_defs(root: Path) -> dict[str, ast.AST]:
    """{dotted name: def or class node} of every function or class in `__all__` of the engine's
    `__init__.py` (imported there `from .module import name`), and of the public top-level
    functions of every module it lists (`from . import cache`)."""
    package = root / ENGINE
    tree = ast.parse((package / "__init__.py").read_text(encoding="utf-8"))
    names = next(
        ast.literal_eval(node.value)
        for node in tree.body
        if isinstance(node, ast.Assign)
        and any(getattr(t, "id", "") == "__all__" for t in node.targets)
    )
    origin = {}  # name -> (module, name there, whole module?)
    for node in tree.body:
        if isinstance(node, ast.ImportFrom) and node.level == 1:
            for alias in node.names:
                if node.module:
                    origin[alias.asname or alias.name] = (node.module, alias.name, False)
                else:
                    origin[alias.asname or alias.name] = (alias.name, None, True)
    defs = {}
    for name in names:
        if name not in origin:
            continue
        module, there, whole = origin[name]
        body = ast.parse((package / f"{module}.py").read_text(encoding="utf-8")).body
        for node in body:
            if not isinstance(node, (ast.FunctionDef, ast.ClassDef)):
                continue
            if (whole and not node.name.startswith("_") and isinstance(node, ast.FunctionDef)) or (
                not whole and node.name == there
            ):
                defs[f"{module}.{node.name}"] = node
    return defs


def docstring_problems(defs: dict[str, ast.AST]) -> list[str]:
    """Each def without a numpydoc docstring: a one-line summary (ending in a full stop, a
    blank line or nothing after it) and, for a function that takes parameters, a Parameters
    section."""
    problems = []
    for name, node in sorted(defs.items()):
        doc = ast.get_docstring(node)
        if not doc:
            problems.append(f"{name}: no docstring")
            continue
        lines = doc.splitlines()
        if not lines[0].strip().endswith(".") or (len(lines) > 1 and lines[1].strip()):
            problems.append(f"{name}: the first line is not a one-line summary")
        if isinstance(node, ast.FunctionDef):
            a = node.args
            takes = [*a.posonlyargs, *a.args, *a.kwonlyargs, *filter(None, (a.vararg, a.kwarg))]
            if takes and not any(
                line.strip() == "Parameters" and nxt.strip().startswith("---")
                for line, nxt in zip(lines, lines[1:])
            ):
                problems.append(f"{name}: no Parameters section")
    return problems


def test_the_engine_public_names_have_numpydoc_docstrings():
    defs = engine_public_defs(REPO)
    assert {"envmap.environment_map", "params.Params", "cache.set_limit"} <= set(defs)
    problems = docstring_problems(defs)
    assert not problems, _report("engine public names without a numpydoc docstring", problems)


def test_the_docstring_rule_sees_summaries_and_parameters(tmp_path):
    good = '"""Do it.\n\n    Parameters\n    ----------\n    x : int\n        The x.\n    """'
    root = _package(
        tmp_path,
        {
            f"{ENGINE}/__init__.py": "from . import c\nfrom .m import A, f, g, h\n"
            "__all__ = ['A', 'c', 'f', 'g']\n",
            f"{ENGINE}/m.py": f"class A:\n    '''An a; semicolons\n    run on.'''\n"
            f"def f(x):\n    {good}\ndef g(x):\n    '''Do it.'''\ndef h():\n    pass\n",
            f"{ENGINE}/c.py": "def k():\n    '''K.'''\ndef _p():\n    pass\ndef q(y):\n    pass\n",
        },
    )
    defs = engine_public_defs(root)
    assert sorted(defs) == ["c.k", "c.q", "m.A", "m.f", "m.g"]
    assert docstring_problems(defs) == [
        "c.q: no docstring",
        "m.A: the first line is not a one-line summary",
        "m.g: no Parameters section",
    ]


# --- rules 7-9: one definition of each choice list, of the triangles limit, of the CLI layer --

DEFINITIONS = f"{ENGINE}/methods.py"  # the methods, the Surroundings, the looks, MAX_TRIANGLES
CLI_COMMON = f"{ENGINE}/cli_common.py"  # exit codes, Terminated, the one-line parser
CHOICE_LISTS = {
    "methods": {"ground", "camera", "paper"},
    "surroundings": {"auto", "open", "enclosed", "world", "custom"},
    "combine modes": {"replace", "modulate", "mix", "world"},
}
# Lists whose parts are decided there too (methods.uses_camera..., methods.WHOLE_SURFACE_LOOKS)
PARTS_DECIDED = ("methods", "combine modes")
TRIANGLES_LIMIT = 1024


def product_files(root: Path) -> dict[str, Path]:
    """{file path: file} of the product's modules and render_shot.py (its batch entry)."""
    files = {
        path.relative_to(root).as_posix(): path
        for name, path in discover(root).items()
        if name.partition(".")[0] in PRODUCT
    }
    if (root / "render_shot.py").is_file():
        files["render_shot.py"] = root / "render_shot.py"
    return dict(sorted(files.items()))


def _strings(node: ast.expr) -> list[str] | None:
    """The strings of a tuple, list or set literal of string constants only, or the first
    strings of a literal of such tuples (Blender's enum items: (key, label, description)),
    else None."""
    if not isinstance(node, (ast.Tuple, ast.List, ast.Set)) or len(node.elts) < 2:
        return None
    firsts = [e.elts[0] if isinstance(e, ast.Tuple) and e.elts else e for e in node.elts]
    if not all(isinstance(e, ast.Constant) and isinstance(e.value, str) for e in firsts):
        return None
    return [e.value for e in firsts]


def spelled_choice_lists(root: Path) -> list[str]:
    """`file:line` of each literal that spells a choice list outside its definition (rule 7):
    all of one list's names and nothing else, in any order and case (argparse's
    `choices=(...)`, a second list to check against); for the methods and the looks also two
    of them (`("CAMERA", "GROUND")`: a module re-deciding what a method or a look does,
    which virtual_reflections.methods says)."""
    problems = []
    for where, path in product_files(root).items():
        if where == DEFINITIONS:
            continue
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), filename=where)):
            names = _strings(node)
            if names is None:
                continue
            folded = {n.lower() for n in names}
            for what, choices in CHOICE_LISTS.items():
                if folded == choices or (what in PARTS_DECIDED and folded <= choices):
                    problems.append(f"{where}:{node.lineno} {what} {tuple(names)}")
                    break
    return sorted(problems, key=lambda p: (p.split(":")[0], int(p.split(":")[1].split()[0])))


def _statements(tree: ast.AST):
    """(statement, the text that says what it is about) of every statement: a simple one
    whole; a compound one (if, for, def...) by its header, not its body."""
    for node in ast.walk(tree):
        if not isinstance(node, ast.stmt):
            continue
        body = [
            n for f in ("body", "orelse", "finalbody", "handlers") for n in getattr(node, f, [])
        ]
        yield node, [n for n in ast.iter_child_nodes(node) if n not in body]


def triangles_limits(root: Path) -> list[str]:
    """`file:line` of each spelling of the triangles limit outside its definition (rule 8):
    the number in a statement about triangles (or in the if statement whose body is about
    them), or a text naming triangles and the number."""
    limit = str(TRIANGLES_LIMIT)
    problems = []
    for where, path in product_files(root).items():
        if where == DEFINITIONS:
            continue
        text = path.read_text(encoding="utf-8")
        tree = ast.parse(text, filename=where)
        for node, header in _statements(tree):
            numbers = [
                n
                for part in header
                for n in ast.walk(part)
                if isinstance(n, ast.Constant) and n.value == TRIANGLES_LIMIT
            ]
            about = (ast.get_source_segment(text, node) or "").lower()
            if numbers and "triangle" in about:
                problems.append(f"{where}:{numbers[0].lineno} {TRIANGLES_LIMIT}")
        for n in ast.walk(tree):
            if isinstance(n, ast.Constant) and isinstance(n.value, str):
                if "triangle" in n.value.lower() and limit in n.value:
                    problems.append(f"{where}:{n.lineno} {n.value[:50]!r}")
    return sorted(set(problems))


def cli_layers(root: Path) -> list[str]:
    """`file:line` of each exit code or argparse parser class defined outside the shared
    command-line layer (rule 9): `EXIT_... = <number>`, `class X(argparse.ArgumentParser)`,
    `class Terminated(...)`."""
    problems = []
    for where, path in product_files(root).items():
        if where == CLI_COMMON:
            continue
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), filename=where)):
            if isinstance(node, ast.Assign) and isinstance(node.value, ast.Constant):
                for target in node.targets:
                    if isinstance(target, ast.Name) and target.id.startswith("EXIT_"):
                        problems.append(f"{where}:{node.lineno} {target.id}")
            if isinstance(node, ast.ClassDef) and (
                node.name == "Terminated"
                or any(_called_name(base) == "ArgumentParser" for base in node.bases)
            ):
                problems.append(f"{where}:{node.lineno} class {node.name}")
    return problems


def test_each_choice_list_is_spelled_once():
    problems = spelled_choice_lists(REPO)
    assert not problems, _report(
        f"choice lists spelled outside {DEFINITIONS} (derive them, or ask its predicates)",
        problems,
    )


def test_the_triangles_limit_is_spelled_once():
    problems = triangles_limits(REPO)
    assert not problems, _report(
        f"triangles limits outside {DEFINITIONS} (MAX_TRIANGLES)", problems
    )


def test_one_command_line_layer():
    problems = cli_layers(REPO)
    assert not problems, _report(f"command-line pieces outside {CLI_COMMON}", problems)


def test_the_rules_7_to_9_see_what_they_guard(tmp_path):
    """Each rule finds the spellings the code had before issue 43 (items 1 and 5)."""
    root = _package(
        tmp_path,
        {
            "operators/__init__.py": "",
            "operators/pipeline.py": "def f(s):\n    return s.method in ('CAMERA', 'GROUND')\n"
            "LOOKS = ('REPLACE', 'MODULATE')\n",
            "operators/batch_options.py": "SURROUNDINGS = ('auto', 'open', 'enclosed', "
            "'world', 'custom')\ndef g(t):\n    if not 4 <= t <= 1024:\n"
            "        raise ValueError(f'--triangles must be from 4 to 1024, not {t}')\n",
            "ui/__init__.py": "",
            "ui/properties.py": "P = dict(name='Triangles', max=1024)\n"
            "W = dict(name='Resolution', default=1024)\n"
            "ITEMS = (('AUTO', 'Auto', ''), ('OPEN', 'Open', ''), ('ENCLOSED', 'E', ''),\n"
            "    ('WORLD', 'W', ''), ('CUSTOM', 'C', ''))\n",
            f"{ENGINE}/__init__.py": "",
            f"{ENGINE}/methods.py": "METHODS = ('ground', 'camera', 'paper')\nMAX = 1024\n",
            f"{ENGINE}/cli.py": "import argparse\nEXIT_FAILED = 1\n"
            "class Terminated(KeyboardInterrupt):\n    pass\n"
            "class _P(argparse.ArgumentParser):\n    pass\n",
            f"{ENGINE}/cli_common.py": "EXIT_FAILED = 1\n",
            "render_shot.py": "import argparse\np = argparse.ArgumentParser(allow_abbrev=False)\n"
            "p.add_argument('--combine', choices=('REPLACE', 'MODULATE', 'MIX', 'WORLD'))\n"
            "EXIT_BAD_INPUT = 2\n",
        },
    )
    assert spelled_choice_lists(root) == [
        "operators/batch_options.py:1 surroundings ('auto', 'open', 'enclosed', 'world', 'custom')",
        "operators/pipeline.py:2 methods ('CAMERA', 'GROUND')",
        "operators/pipeline.py:3 combine modes ('REPLACE', 'MODULATE')",
        "render_shot.py:3 combine modes ('REPLACE', 'MODULATE', 'MIX', 'WORLD')",
        "ui/properties.py:3 surroundings ('AUTO', 'OPEN', 'ENCLOSED', 'WORLD', 'CUSTOM')",
    ]
    assert triangles_limits(root) == [
        "operators/batch_options.py:3 1024",
        "operators/batch_options.py:4 '--triangles must be from 4 to 1024, not '",
        "ui/properties.py:1 1024",
    ]
    assert cli_layers(root) == [
        "render_shot.py:4 EXIT_BAD_INPUT",
        f"{ENGINE}/cli.py:2 EXIT_FAILED",
        f"{ENGINE}/cli.py:3 class Terminated",
        f"{ENGINE}/cli.py:5 class _P",
    ]


# --- rule 10: a lookup table writes itself through its layers --------------------------------

TABLE = f"{ENGINE}/table.py"


def table_payloads(root: Path) -> list[str]:
    """Optional fields of LookupTable (in TABLE) but `fill`, and every `table.X is (not) None`
    test in the engine but on `fill`: "path:line what"."""
    problems = []
    package = root / ENGINE
    for path in sorted(package.glob("*.py")):
        where = path.relative_to(root).as_posix()
        tree = ast.parse(path.read_text(encoding="utf-8"))
        for node in ast.walk(tree):
            if where == TABLE and isinstance(node, ast.ClassDef) and node.name == "LookupTable":
                for item in node.body:
                    if (
                        isinstance(item, ast.AnnAssign)
                        and "None" in ast.unparse(item.annotation)
                        and item.target.id != "fill"
                    ):
                        problems.append(f"{where}:{item.lineno} LookupTable.{item.target.id}")
            if isinstance(node, ast.Compare) and any(
                isinstance(op, (ast.Is, ast.IsNot)) for op in node.ops
            ):
                left = node.left
                if (
                    isinstance(left, ast.Attribute)
                    and isinstance(left.value, ast.Name)
                    and left.value.id == "table"
                    and left.attr != "fill"
                    and any(
                        isinstance(c, ast.Constant) and c.value is None for c in node.comparators
                    )
                ):
                    problems.append(f"{where}:{node.lineno} {ast.unparse(node)}")
    return problems


def test_a_lookup_table_writes_itself_through_its_layers():
    problems = table_payloads(REPO)
    assert not problems, _report("optional table payloads (make them layers: layers.py)", problems)


def test_the_rule_10_sees_the_payload_ladder(tmp_path):
    """The rule finds the table and the ladder of before issue 43, item 2."""
    root = _package(
        tmp_path,
        {
            f"{ENGINE}/__init__.py": "",
            f"{ENGINE}/table.py": "class LookupTable:\n    levels: int\n"
            "    index: np.ndarray | None\n    fill: Fill | None = None\n"
            "    trilinear: Trilinear | None = None\n",
            f"{ENGINE}/envmap.py": "def apply_table(table, out):\n"
            "    if table.fill is not None:\n        pass\n"
            "    if table.trilinear is not None and table.index is None:\n        pass\n",
        },
    )
    assert table_payloads(root) == [
        f"{ENGINE}/envmap.py:4 table.trilinear is not None",
        f"{ENGINE}/envmap.py:4 table.index is None",
        f"{ENGINE}/table.py:3 LookupTable.index",
        f"{ENGINE}/table.py:5 LookupTable.trilinear",
    ]


# --- rule 11: outside code imports only what the engine's __all__ names --------------------


def engine_surface(root: Path) -> set[str]:
    """The names of the engine's `__all__`: its own names and the modules others may import."""
    tree = ast.parse((root / ENGINE / "__init__.py").read_text(encoding="utf-8"))
    return set(
        next(
            ast.literal_eval(node.value)
            for node in tree.body
            if isinstance(node, ast.Assign)
            and any(getattr(t, "id", "") == "__all__" for t in node.targets)
        )
    )


def engine_imports_from_outside(root: Path) -> list[tuple[str, int, str, tuple[str, ...]]]:
    """(file, line, engine module or "" for the package, names taken) of every import of the
    engine by a Python file outside it and outside tests/: `import`, `from ... import` (relative
    ones resolved from the file's folder) and a literal "...virtual_reflections.<module>"
    handed to `import_module`."""
    found = []
    for path in python_files(root):
        parts = path.relative_to(root).parts
        if parts[0] in (ENGINE, "tests"):
            continue
        where = path.relative_to(root).as_posix()
        tree = ast.parse(path.read_text(encoding="utf-8"), filename=where)
        package = list(parts[:-1])
        for node in ast.walk(tree):
            targets = []
            if isinstance(node, ast.Import):
                targets = [(a.name, ()) for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    up = node.level - 1
                    if up > len(package):
                        continue
                    base = _join(".".join(package[: len(package) - up]), base)
                targets = [(base, tuple(a.name for a in node.names))]
            elif isinstance(node, ast.Call) and _called_name(node.func) == "import_module":
                for arg in ast.walk(node):
                    if isinstance(arg, ast.Constant) and isinstance(arg.value, str):
                        text = arg.value.lstrip(".")
                        if text == ENGINE or text.startswith(ENGINE + "."):
                            targets.append((text, ()))
                        elif f".{ENGINE}." in arg.value:
                            targets.append((ENGINE + arg.value.split(f".{ENGINE}", 1)[1], ()))
            for target, names in targets:
                dotted = target.split(".")
                if dotted[0] != ENGINE:
                    continue
                module = dotted[1] if len(dotted) > 1 else ""
                found.append((where, node.lineno, module, names))
    return found


def outside_engine_imports(root: Path) -> list[str]:
    """`file:line what` of each import from outside the engine of a module or a name its
    `__all__` does not list (rule 11)."""
    surface = engine_surface(root)
    problems = []
    for where, line, module, names in engine_imports_from_outside(root):
        if module:
            if module not in surface:
                problems.append(f"{where}:{line} {ENGINE}.{module}")
        else:
            problems += [f"{where}:{line} {ENGINE}.{n}" for n in names if n not in surface]
    return sorted(set(problems))


def engine_defs_used_outside(root: Path) -> dict[str, ast.AST]:
    """{module.name: def or class node} of the public names outside code imports from a listed
    module."""
    wanted = {}
    for _, _, module, names in engine_imports_from_outside(root):
        if module:
            wanted.setdefault(module, set()).update(names)
    defs = {}
    for module, names in wanted.items():
        path = root / ENGINE / f"{module}.py"
        if not path.is_file():
            continue
        for node in ast.parse(path.read_text(encoding="utf-8")).body:
            if isinstance(node, (ast.FunctionDef, ast.ClassDef)) and node.name in names:
                if not _private(node.name):
                    defs[f"{module}.{node.name}"] = node
    return defs


def test_outside_code_imports_only_the_engines_public_surface():
    problems = outside_engine_imports(REPO)
    assert not problems, _report(
        "imports of engine modules or names its __all__ does not list (list them there or "
        "take them from a listed module)",
        problems,
    )


def test_what_outside_code_imports_from_the_engine_is_documented():
    defs = engine_defs_used_outside(REPO)
    assert {"imagefiles.read_rgba", "atomic_files.commit"} <= set(defs)
    problems = docstring_problems(defs)
    assert not problems, _report("engine names used outside without a numpydoc docstring", problems)


def test_the_rule_11_sees_every_way_in(tmp_path):
    root = _package(
        tmp_path,
        {
            f"{ENGINE}/__init__.py": "from .m import f\n__all__ = ['f', 'pub']\n",
            f"{ENGINE}/m.py": "def f():\n    pass\ndef g():\n    pass\n",
            f"{ENGINE}/pub.py": "def h(x):\n    pass\n",
            f"{ENGINE}/own.py": "from .m import g\n",
            "operators/__init__.py": "",
            "operators/a.py": "from ..virtual_reflections import f, g\n"
            "from ..virtual_reflections.pub import h\nfrom ..virtual_reflections.own import x\n",
            "study/b.py": "import virtual_reflections.own\nfrom importlib import import_module\n"
            "m = import_module(name + '.virtual_reflections.m')\n"
            "p = import_module('virtual_reflections.pub')\n",
            "tests/t.py": "from virtual_reflections.own import g\n",
        },
    )
    assert outside_engine_imports(root) == [
        f"operators/a.py:1 {ENGINE}.g",
        f"operators/a.py:3 {ENGINE}.own",
        f"study/b.py:1 {ENGINE}.own",
        f"study/b.py:3 {ENGINE}.m",
    ]
    assert docstring_problems(engine_defs_used_outside(root)) == ["pub.h: no docstring"]


# --- rule 12: the rooms of operators/ import one way ------------------------------------------

# Each room of the Blender layer and its floor: a module imports only its own room and the
# rooms on lower floors ("operators" is the top of operators/: the pipeline and the features).
ROOMS = {
    "operators.scene": 0,
    "operators.node_trees": 1,
    "operators": 2,
    "operators.batch": 3,
    "operators.ops": 3,
}


def room_of(name: str) -> str | None:
    """The room of a module of operators/ (its longest prefix in ROOMS), None outside it."""
    parts = name.split(".")
    for i in range(len(parts), 0, -1):
        if ".".join(parts[:i]) in ROOMS:
            return ".".join(parts[:i])
    return None


def room_imports(root: Path) -> list[str]:
    """`file:line imports file` for each import between the rooms of operators/ that runs
    sideways or up (rule 12), and for each import by a room's __init__.py."""
    modules = discover(root)
    imports = all_imports(modules, root)
    problems = set()
    for name, found in imports.items():
        here = room_of(name)
        if here is None:
            continue
        for imp in found:
            target = known_module(imp.target, modules) if imp.internal else None
            there = room_of(target) if target is not None else None
            if there is None or target == name:
                continue
            if name in ROOMS and name != "operators.ops" and name != "operators":
                why = "a room's __init__.py imports nothing"
            elif there == here or ROOMS[there] < ROOMS[here]:
                continue
            else:
                why = "sideways or up between the rooms of operators/"
            where, shown = display(name, modules, root), display(target, modules, root)
            problems.add((where, imp.line, f"{where}:{imp.line} imports {shown} ({why})"))
    return [message for *_, message in sorted(problems)]


def test_the_rooms_of_operators_import_one_way():
    problems = room_imports(REPO)
    assert not problems, _report("imports against the rooms of operators/", problems)


def test_the_rule_12_sees_imports_up_and_sideways(tmp_path):
    root = _package(
        tmp_path,
        {
            "operators/__init__.py": "",
            "operators/scene/__init__.py": "from . import plate\n",
            "operators/scene/plate.py": "from ..node_trees import shading\n",
            "operators/node_trees/__init__.py": "",
            "operators/node_trees/shading.py": "from ..scene import plate\n"
            "def f():\n    from .. import generate\n",
            "operators/generate.py": "from .scene import plate\nfrom .node_trees import shading\n"
            "from .batch import shot\n",
            "operators/batch/__init__.py": "",
            "operators/batch/shot.py": "from .. import generate, ops\n",
            "operators/ops.py": "from . import generate\n",
        },
    )
    assert room_imports(root) == [
        "operators/batch/shot.py:1 imports operators/ops.py "
        "(sideways or up between the rooms of operators/)",
        "operators/generate.py:3 imports operators/batch/shot.py "
        "(sideways or up between the rooms of operators/)",
        "operators/node_trees/shading.py:3 imports operators/generate.py "
        "(sideways or up between the rooms of operators/)",
        "operators/scene/__init__.py:1 imports operators/scene/plate.py "
        "(a room's __init__.py imports nothing)",
        "operators/scene/plate.py:1 imports operators/node_trees/shading.py "
        "(sideways or up between the rooms of operators/)",
    ]


# --- rule 13: no function longer than a reader can follow ------------------------------------

MAX_FUNCTION_LINES = 80


def long_functions(root: Path) -> list[str]:
    """`file:line name (n lines)` of each function or method over MAX_FUNCTION_LINES in the
    repository's Python files, its tests aside (rule 13)."""
    found = []
    for path in python_files(root):
        rel = path.relative_to(root)
        if rel.parts[0] == "tests":
            continue
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                n = node.end_lineno - node.lineno + 1
                if n > MAX_FUNCTION_LINES:
                    found.append(f"{rel.as_posix()}:{node.lineno} {node.name} ({n} lines)")
    return sorted(found)


def test_no_function_is_longer_than_a_reader_can_follow():
    problems = long_functions(REPO)
    assert not problems, _report(f"functions over {MAX_FUNCTION_LINES} lines", problems)


def test_the_rule_13_sees_long_functions_and_methods_but_not_the_tests(tmp_path):
    body = "".join(f"    x{i} = {i}\n" for i in range(MAX_FUNCTION_LINES))  # def + 80 lines
    short = "".join(f"    x{i} = {i}\n" for i in range(MAX_FUNCTION_LINES - 1))
    root = _package(
        tmp_path,
        {
            "tool.py": f"def long():\n{body}def fine():\n{short}",
            "pkg/__init__.py": "",
            "pkg/mod.py": "class K:\n    def method(self):\n" + body.replace("    ", "        "),
            "tests/test_x.py": f"def test_long():\n{body}",
        },
    )
    assert long_functions(root) == [
        f"pkg/mod.py:2 method ({MAX_FUNCTION_LINES + 1} lines)",
        f"tool.py:1 long ({MAX_FUNCTION_LINES + 1} lines)",
    ]
