"""The research around the engine, not part of the extension: the accuracy study (`evaluate`),
the speed benchmark (`bench`), the named engine configurations they compare (`methods`) and
the panorama geometry that turns Blender's HDRIs into plates and ground truth (`panorama`).

It imports the engine (`virtual_reflections`) like any other user; the engine and the add-on
never import it. Command line: `python -m study evaluate|bench` (cli.py).
"""
