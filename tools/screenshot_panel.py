"""Screenshots of the N-panel from a real Blender window (run by tools/screenshot-panel).

    blender --factory-startup --enable-event-simulate --python tools/screenshot_panel.py \\
        -- --handshake DIR

Builds the sample scene (a chrome sphere on the courtyard plate), generates its reflection
with the add-on from this checkout, shows the 3D viewport through the camera in Material
Preview with the sidebar on the "Reflections" tab (clicked, as an artist would: the tab is
read-only in Python), then opens the segmentation in an Image Editor with the panel's button.

Blender's own screenshot operators read the window's front buffer, which is black under Xvfb
with software OpenGL, so the pictures are taken from the X server: at each shot this script
writes ``DIR/<n>.json`` ({"crops": {name: [x, y, width, height]}}, X screen pixels, origin
top-left) and waits for ``DIR/<n>.done``; tools/screenshot-panel grabs the screen (xwd) in
between and crops. Prints one line ``RESULT={json}`` (what was checked) and quits.
"""

import argparse
import importlib.util
import json
import os
import pathlib
import sys
import time
import traceback

import bpy

ROOT = pathlib.Path(__file__).resolve().parents[1]
RESULT = {}
STATE = {}
STEPS = []
WAIT_FOR_SHOT = 60.0  # seconds


def _args():
    argv = sys.argv[sys.argv.index("--") + 1 :] if "--" in sys.argv else []
    p = argparse.ArgumentParser(prog="screenshot_panel", allow_abbrev=False)
    p.add_argument("--handshake", required=True, help="folder shared with tools/screenshot-panel")
    return p.parse_args(argv)


def _load(name, path, package=False):
    spec = importlib.util.spec_from_file_location(
        name, path, submodule_search_locations=[str(path.parent)] if package else None
    )
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module


ARGS = _args()
ADDON = _load("vr_screenshot_addon", ROOT / "__init__.py", package=True)
ADDON.register()
SCENES = _load("vr_build_scenes", ROOT / "sample_scenes" / "build_scenes.py")


def view3d(window):
    area = max(
        (a for a in window.screen.areas if a.type == "VIEW_3D"), key=lambda a: a.width * a.height
    )
    return area, next(r for r in area.regions if r.type == "UI")


def screen_rect(window, thing):
    """[x, y, w, h] of a window, area or region on the X screen (origin top-left)."""
    wx, wy = getattr(window, "x", 0), getattr(window, "y", 0)
    if thing is window:
        return [wx, wy, window.width, window.height]
    return [wx + thing.x, wy + window.height - (thing.y + thing.height), thing.width, thing.height]


def step(function):
    STEPS.append(function)
    return function


def shot(crops):
    """Ask for the screen to be grabbed; the next step waits until it has been."""
    STATE["shots"] = STATE.get("shots", 0) + 1
    base = os.path.join(ARGS.handshake, f"{STATE['shots']:02d}")
    with open(base + ".json.tmp", "w") as f:
        json.dump({"crops": crops}, f)
    os.replace(base + ".json.tmp", base + ".json")
    STATE["waiting"] = (base + ".done", time.monotonic())
    STEPS.insert(0, wait_for_shot)


def wait_for_shot():
    path, since = STATE["waiting"]
    if os.path.exists(path):
        return
    if time.monotonic() - since > WAIT_FOR_SHOT:
        raise RuntimeError("no screen grab came back (is tools/screenshot-panel running this?)")
    STEPS.insert(0, wait_for_shot)
    return 0.2


@step
def prepare():
    for obj in list(bpy.data.objects):  # the factory scene emptied (a new file would
        bpy.data.objects.remove(obj)  # rebuild the window's screens under our feet)
    built = SCENES.build("spheres", "courtyard", scale=50, samples=8)
    sphere = built.objects[0]
    for obj in bpy.context.view_layer.objects:
        obj.select_set(obj == sphere)
    bpy.context.view_layer.objects.active = sphere
    settings = built.scene.virtual_reflections
    settings.resolution = "AUTO"
    window = bpy.context.window_manager.windows[0]
    area, _ui = view3d(window)
    with bpy.context.temp_override(window=window, area=area):
        bpy.ops.vr.setup_plate()  # the plate behind the camera view, as an artist sets it up
        assert bpy.ops.vr.generate() == {"FINISHED"}, "Generate failed"
        bpy.ops.vr.apply_preset(preset="CHROME")
    if built.ground is not None:
        built.ground.hide_set(True)  # the shadow catcher shows as a grey floor in the viewport
    settings.live_update = True
    RESULT["report"] = settings.last_report
    space = area.spaces.active
    space.show_region_ui = True
    space.shading.type = "MATERIAL"
    space.region_3d.view_perspective = "CAMERA"
    STATE.update(window=window, area=area, sphere=sphere)
    # The splash screen of a factory start-up: Escape closes it.
    window.event_simulate(type="ESC", value="PRESS", x=window.width // 2, y=window.height // 2)
    window.event_simulate(type="ESC", value="RELEASE", x=window.width // 2, y=window.height // 2)


@step
def frame_camera():
    window, area = STATE["window"], STATE["area"]
    region = next(r for r in area.regions if r.type == "WINDOW")
    with bpy.context.temp_override(window=window, area=area, region=region):
        bpy.ops.view3d.view_center_camera()


@step
def next_tab():
    """Click down the sidebar's tabs (its outer edge, ours last) until ours is active."""
    window = STATE["window"]
    _area, ui = view3d(window)
    if ui.active_panel_category == "Reflections":
        return
    STATE["tries"] = STATE.get("tries", 0) + 1
    if STATE["tries"] > 30:
        raise RuntimeError(f"could not reach the Reflections tab ({ui.active_panel_category})")
    x = ui.x + ui.width - 8
    y = ui.y + ui.height - 30 - 25 * STATE["tries"]
    window.event_simulate(type="MOUSEMOVE", value="NOTHING", x=x, y=y)
    window.event_simulate(type="LEFTMOUSE", value="PRESS", x=x, y=y)
    window.event_simulate(type="LEFTMOUSE", value="RELEASE", x=x, y=y)
    STEPS.insert(0, next_tab)


@step
def park_mouse():
    # Away from buttons (no tooltip, no highlight); the viewport compiles its shaders.
    window, area = STATE["window"], STATE["area"]
    window.event_simulate(type="MOUSEMOVE", value="NOTHING", x=area.x + 40, y=area.y + 40)
    return 6.0


@step
def shoot_panel():
    window, area = STATE["window"], STATE["area"]
    _area, ui = view3d(window)
    previews = sys.modules[ADDON.__name__ + ".operators.previews"]
    shown = previews.for_object(bpy.context.scene, STATE["sphere"])
    RESULT.update(
        tab=ui.active_panel_category,
        panel=screen_rect(window, ui),
        previews=[p.icon_id for p in (shown["map"], shown["overlay"]) if p is not None],
        advice=shown["advice"],
        map=list(shown["image"].size) if shown["image"] is not None else None,
    )
    shot({"panel": screen_rect(window, ui), "viewport": screen_rect(window, area)})


@step
def open_segmentation():
    window, area = STATE["window"], STATE["area"]
    with bpy.context.temp_override(window=window, area=area):
        result = bpy.ops.vr.show_image(kind="SEGMENTATION", object=STATE["sphere"].name)
    RESULT["show_image"] = sorted(result)
    editors = [
        (w, a)
        for w in bpy.context.window_manager.windows
        for a in w.screen.areas
        if a.type == "IMAGE_EDITOR" and a.spaces.active.image is not None
    ]
    RESULT["image_editors"] = [a.spaces.active.image.name for _w, a in editors]
    if editors:
        STATE["editor"] = editors[-1]
    return 2.0


@step
def fit_editor():
    if "editor" in STATE:
        w, a = STATE["editor"]
        region = next(r for r in a.regions if r.type == "WINDOW")
        with bpy.context.temp_override(window=w, area=a, region=region):
            bpy.ops.image.view_all(fit_view=True)
    return 2.0


@step
def shoot_editor():
    if "editor" in STATE:
        w, a = STATE["editor"]
        shot({"segmentation_editor": screen_rect(w, w)})


@step
def drag():
    """Live update with Blender's own timers: move the sphere as a drag would."""
    maps = sys.modules[ADDON.__name__ + ".operators.scene.maps"]
    image = bpy.data.images[maps.map_name(STATE["sphere"].name)]
    STATE["version"] = maps.version(image)
    STATE["sphere"].location.x += 0.3
    return 2.0  # more than live.REST: the small map, then the full one


SETTLE = 30.0  # seconds a loaded machine may take (software GL draws slowly between timers)


def _settled(live, key):
    """True once live update has nothing pending or resting, or after SETTLE seconds; else
    put the calling step back to run again soon."""
    started = STATE.setdefault(key, time.monotonic())
    if (live.pending() or live.resting()) and time.monotonic() - started < SETTLE:
        STEPS.insert(0, globals()[key])
        return False
    return True


@step
def rested():
    maps = sys.modules[ADDON.__name__ + ".operators.scene.maps"]
    live = sys.modules[ADDON.__name__ + ".operators.live"]
    if not _settled(live, "rested"):
        return 0.5
    image = bpy.data.images[maps.map_name(STATE["sphere"].name)]
    RESULT["live"] = {
        "passes": maps.version(image) - STATE["version"],
        "size": list(image.size),
        "status": live.status(bpy.context.scene),
    }
    bpy.context.scene.virtual_reflections.enlarge = 10.0  # a setting that shapes the map
    STATE["version"] = maps.version(image)
    return 2.0


@step
def reshaped():
    maps = sys.modules[ADDON.__name__ + ".operators.scene.maps"]
    if not _settled(sys.modules[ADDON.__name__ + ".operators.live"], "reshaped"):
        return 0.5
    image = bpy.data.images[maps.map_name(STATE["sphere"].name)]
    RESULT["live"]["after_enlarge"] = maps.version(image) - STATE["version"]


def run():
    wait = 1.0
    try:
        wait = STEPS.pop(0)() or 1.0
    except Exception:
        RESULT["error"] = traceback.format_exc()
        STEPS.clear()
    if STEPS:
        return wait
    print("RESULT=" + json.dumps(RESULT), flush=True)
    ADDON.unregister()
    bpy.ops.wm.quit_blender()
    return None


bpy.app.timers.register(run, first_interval=1.0)
