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

Only modules with something to register are listed here, in that order.
"""

from . import live, maps, ops, previews, sequence, shading, undo_pixels

_modules = (undo_pixels, shading, maps, sequence, live, previews, ops)


def register():
    for module in _modules:
        module.register()


def unregister():
    for module in reversed(_modules):
        module.unregister()
