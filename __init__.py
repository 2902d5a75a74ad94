"""Virtual Reflections: a Blender extension that makes virtual objects reflect the plate
they are composited into (Ropinski, Wachenfeld & Hinrichs 2004).

Only wiring lives here: submodules register in order and unregister in reverse.
"""

from . import operators, preferences, ui

_modules = (operators, ui, preferences)


def register():
    for module in _modules:
        module.register()


def unregister():
    for module in reversed(_modules):
        module.unregister()
