"""Virtual Reflections: a Blender extension that makes virtual objects reflect the plate
they are composited into (Ropinski, Wachenfeld & Hinrichs 2004).

Only wiring lives here: submodules register in order and unregister in reverse.
"""

from . import operators, preferences, render_shot, ui

# render_shot registers the command line `blender -c virtual_reflections ...`
_modules = (operators, ui, preferences, render_shot)


def register():
    for module in _modules:
        module.register()


def unregister():
    for module in reversed(_modules):
        module.unregister()
