"""The extension registers `blender -c virtual_reflections` with Blender 4.2+ and removes it
again on unregister (the command itself runs in tests/e2e/test_cli_command.py)."""

import bpy
from shots import addon_part


def test_cli_command_registered_and_removed(addon_module):
    render_shot = addon_part("render_shot")
    assert hasattr(bpy.utils, "register_cli_command")  # both bpy 4.5 and 5.x have it
    addon_module.register()
    try:
        assert len(render_shot._cli) == 1
        render_shot.register()
        assert len(render_shot._cli) == 1
    finally:
        addon_module.unregister()
    assert render_shot._cli == []
    # Registered again after an unregister (disable, enable): no error from Blender.
    addon_module.register()
    addon_module.unregister()
