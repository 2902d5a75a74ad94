"""Fixtures for tests against the `bpy` module (PyPI wheel, Blender 4.5 or 5.x).

The extension is loaded the way Blender loads an extension: as a package whose
directory is the repository root, so its relative imports and `__package__` work.
"""

import pytest

bpy = pytest.importorskip("bpy", reason="the bpy module is not installed in this environment")

from shots import load_addon  # noqa: E402  (after the bpy check)


@pytest.fixture
def clean_file():
    """An empty factory-startup file (keeps extensions enabled, unlike read_factory_settings)."""
    bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True)
    yield bpy.context


@pytest.fixture
def addon(clean_file):
    """The extension registered on an empty file; unregistered afterwards."""
    module = load_addon()
    module.register()
    try:
        yield module
    finally:
        module.unregister()


@pytest.fixture
def addon_module(clean_file):
    """The extension package, imported but not registered."""
    return load_addon()
