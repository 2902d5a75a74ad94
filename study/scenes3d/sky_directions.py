"""Per pixel, the world direction the mirror and the plate look along (issue 41: the unseen
sky retrieved from Blender's studio-light HDRIs, study/scenes3d/sky_retrieval.py).

For each scene of `heldout_sky.specs` four renders at the held-out study's size (256 px, 16
samples), the world replaced by one that shows each direction d as 0.5 + 0.5 d:

- ``dir mirror.exr``: the mirror (roughness 0) alone under it, ``white mirror.exr`` under a
  white world (the mirror's own colour k: d = 2 rgb / k - 1);
- ``dir plate.exr``: the camera's own rays (the subject, the ground and the neighbours hidden);
- ``alpha plate.exr``: the plate's geometry over a transparent film (alpha 0 where the plate
  shows the sky).

    python -m study.scenes3d.sky_directions OUT    # OUT/<scene>/*.exr; a scene done is skipped
"""

from __future__ import annotations

import pathlib
import sys
import time

import bpy

from . import build, heldout_sky, run

NAMES = ("dir mirror.exr", "white mirror.exr", "dir plate.exr", "alpha plate.exr")


def direction_world():
    """A world showing each view direction d (world frame) as 0.5 + 0.5 d."""
    world = bpy.data.worlds.new("Directions")
    world.use_nodes = True
    tree = world.node_tree
    tree.nodes.clear()
    background = tree.nodes.new("ShaderNodeBackground")
    output = tree.nodes.new("ShaderNodeOutputWorld")
    coords = tree.nodes.new("ShaderNodeTexCoord")
    code = tree.nodes.new("ShaderNodeVectorMath")
    code.operation = "MULTIPLY_ADD"
    code.inputs[1].default_value = (0.5, 0.5, 0.5)
    code.inputs[2].default_value = (0.5, 0.5, 0.5)
    tree.links.new(coords.outputs["Generated"], code.inputs[0])
    tree.links.new(code.outputs["Vector"], background.inputs["Color"])
    tree.links.new(background.outputs["Background"], output.inputs["Surface"])
    world.cycles.sampling_method = "NONE"
    return world


def render_scene(spec, out: pathlib.Path) -> None:
    folder = out / spec.name
    if all((folder / n).is_file() for n in NAMES):
        return
    folder.mkdir(parents=True, exist_ok=True)
    run.new_file()
    scene, camera, subject, others, _, material = build.build(
        spec, heldout_sky.WIDTH, heldout_sky.SAMPLES
    )
    border = run.subject_border(scene, camera, subject)
    coded, white = direction_world(), build.mean_world((1.0, 1.0, 1.0))
    for obj in others:
        obj.hide_render = True
    build.set_roughness(material, 0.0)
    scene.render.film_transparent = True
    scene.world = coded
    run.render(scene, folder / "dir mirror.exr", border)
    scene.world = white
    run.render(scene, folder / "white mirror.exr", border)
    subject.hide_render = True
    scene.render.film_transparent = False
    scene.world = coded
    run.render(scene, folder / "dir plate.exr")
    for obj in others:
        obj.hide_render = False
    scene.render.film_transparent = True
    run.render(scene, folder / "alpha plate.exr")


def main(argv=None) -> int:
    args = list(sys.argv[1:] if argv is None else argv)
    if len(args) != 1:
        print("usage: python -m study.scenes3d.sky_directions OUT", file=sys.stderr)
        return 2
    out = pathlib.Path(args[0])
    for spec in heldout_sky.specs():
        t0 = time.perf_counter()
        render_scene(spec, out)
        print(f"{spec.name}: {time.perf_counter() - t0:.1f} s", flush=True)
    run.new_file()
    return 0


if __name__ == "__main__":
    sys.exit(main())
