"""Everything that touches bpy data: bounds, images, node groups, renders."""

from . import generate, interreflect, live, maps, previews, sequence

_modules = (maps, generate, interreflect, sequence, live, previews)


def register():
    for module in _modules:
        module.register()


def unregister():
    for module in reversed(_modules):
        module.unregister()
