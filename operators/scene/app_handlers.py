"""Blender's application handlers (``bpy.app.handlers``) added once and removed whole: the
modules that watch file saves and loads list theirs as (handler list name, function) pairs."""

import bpy


def add(pairs) -> None:
    """Append each function to its handler list unless it is there already."""
    for name, function in pairs:
        handlers = getattr(bpy.app.handlers, name)
        if function not in handlers:
            handlers.append(function)


def remove(pairs) -> None:
    """Remove every copy of each function from its handler list."""
    for name, function in pairs:
        handlers = getattr(bpy.app.handlers, name)
        while function in handlers:
            handlers.remove(function)
