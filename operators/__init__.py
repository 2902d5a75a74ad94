"""Everything that touches bpy data: bounds, images, node groups, renders."""

_modules = ()


def register():
    for module in _modules:
        module.register()


def unregister():
    for module in reversed(_modules):
        module.unregister()
