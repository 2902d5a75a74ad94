"""Everything that touches bpy data: bounds, images, node groups, renders."""

from . import generate, maps

_modules = (maps, generate)


def register():
    for module in _modules:
        module.register()


def unregister():
    for module in reversed(_modules):
        module.unregister()
