"""Ray-traced inter-reflections, a prototype in the study (issue 11, item 4).

The default's passes (inter.py) rebuild each mirror's map from the previous composite; against
the 3D truth they bring nothing. Here the same cases are rendered with the default look ray
traced instead: every mirror a real Cycles mirror, and whatever a mirror's ray meets that is not
another mirror is read by the default's own lookup (Camera View + Ground, Replace look: the map
along the ray, the ground where the ray meets it looked up on the plate, darkened by every
mirror's contact shadow). That lookup needs the ray's origin, which a world shader does not
have; so it sits on a dome (a sphere far around the scene, seen by glossy rays only) whose
shader recovers the origin from the hit point and the ray's length:

    origin = Position + Incoming * Ray Length,   direction = -Incoming

Per case: the product's one pass (Generate, Replace look, one render), the prototype with the
mirrors seeing each other, and the prototype with the mirrors blind to each other (each sees
only the dome: the prototype's own one pass). Scores as inter.py: all the mirrors' pixels and
the inter pixels (where the truth differs from the truth with the mirrors blind to each other).
Not the product: nothing here is in the add-on (docs/scenes3d.md, "Ray-traced
inter-reflections").

    python -m study traced [--quick] [--out DIR]
"""

from __future__ import annotations

import importlib
import json
import pathlib
import shutil
import sys
import tempfile
import time

import bpy
import numpy as np
from mathutils import Vector

from ..evaluate.metrics import to_display
from . import build, inter, scenes
from .run import border_pixels, new_file, render, score, write_png

DOME_RADIUS = 5000.0  # m, around the world origin: far beyond every scene of the study
ONE, SEEING, BLIND = "one pass (product)", "ray traced", "ray traced, mirrors blind"
RUNS = (ONE, SEEING, BLIND)


def _ground_of(group, ground_nodes, created):
    """The GroundLookup the default's reflection group was built with (read off its nodes)."""
    lookup = next(
        n
        for n in group.nodes
        if n.bl_idname == "ShaderNodeGroup" and n.node_tree.get(created) == "ground"
    )
    plate = next(n for n in group.nodes if n.bl_idname == "ShaderNodeTexImage").image
    value = lookup.inputs
    return ground_nodes.GroundLookup(
        plate=plate,
        height=value["Height"].default_value,
        focal=tuple(value["Focal"].default_value)[:2],
        centre=tuple(value["Centre"].default_value)[:2],
        aspect=value["Aspect"].default_value,
        frames=None,
    )


def _world_box(obj):
    """(centre, half size) of ``obj``'s bounding box in world space (axis-aligned)."""
    corners = [obj.matrix_world @ Vector(c) for c in obj.bound_box]
    low = [min(c[i] for c in corners) for i in range(3)]
    high = [max(c[i] for c in corners) for i in range(3)]
    return (
        tuple((a + b) / 2 for a, b in zip(low, high)),
        tuple((b - a) / 2 for a, b in zip(low, high)),
    )


def _group_node(nodes, tree, location):
    node = nodes.new("ShaderNodeGroup")
    node.node_tree, node.location = tree, location
    return node


def _vector(nodes, links, operation, a, b=None, scale=None):
    node = nodes.new("ShaderNodeVectorMath")
    node.operation = operation
    links.new(a, node.inputs[0])
    if b is not None:
        links.new(b, node.inputs[1])
    if scale is not None:
        node.inputs["Scale"].default_value = scale
    return node


def dome(addon, group, mirrors):
    """The dome object: the default's lookup for whatever a ray meets there, from its origin.
    ``group``: the default's reflection group (Replace) made by Generate for one mirror; its
    map and ground serve every ray. Seen by glossy rays only."""
    module = addon.module.__name__
    rn = importlib.import_module(f"{module}.operators.reflection_nodes")
    gn = importlib.import_module(f"{module}.operators.ground_nodes")
    created = importlib.import_module(f"{module}.operators.nodes").CREATED
    ground = _ground_of(group, gn, created)
    image = next(n for n in group.nodes if n.bl_idname == "ShaderNodeTexEnvironment").image

    material = bpy.data.materials.new("VR study dome")
    if bpy.app.version < (5, 0):  # 5.x materials always have their node tree
        material.use_nodes = True
    nodes, links = material.node_tree.nodes, material.node_tree.links
    nodes.clear()
    geometry = nodes.new("ShaderNodeNewGeometry")
    path = nodes.new("ShaderNodeLightPath")
    back = _vector(nodes, links, "SCALE", geometry.outputs["Incoming"])
    links.new(path.outputs["Ray Length"], back.inputs["Scale"])
    origin = _vector(nodes, links, "ADD", geometry.outputs["Position"], back.outputs[0])
    direction = _vector(nodes, links, "SCALE", geometry.outputs["Incoming"], scale=-1.0)
    ray = (origin.outputs[0], direction.outputs[0])

    colour = rn._env_lookup(nodes, links, ray[1], image, (0, 0))
    lookup = _group_node(nodes, gn.ensure_ground_group(), (200, -300))
    for name in ("Position", "Direction"):
        links.new(ray[name == "Direction"], lookup.inputs[name])
    lookup.inputs["Height"].default_value = ground.height
    lookup.inputs["Focal"].default_value = (*ground.focal, 0.0)
    lookup.inputs["Centre"].default_value = (*ground.centre, 0.0)
    lookup.inputs["Aspect"].default_value = ground.aspect
    plate = nodes.new("ShaderNodeTexImage")
    plate.image, plate.interpolation, plate.extension = ground.plate, "Linear", "EXTEND"
    links.new(lookup.outputs["UV"], plate.inputs["Vector"])
    seen = plate.outputs["Color"]
    for obj in mirrors:  # every mirror's contact shadow (the dome's space is the world's)
        centre, half = _world_box(obj)
        shade = _group_node(nodes, gn.ensure_occlusion_group(), (400, -600))
        for name in ("Position", "Direction"):
            links.new(ray[name == "Direction"], shade.inputs[name])
        shade.inputs["Height"].default_value = ground.height
        shade.inputs["Box Centre"].default_value = centre
        shade.inputs["Box Half Size"].default_value = half
        scaled = _vector(nodes, links, "SCALE", seen)
        links.new(shade.outputs["Sky"], scaled.inputs["Scale"])
        seen = scaled.outputs[0]
    # colour + weight (ground - colour), as the material's own mix
    step = _vector(nodes, links, "SUBTRACT", seen, colour)
    step = _vector(nodes, links, "SCALE", step.outputs[0])
    links.new(lookup.outputs["Weight"], step.inputs["Scale"])
    total = _vector(nodes, links, "ADD", colour, step.outputs[0])
    emission = nodes.new("ShaderNodeEmission")
    links.new(total.outputs[0], emission.inputs["Color"])
    output = nodes.new("ShaderNodeOutputMaterial")
    links.new(emission.outputs[0], output.inputs["Surface"])

    import bmesh  # Blender's, importable once bpy is

    mesh = bpy.data.meshes.new("VR study dome")
    bm = bmesh.new()
    bmesh.ops.create_uvsphere(bm, u_segments=64, v_segments=32, radius=DOME_RADIUS)
    bm.to_mesh(mesh)
    bm.free()
    mesh.materials.append(material)
    obj = bpy.data.objects.new("VR study dome", mesh)
    bpy.context.scene.collection.objects.link(obj)
    obj.visible_camera = obj.visible_shadow = obj.visible_diffuse = False
    obj.visible_transmission = obj.visible_volume_scatter = False
    return obj


def _reflection_group(obj):
    for slot in obj.material_slots:
        for node in slot.material.node_tree.nodes:
            tree = getattr(node, "node_tree", None)
            if tree is not None and tree.get("vr_mode") == "REPLACE":
                return tree
    raise RuntimeError(f"{obj.name}: no Replace reflection group after Generate")


def run_scene(spec, addon, work: pathlib.Path, width, samples, log):
    """One case: plate, truth, blind truth, the product's one pass, the prototype seeing and
    blind. Returns the record."""
    started = time.perf_counter()
    new_file()
    scene, camera, subject, others, _, material = build.build(spec, width, samples)
    mirrors = [subject, *build.add_companions(scene, spec, material)]
    scene.cycles.glossy_bounces = inter.GLOSSY_BOUNCES
    scene.cycles.max_bounces = inter.GLOSSY_BOUNCES + 2
    work.mkdir(parents=True, exist_ok=True)
    for obj in mirrors:
        obj.hide_render = True
    scene.render.film_transparent = False
    plate = render(scene, work / "plate.exr")[..., :3]
    write_png(work / "plate.png", plate)
    for obj in mirrors:
        obj.hide_render = False
    border = inter.union_border(scene, camera, mirrors)
    crop = border_pixels(border, width, scene.render.resolution_y)
    truth = render(scene, work / "truth.exr", border)[..., :3]
    for obj in mirrors:
        obj.visible_glossy = False
    blind = render(scene, work / "blind.exr", border)[..., :3]
    for obj in mirrors:
        obj.visible_glossy = True

    for obj in others:
        obj.hide_render = True
    scene.render.film_transparent = True
    settings = scene.virtual_reflections
    settings.plate_image = bpy.data.images.load(str(work / "plate.png"))
    settings.resolution = "AUTO"
    settings.method = settings.bl_rna.properties["method"].default
    settings.combine = "REPLACE"
    for obj in mirrors:
        obj.virtual_reflections.enabled = True
    report = addon.generate.generate(scene, bpy.context.evaluated_depsgraph_get(), mirrors)
    if not report.done:
        raise RuntimeError(f"{spec.name}: Generate made nothing: {report.warnings}")
    rgba = {ONE: render(scene, work / "one.exr", border)}
    shell = dome(addon, _reflection_group(mirrors[0]), mirrors)
    made = [list(obj.data.materials) for obj in mirrors]
    scene.world = bpy.data.worlds.new("VR study black")  # the dome is everything they see
    for obj in mirrors:  # the white mirror of the truth, meeting the dome and each other
        obj.data.materials.clear()
        obj.data.materials.append(material)
    build.set_roughness(material, 0.0)
    rgba[SEEING] = render(scene, work / "seeing.exr", border)
    for obj in mirrors:
        obj.visible_glossy = False
    rgba[BLIND] = render(scene, work / "blind prototype.exr", border)
    for obj, materials in zip(mirrors, made):
        obj.visible_glossy = True
        obj.data.materials.clear()
        for m in materials:
            obj.data.materials.append(m)
    bpy.data.objects.remove(shell)
    addon.generate.remove_all()

    mask = rgba[ONE][..., 3] > 0.5
    region = mask & (np.abs(to_display(truth) - to_display(blind)).max(-1) > inter.INTER_THRESHOLD)
    results = {}
    for run, image in rgba.items():
        composite = image[..., :3] + (1.0 - image[..., 3:4]) * plate
        results[run] = score(composite, truth, mask, crop)
        results[run]["inter psnr"] = score(composite, truth, region, crop)["psnr"]
    record = {
        "scene": spec.to_json(),
        "mirrors": len(mirrors),
        "subject_pixels": int(mask.sum()),
        "inter_pixels": int(region.sum()),
        "results": results,
        "seconds": time.perf_counter() - started,
    }
    log(
        f"{spec.name}: "
        + ", ".join(
            f"{run} {r['psnr']:.2f} dB (inter {r['inter psnr']:.2f})" for run, r in results.items()
        )
    )
    return record


def table(data) -> str:
    """Per case and on average: PSNR / SSIM on all the mirrors' pixels, PSNR on the inter px."""
    head = " | ".join(RUNS)
    lines = [
        f"| case | mirrors: px (inter px) | {head} | ray traced − one pass |",
        "|---|---|" + "---|" * (len(RUNS) + 1),
    ]

    def cell(r):
        return f"{r['psnr']:.2f} / {r['ssim']:.3f} ({r['inter psnr']:.2f})"

    for rec in data["scenes"]:
        res = rec["results"]
        gain = res[SEEING]["psnr"] - res[ONE]["psnr"]
        lines.append(
            f"| {rec['scene']['name']} | {rec['mirrors']}: {rec['subject_pixels']} "
            f"({rec['inter_pixels']}) | "
            + " | ".join(cell(res[r]) for r in RUNS)
            + f" | {gain:+.2f} dB |"
        )
    mean = {
        r: {
            k: float(np.mean([rec["results"][r][k] for rec in data["scenes"]]))
            for k in ("psnr", "ssim", "inter psnr")
        }
        for r in RUNS
    }
    ahead = sum(
        rec["results"][SEEING]["psnr"] > rec["results"][ONE]["psnr"] for rec in data["scenes"]
    )
    lines.append(
        "| mean | | "
        + " | ".join(cell(mean[r]) for r in RUNS)
        + f" | {mean[SEEING]['psnr'] - mean[ONE]['psnr']:+.2f} dB, ahead in {ahead}/"
        f"{len(data['scenes'])} |"
    )
    return "\n".join(lines)


def run_command(quick=False, out=None, log=None, width=320, samples=32):
    """Run the cases (quick: the two spheres), print the table; with ``out`` write
    OUT/scenes3d_traced.json and the table into OUT/scenes3d.md."""
    from . import report

    say = log or (lambda line: print(line, file=sys.stderr, flush=True))
    addon = inter.InterAddon()
    work = pathlib.Path(tempfile.mkdtemp(prefix="vr_traced_"))
    started = time.perf_counter()
    try:
        records = [
            run_scene(spec, addon, work / spec.name, width, samples, say)
            for spec in scenes.inter_set(quick)
        ]
    finally:
        new_file()
        addon.close()
        shutil.rmtree(work, ignore_errors=True)
    data = {
        "command": "python -m study traced" + (" --quick" if quick else ""),
        "resolution": [width, round(width / scenes.ASPECT)],
        "samples": samples,
        "glossy_bounces": inter.GLOSSY_BOUNCES,
        "scenes": records,
        "bpy": bpy.app.version_string,
        "seconds": time.perf_counter() - started,
    }
    text = table(data)
    print(text)
    if out is not None:
        out = pathlib.Path(out)
        out.mkdir(parents=True, exist_ok=True)
        (out / f"scenes3d_traced{'_quick' if quick else ''}.json").write_text(
            json.dumps(data, indent=1) + "\n"
        )
        report.add_block(
            out / "scenes3d.md", "traced", "Ray-traced inter-reflections", text, data["command"]
        )
    return data
