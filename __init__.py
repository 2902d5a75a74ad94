"""Virtual Reflections: a Blender extension that makes virtual objects reflect the plate
they are composited into (Ropinski, Wachenfeld & Hinrichs 2004).

Only wiring lives here: submodules register in order and unregister in reverse. Without
NumPy (distributions' Blender packages do not depend on it) only `dependencies` registers:
a panel and operators that say what to install, instead of a traceback.
"""

from . import dependencies

if dependencies.missing_required() is None:
    from . import operators, preferences, render_shot, ui

    # render_shot registers the command line `blender -c virtual_reflections ...`
    _modules = (operators, ui, preferences, render_shot)
else:
    _modules = (dependencies,)


def register():
    for module in _modules:
        module.register()


def unregister():
    for module in reversed(_modules):
        module.unregister()
