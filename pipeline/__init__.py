"""Pipeline tools around the batch entry (render_shot.py) that run outside Blender: no bpy here.

farm: fan a shot's frames out in chunks on a Dask distributed cluster.
"""
