"""Benchmark: the paper's Table 2 -- a chrome sphere and a chrome torus reflecting each other.

    .venv/bin/python benchmarks/table2.py [--scale 50] [--samples 16] [--repeat 3]
        [--out docs/images] [--no-charts]

The scene (§3.3, Fig. 6): the courtyard plate (sample_scenes/plates/courtyard.jpg, 1280 x 720,
its camera from courtyard.json), a chrome sphere and a chrome torus standing close together on
its ground with a shadow catcher under them, combine Replace, Cycles on the CPU at ``--scale``
percent with ``--samples`` samples and denoising (build_scenes' quick settings). Measured with
`operators.interreflect.render_passes`: r = 2 and r = 6 passes with the front face cut into
n = 32 and n = 128 triangles, and r chosen automatically (until a pass changes the objects'
pixels by less than 1/255). Every frame starts with an empty table cache, as a new pose does,
so pass 1 includes building the objects' lookup tables; one untimed render first takes the
process's start-up (kernels, denoiser) out of the figures. Runs are interleaved over
``--repeat`` rounds; figures are medians.

Prints the table (time per frame -- all passes -- and per pass, first and later), the targets
(a later pass <= 40 % of the first; auto-r within 3 passes), and writes into ``--out``:
``interreflection_time.png`` (time per pass, r = 6), ``interreflection_convergence.png``
(change per pass, log scale) and ``interreflection_passes.png`` (pass 1 / pass 2 / their
difference, cropped to the objects).
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import math
import os
import pathlib
import platform
import statistics
import sys
import time

import bpy
import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
PLATE = ROOT / "sample_scenes" / "plates" / "courtyard.jpg"
TRIANGLES = (32, 128)
PASSES = (2, 6, "auto")
# Where the objects stand: plate position of the ground contact (fractions, y down); the
# torus stands on its rim, turned 45 degrees from facing the camera's heading.
SPHERE_AT, SPHERE_RADIUS = (0.42, 0.8), 0.36
TORUS_AT, TORUS_RADII, TORUS_YAW = (0.58, 0.8), (0.40, 0.13), 45.0


def _load(name, path, package=False):
    """Import a file under ``name`` (the add-on as a package, so its relative imports work)."""
    if name not in sys.modules:
        where = [str(path.parent)] if package else None
        spec = importlib.util.spec_from_file_location(name, path, submodule_search_locations=where)
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        spec.loader.exec_module(module)
    return sys.modules[name]


def make_torus(scene, name, major, minor, segments=96, sides=32):
    """A smooth torus standing on its rim on z = 0: the ring in the XZ plane, axis along Y."""
    u = np.linspace(0, 2 * math.pi, segments, endpoint=False)[:, None]  # around the ring
    v = np.linspace(0, 2 * math.pi, sides, endpoint=False)[None, :]  # around the tube
    radius = major + minor * np.cos(v)
    x = radius * np.cos(u)
    y = np.broadcast_to(minor * np.sin(v), x.shape)
    z = radius * np.sin(u) + major + minor
    vertices = np.stack([x, y, z], -1).reshape(-1, 3)
    i, j = np.meshgrid(np.arange(segments), np.arange(sides), indexing="ij")
    i1, j1 = (i + 1) % segments, (j + 1) % sides
    faces = np.stack([i * sides + j, i1 * sides + j, i1 * sides + j1, i * sides + j1], -1)
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(vertices.tolist(), [], faces.reshape(-1, 4).tolist())
    mesh.shade_smooth()
    obj = bpy.data.objects.new(name, mesh)
    scene.collection.objects.link(obj)
    return obj


def build_scene(build_scenes, scale, samples):
    """The sphere and the torus on the courtyard plate, in the current (empty) file; returns
    (scene, [sphere, torus])."""
    scene = bpy.context.scene
    camera_json = json.loads(PLATE.with_suffix(".json").read_text())
    build_scenes.add_plate_camera(scene, camera_json)
    height = build_scenes.plate_height(PLATE)
    chrome = build_scenes.principled("Chrome", (0.8, 0.8, 0.8), metallic=1.0, roughness=0.05)
    sphere = build_scenes.make_sphere(scene, "Chrome Sphere", SPHERE_RADIUS)
    sphere.location = build_scenes.ground_point(camera_json, *SPHERE_AT, height)
    torus = make_torus(scene, "Chrome Torus", *TORUS_RADII)
    torus.location = build_scenes.ground_point(camera_json, *TORUS_AT, height)
    heading = build_scenes.camera_heading(camera_json)
    torus.rotation_euler = (0.0, 0.0, heading + math.radians(TORUS_YAW - 90.0))
    for obj in (sphere, torus):
        obj.data.materials.append(chrome)
        obj.virtual_reflections.enabled = True
    image = build_scenes.load_plate_image(PLATE)
    centre = (sphere.location + torus.location) / 2
    build_scenes.add_ground(scene, (centre.x, centre.y, centre.z))
    sky, ground = build_scenes.mean_colours(image, build_scenes.horizon_row(camera_json))
    build_scenes.gradient_world(scene, sky, ground)
    w, h = camera_json["width"], camera_json["height"]
    build_scenes.quick_render_settings(scene, w, h, scale=scale, samples=samples)
    settings = scene.virtual_reflections
    settings.plate_image = image
    settings.combine = "REPLACE"
    settings.method = "PAPER"  # the paper's Table 2, and neighbours on the facing sides
    settings.front = "TRIANGLES"
    return scene, [sphere, torus]


def machine():
    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo") as f:
            cpu = next(line.split(":", 1)[1].strip() for line in f if "model name" in line)
    except (OSError, StopIteration):
        pass
    return (
        f"{cpu}, {os.cpu_count()} cores; {platform.system()}; Python {platform.python_version()}, "
        f"NumPy {np.__version__}, Blender {bpy.app.version_string} (bpy module), Cycles CPU"
    )


def median_reports(runs):
    """[[PassReport]] (one list per repeat) -> per pass index: dict of median figures."""
    count = min(len(r) for r in runs) if runs else 0
    out = []
    for i in range(count):
        rows = [r[i] for r in runs]
        out.append(
            {
                key: statistics.median(getattr(row, key) for row in rows)
                for key in ("seconds", "change", "maps_seconds", "render_seconds")
            }
        )
    return out


def run(interreflect, scene, objects, plate, passes, clear_tables):
    clear_tables()
    started = time.perf_counter()
    composite, _, reports = interreflect.render_passes(
        scene, bpy.context.evaluated_depsgraph_get(), objects, plate, passes
    )
    return time.perf_counter() - started, composite, reports


def fmt_s(seconds):
    return f"{seconds:.2f} s ({1 / seconds:.2f} fps)"


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0], allow_abbrev=False)
    p.add_argument("--scale", type=int, default=50, help="resolution percentage of 1280 x 720")
    p.add_argument("--samples", type=int, default=16)
    p.add_argument("--repeat", type=int, default=3)
    p.add_argument("--out", default=str(ROOT / "docs" / "images"))
    p.add_argument("--no-charts", action="store_true")
    args = p.parse_args(argv)

    addon = _load("vr_table2_addon", ROOT / "__init__.py", package=True)
    build_scenes = _load("vr_table2_build_scenes", ROOT / "sample_scenes" / "build_scenes.py")
    render_sample = _load("vr_table2_render_sample", ROOT / "sample_scenes" / "render_sample.py")
    # A new empty file before registering: loading a file with the add-on registered makes the
    # bpy 4.5 module hang at exit (seen with the extension's preferences class).
    build_scenes.new_file()
    addon.register()
    try:
        return measure(addon, build_scenes, render_sample, args)
    finally:
        addon.unregister()  # the bpy 4.5 module hangs at exit while classes stay registered


def measure(addon, build_scenes, render_sample, args):
    from importlib import import_module

    interreflect = import_module(addon.__name__ + ".operators.interreflect")
    plates = import_module(addon.__name__ + ".operators.scene.plate")
    engine = import_module(addon.__name__ + ".virtual_reflections")
    quiet = render_sample.renderer_quiet

    with quiet():
        scene, objects = build_scene(build_scenes, args.scale, args.samples)
    settings = scene.virtual_reflections
    plate, _ = plates.pixels(scene)
    w = scene.render.resolution_x * scene.render.resolution_percentage // 100
    h = scene.render.resolution_y * scene.render.resolution_percentage // 100
    print(f"Machine: {machine()}; load average {os.getloadavg()[0]:.1f}")
    print(
        f"Scene: chrome sphere + chrome torus on {PLATE.name} ({plate.shape[1]}x{plate.shape[0]}),"
        f" render {w}x{h}, {args.samples} samples, denoised; map {settings.resolution} wide; "
        f"medians of {args.repeat}"
    )
    with quiet():  # process start-up (kernels, denoiser) out of the figures
        interreflect.render_passes(scene, bpy.context.evaluated_depsgraph_get(), objects, plate, 1)

    runs, totals, composites = _rounds(
        args.repeat, settings, interreflect, scene, objects, plate, engine, quiet
    )
    table = {key: median_reports(value) for key, value in runs.items()}
    print(
        f"Load average at the end (1, 5, 15 min): {', '.join(f'{x:.1f}' for x in os.getloadavg())}"
    )
    _print_table(table, runs, totals)
    if not args.no_charts:
        os.makedirs(args.out, exist_ok=True)
        charts(args.out, table, runs)
        with quiet():
            settings.triangles = TRIANGLES[0]
            first, _, _ = interreflect.render_passes(
                scene, bpy.context.evaluated_depsgraph_get(), objects, plate, 1
            )
        second, reports = composites[(TRIANGLES[0], 2)]
        encode = import_module(addon.__name__ + ".virtual_reflections.colour").linear_to_srgb
        path = os.path.join(args.out, "interreflection_passes.png")
        picture(path, first, second, reports[1].border, encode)
        print(f"wrote charts and picture into {args.out}")
    return 0


def _rounds(repeat, settings, interreflect, scene, objects, plate, engine, quiet):
    """``repeat`` rounds of every triangle count and pass count, each from a cold lookup cache:
    (each key's pass reports per round, its times per frame, its last composite and reports)."""
    runs = {(n, r): [] for n in TRIANGLES for r in PASSES}
    totals = {key: [] for key in runs}
    composites = {}
    for rep in range(repeat):
        for n in TRIANGLES:
            settings.triangles = n
            for r in PASSES:
                with quiet():
                    total, composite, reports = run(
                        interreflect, scene, objects, plate, r, engine.lookup_table.cache_clear
                    )
                runs[(n, r)].append(reports)
                totals[(n, r)].append(total)
                composites[(n, r)] = (composite, reports)
                print(
                    f"  round {rep + 1}, n = {n:3d}, r = {r}: {total:.2f} s, "
                    f"{len(reports)} passes, changes "
                    + " ".join(f"{x.change:.5f}" for x in reports)
                )
    return runs, totals, composites


def _print_table(table, runs, totals) -> None:
    """Print the Table 2 rows (time per frame, per pass first / later, of which render) per pass
    count and triangle count, and whether the two targets are met."""
    print()
    print("| sphere and torus | n = 32 | n = 128 |")
    print("|---|---|---|")
    ratios = []
    for r in PASSES:
        cells, passes_cells, first_cells = [], [], []
        for n in TRIANGLES:
            per = table[(n, r)]
            total = statistics.median(totals[(n, r)])
            first, later = per[0]["seconds"], [x["seconds"] for x in per[1:]]
            ratio = statistics.mean(later) / first
            ratios.append(ratio)
            count = statistics.median(len(x) for x in runs[(n, r)])
            cells.append(fmt_s(total) + ("" if r != "auto" else f", r = {count:g}"))
            first_cells.append(f"{first:.2f} s / {statistics.mean(later):.2f} s ({ratio:.0%})")
            passes_cells.append(
                "render {:.2f} s / {:.2f} s".format(
                    per[0]["render_seconds"],
                    statistics.mean(x["render_seconds"] for x in per[1:]),
                )
            )
        label = f"r = {r}" if r != "auto" else "r = auto (change < 1/255)"
        print(f"| {label}: time per frame | {cells[0]} | {cells[1]} |")
        print(
            f"| {label}: per pass, first / later (later/first) | " + " | ".join(first_cells) + " |"
        )
        print(f"| {label}: of which render, first / later | " + " | ".join(passes_cells) + " |")
    autos = [len(reports) for n in TRIANGLES for reports in runs[(n, "auto")]]
    print()
    print(
        f"Target: a later pass <= 40 % of the first: worst {max(ratios):.0%} -> "
        + ("met" if max(ratios) <= 0.40 else "NOT met")
    )
    print(
        f"Target: auto-r stops within 3 passes: r = {sorted(set(autos))} -> "
        + ("met" if max(autos) <= 3 else "NOT met")
    )


def charts(out, table, runs):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 3.6), dpi=110)
    width = 0.38
    for k, (n, colour) in enumerate(zip(TRIANGLES, ("tab:blue", "tab:orange"))):
        per = table[(n, 6)]
        x = np.arange(1, len(per) + 1) + (k - 0.5) * width
        render = [p["render_seconds"] for p in per]
        maps = [p["maps_seconds"] for p in per]
        other = [p["seconds"] - p["render_seconds"] - p["maps_seconds"] for p in per]
        ax.bar(x, render, width, color=colour, label=f"n = {n}: render")
        ax.bar(x, maps, width, bottom=render, color=colour, alpha=0.45, label=f"n = {n}: maps")
        ax.bar(
            x,
            other,
            width,
            bottom=np.add(render, maps),
            color="grey",
            alpha=0.5,
            label="read, composite" if k == 0 else None,
        )
    ax.set_xlabel("pass (r = 6)")
    ax.set_ylabel("seconds")
    ax.set_title("Time per pass: pass 1 renders the frame, later passes the objects' region")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(os.path.join(out, "interreflection_time.png"))
    plt.close(fig)

    floor = 1e-6  # a pass that changes nothing is drawn on the floor
    fig, ax = plt.subplots(figsize=(6.4, 3.6), dpi=110)
    for n, colour in zip(TRIANGLES, ("tab:blue", "tab:orange")):
        changes = [max(p["change"], floor) for p in table[(n, 6)]]
        ax.plot(range(1, len(changes) + 1), changes, "o-", color=colour, label=f"r = 6, n = {n}")
        autos = [max(p["change"], floor) for p in table[(n, "auto")]]
        ax.plot(
            range(1, len(autos) + 1),
            autos,
            "s",
            mfc="none",
            ms=11,
            color=colour,
            label=f"auto, n = {n} (r = {len(autos)})",
        )
    ax.axhline(1 / 255, color="grey", ls="--", lw=1, label="tolerance 1/255")
    ax.set_yscale("log")
    ax.set_ylim(floor / 2, 1)
    ax.set_xlabel("pass")
    ax.set_ylabel("mean |change| of the objects' pixels")
    ax.set_title("Convergence (pass 1: against the bare plate; 1e-6: no change)")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(os.path.join(out, "interreflection_convergence.png"))
    plt.close(fig)


def picture(path, first, second, border, encode, margin=16, gain=8.0):
    """Pass 1, pass 2 and 8 x their difference, cropped to the objects, side by side."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    h, w = first.shape[:2]
    x0, y0, x1, y1 = border
    x0, y0, x1, y1 = (
        max(x0 - margin, 0),
        max(y0 - margin, 0),
        min(x1 + margin, w),
        min(y1 + margin, h),
    )
    panels = (
        ("pass 1: each object reflects the plate", encode(first[y0:y1, x0:x1])),
        ("pass 2: ... and the other object", encode(second[y0:y1, x0:x1])),
        (f"|pass 2 - pass 1| x {gain:g}", np.abs(second - first)[y0:y1, x0:x1] * gain),
    )
    fig, axes = plt.subplots(1, 3, figsize=(12, 12 * (y1 - y0) / (3 * (x1 - x0)) + 0.5), dpi=100)
    for ax, (title, pixels) in zip(axes, panels):
        ax.imshow(np.clip(pixels, 0, 1), interpolation="lanczos")
        ax.set_title(title, fontsize=10)
        ax.axis("off")
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


if __name__ == "__main__":
    sys.exit(main())
