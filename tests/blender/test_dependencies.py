"""What the extension says when a module is missing (dependencies.py): one sentence with the
command for the running Blender's Python. The real Blender without each module:
tests/e2e/test_missing_modules.py."""

import sys

from shots import addon_part


def test_the_sentence_names_the_module_and_the_command(addon_module, monkeypatch):
    deps = addon_part("dependencies")
    monkeypatch.setattr(sys, "executable", "/opt/blender/5.2/python/bin/python3.13")
    sentence = deps.needs("numpy")
    assert sentence == (
        "Virtual Reflections needs NumPy: install it into Blender's Python "
        '("/opt/blender/5.2/python/bin/python3.13" -m pip install numpy)'
    )
    assert "\n" not in sentence
    monkeypatch.setattr(sys, "executable", "/usr/bin/python3.14")
    monkeypatch.setattr(deps.os.path, "exists", lambda p: p == "/etc/debian_version")
    assert deps.install_command("OpenImageIO") == "sudo apt install python3-openimageio"


def test_with_numpy_nothing_is_missing(addon_module):
    deps = addon_part("dependencies")
    assert deps.available("numpy") and deps.missing_required() is None
