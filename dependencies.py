"""What the extension needs besides Blender, checked before anything imports it.

Blender's own builds bundle NumPy and OpenImageIO; distributions' packages (Debian's, for
one) depend on neither. Without NumPy nothing of the extension can run: it still registers,
with a panel and operators that say in one sentence what to install (`register`). Without
OpenImageIO everything in Blender works (Blender's image API reads and writes the pixels)
except what only OpenImageIO can do: command lines that read plate files or write map files.

This module imports nothing of the extension and nothing that may be missing (no NumPy).
"""

import importlib
import os
import sys

import bpy

# module -> (the name people know it by, its pip package, its Debian package)
MODULES = {
    "numpy": ("NumPy", "numpy", "python3-numpy"),
    "OpenImageIO": ("OpenImageIO", "OpenImageIO", "python3-openimageio"),
}
_found = {}  # module -> bool, checked once per session


def available(module: str) -> bool:
    """Whether ``module`` imports in this Blender's Python (checked once)."""
    if module not in _found:
        try:
            importlib.import_module(module)
        except Exception:  # ImportError, or a broken installation raising anything
            _found[module] = False
        else:
            _found[module] = True
    return _found[module]


def install_command(module: str) -> str:
    """The command that installs ``module`` for the running Blender: the distribution's
    package when Blender runs on the system's Python (pip may not install there), else pip
    into Blender's own Python."""
    _, pip_name, deb_name = MODULES[module]
    python = sys.executable or "python3"
    system_python = python.startswith(("/usr/bin/", "/bin/"))
    if system_python and os.path.exists("/etc/debian_version"):
        return f"sudo apt install {deb_name}"
    if system_python:
        return f"{python} -m pip install --user {pip_name}"
    return f'"{python}" -m pip install {pip_name}'


def needs(module: str, what: str = "Virtual Reflections") -> str:
    """One sentence: what needs ``module`` and how to install it."""
    name = MODULES[module][0]
    return f"{what} needs {name}: install it into Blender's Python ({install_command(module)})"


def missing_required() -> str | None:
    """The sentence to show when the extension cannot run at all (no NumPy), else None."""
    return None if available("numpy") else needs("numpy")


# --- without NumPy: a panel and the main operators that say what to install -----------------


class VR_PT_missing(bpy.types.Panel):
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "Reflections"
    bl_label = "Virtual Reflections"
    bl_idname = "VR_PT_main"  # the same panel as when everything is there

    def draw(self, context):
        col = self.layout.column(align=True)
        col.alert = True
        sentence = missing_required() or ""
        head, _, command = sentence.partition(" (")
        col.label(text=head, icon="ERROR")
        if command:
            col.label(text=command.rstrip(")"))
        col.label(text="then restart Blender")


class _Missing:
    bl_options = {"REGISTER"}

    def execute(self, context):
        self.report({"ERROR"}, missing_required() or "")
        return {"CANCELLED"}


class VR_OT_generate(_Missing, bpy.types.Operator):
    """Build environment maps from the plate and make the selected objects reflect them"""

    bl_idname = "vr.generate"
    bl_label = "Generate Virtual Reflection"


class VR_OT_render_passes(_Missing, bpy.types.Operator):
    """Render the reflective objects reflecting each other (inter-reflections)"""

    bl_idname = "vr.render_passes"
    bl_label = "Render Inter-Reflections"


class VR_MT_object(bpy.types.Menu):
    bl_label = "Virtual Reflections"
    bl_idname = "VR_MT_object"  # the same menu as when everything is there (ui/menus.py)

    def draw(self, context):
        self.layout.operator(VR_OT_generate.bl_idname, icon="ERROR")
        self.layout.operator(VR_OT_render_passes.bl_idname, icon="ERROR")


def _draw_in_object_menu(self, context):
    self.layout.separator()
    self.layout.menu(VR_MT_object.bl_idname)


classes = (VR_PT_missing, VR_OT_generate, VR_OT_render_passes, VR_MT_object)
_register, _unregister = bpy.utils.register_classes_factory(classes)


def register():
    _register()
    bpy.types.VIEW3D_MT_object.append(_draw_in_object_menu)


def unregister():
    bpy.types.VIEW3D_MT_object.remove(_draw_in_object_menu)
    _unregister()
