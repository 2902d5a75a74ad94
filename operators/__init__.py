"""The Blender layer: everything that touches bpy data, in layers that import only downward
(docs/architecture.md):

    choices, images, bounds                  -- no other module of the add-on
    undo_pixels                              -- maps' pixels back after undo and redo
    plate, shading, maps, compositor         -- Blender data helpers
    pipeline                                 -- the one way a map is built
    generate, sequence, live, previews,      -- features
    interreflect
    batch                                    -- the headless entry (render_shot.py)
    ops                                      -- the operators

Only modules with something to register are listed here, in that order. They are imported
when the add-on registers, not with this package: render_shot.py reads the batch's options
(batch_options, no bpy) before Blender's modules are there.
"""

from importlib import import_module

_MODULES = ("undo_pixels", "shading", "maps", "sequence", "live", "previews", "ops")


def _modules():
    return [import_module(f"{__name__}.{name}") for name in _MODULES]


def register():
    for module in _modules():
        module.register()


def unregister():
    for module in reversed(_modules()):
        module.unregister()
