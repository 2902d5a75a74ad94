"""The headless batch behind render_shot.py (and `blender -c virtual_reflections`):

    options, signals, lock, record, report   -- typed options, Ctrl-C and SIGTERM, the output
                                                lock, each frame's record, the JSON report
    render                                   -- the steps on the scene both entries share
    ranges                                   -- frame ranges and their jobs
    shot                                     -- one frame; a range goes to ranges

Nothing is imported here: render_shot.py reads `options` (no bpy) before Blender's modules are
there.
"""
