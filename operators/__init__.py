"""The Blender layer: everything that touches bpy data, in rooms that import only downward
(docs/architecture.md):

    scene/                                   -- the scene's data: plate, images, bounds, floor,
                                                maps, colour, choices, the file's handlers
    node_trees/                              -- the node groups, materials and world
    pipeline                                 -- the one way a map is built
    generate, sequence, live, previews,      -- features
    interreflect, traced_pass, reflection_snapshot, compositor
    batch/                                   -- the headless entry (render_shot.py)
    ops                                      -- the operators

Only modules with something to register are listed here, in that order. They are imported
when the add-on registers, not with this package: render_shot.py reads the batch's options
(batch/options.py, no bpy) before Blender's modules are there.
"""

from importlib import import_module

_MODULES = (
    "scene.undo_pixels",
    "node_trees.shading",
    "scene.maps",
    "sequence",
    "live",
    "previews",
    "ops",
)


def _modules():
    return [import_module(f"{__name__}.{name}") for name in _MODULES]


def register():
    for module in _modules():
        module.register()


def unregister():
    for module in reversed(_modules()):
        module.unregister()
