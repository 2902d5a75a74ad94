"""The extension zip: built with the builder the bpy wheel ships (`blender --command extension
build` runs the same script) from a copy of this folder with stray build output left in it,
it holds the add-on and the engine and nothing of the study, the tests or old builds."""

import importlib.util
import pathlib
import shutil
import subprocess
import sys
import zipfile

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
NOT_COPIED = shutil.ignore_patterns(
    ".git", ".venv", ".venv313", "__pycache__", ".pytest_cache", ".ruff_cache", "*.exr"
)
# What a developer's folder may hold after building, rendering or packaging.
STRAYS = {
    "leftover.zip": b"PK\x05\x06" + bytes(18),
    "build/old/__init__.py": b"",
    "dist/virtual_reflections-0.0.1.zip": b"PK\x05\x06" + bytes(18),
    "out/spheres_with.png": b"",
    "operators/stale.zip": b"PK\x05\x06" + bytes(18),
}


def builder() -> pathlib.Path | None:
    """blender_ext.py of the installed bpy wheel (found, not imported), or None."""
    spec = importlib.util.find_spec("bpy")
    for location in (spec.submodule_search_locations or []) if spec else []:
        found = sorted(
            pathlib.Path(location).glob("*/scripts/addons_core/bl_pkg/cli/blender_ext.py")
        )
        if found:
            return found[-1]
    return None


@pytest.fixture(scope="module")
def names(tmp_path_factory):
    script = builder()
    if script is None:
        pytest.skip("the bpy wheel's extension builder (bl_pkg/cli/blender_ext.py) not found")
    source = tmp_path_factory.mktemp("source") / "virtual_reflections"
    shutil.copytree(ROOT, source, ignore=NOT_COPIED, symlinks=True)
    for name, data in STRAYS.items():
        (source / name).parent.mkdir(parents=True, exist_ok=True)
        (source / name).write_bytes(data)
    out = tmp_path_factory.mktemp("zip")
    r = subprocess.run(
        [
            sys.executable,
            str(script),
            "build",
            "--source-dir",
            str(source),
            "--output-dir",
            str(out),
        ],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert r.returncode == 0, r.stdout + r.stderr
    (package,) = out.glob("*.zip")
    with zipfile.ZipFile(package) as z:
        return z.namelist()


def test_the_zip_holds_the_extension_and_the_engine(names):
    for name in (
        "__init__.py",
        "blender_manifest.toml",
        "dependencies.py",
        "preferences.py",
        "render_shot.py",
        "operators/__init__.py",
        "operators/generate.py",
        "ui/__init__.py",
        "ui/panel.py",
        "virtual_reflections/__init__.py",
        "virtual_reflections/cli.py",
        "virtual_reflections/envmap.py",
        "virtual_reflections/params.py",
        "virtual_reflections/table.py",
    ):
        assert name in names, name


@pytest.mark.parametrize(
    "folder", ["study/", "tests/", "benchmarks/", "docs/", "tools/", "build/", "dist/", "out/"]
)
def test_the_zip_leaves_out_what_is_not_the_extension(names, folder):
    assert not [n for n in names if n.startswith(folder)], folder


def test_no_zip_inside_the_zip(names):
    assert not [n for n in names if n.lower().endswith(".zip")]


def test_build_extension_makes_the_zip_and_a_remote_repository(tmp_path):
    """`tools/build-extension --repo DIR` (the README's Install): the zip, and a folder a studio
    serves whose index.json (Blender's server-generate) lists the extension and its archive."""
    import json

    r = subprocess.run(
        [str(ROOT / "tools" / "build-extension"), "--repo", str(tmp_path / "repo")],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert r.returncode == 0, r.stdout + r.stderr
    index_path, zip_path = r.stdout.split()
    assert pathlib.Path(zip_path).is_file() and zipfile.is_zipfile(zip_path)
    index = json.loads(pathlib.Path(index_path).read_text())
    (entry,) = [e for e in index["data"] if e["id"] == "virtual_reflections"]
    assert (tmp_path / "repo" / entry["archive_url"].lstrip("./")).is_file()
    assert entry["archive_hash"].startswith("sha256:")
    bad = subprocess.run(
        [str(ROOT / "tools" / "build-extension"), "--nope"], capture_output=True, text=True
    )
    assert bad.returncode == 2 and bad.stderr.count("\n") == 1
