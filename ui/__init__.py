"""Panels and properties of the N-panel tab, and the Object menu's entry."""

from . import menus, panel, presets, properties

_modules = (properties, presets, panel, menus)


def register():
    for module in _modules:
        module.register()


def unregister():
    for module in reversed(_modules):
        module.unregister()
