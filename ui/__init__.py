"""Panels and properties of the N-panel tab."""

from . import panel, presets, properties

_modules = (properties, presets, panel)


def register():
    for module in _modules:
        module.register()


def unregister():
    for module in reversed(_modules):
        module.unregister()
