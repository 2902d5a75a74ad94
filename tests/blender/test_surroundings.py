"""Surroundings (Camera View + Ground): what the artist says of the shot sets how bright the
sky the plate does not show is taken to be (virtual_reflections.params.SKY_GAINS), in the
map and per frame, from the panel's setting and from the batch's --surroundings.

The camera looks 35 degrees down at a brown ground, so the plate shows no sky: straight up
from the ball the map holds the sky prior alone — under Auto the plate's mean colour
AUTO_SKY_GAIN times as bright, its hue AUTO_SKY_TINT of the way from grey; under the other
kinds a neutral grey `gain` times the plate's ground level — and the ground below it stays the
plate's.
"""

import math

import bpy
import numpy as np
import pytest
from shots import add_camera, addon_part, ground_plate

W, H = 160, 90
GROUND = (0.18, 0.15, 0.12)
LUMA = np.array([0.2126, 0.7152, 0.0722])
LEVEL = float(np.dot(GROUND, LUMA))  # the plate's level, its mean's and its ground band's


def make_shot():
    scene = bpy.context.scene
    cam = add_camera(scene, size=(W, H))
    cam.location = (0.0, -5.0, 3.0)
    cam.rotation_euler = (math.radians(90 - 35), 0.0, 0.0)  # looks along +Y, 35 deg down
    cam.data.lens = 50.0  # 22 degrees high: the frame's top edge is 24 degrees below the horizon
    bpy.ops.mesh.primitive_uv_sphere_add(radius=0.5, location=(0.0, -0.8, 0.5))
    ball = bpy.context.active_object
    ball.name = "Ball"
    settings = scene.virtual_reflections
    settings.method = "GROUND"
    settings.combine = "WORLD"
    settings.resolution = "256"
    settings.plate_image = ground_plate(
        scene, 0.0, lambda x, y: np.broadcast_to(np.array(GROUND), (*x.shape, 3)), (1, 0, 1)
    )
    return scene, ball


def up_and_ahead(scene, ball, others=()):
    """The map's mean colour within 20 degrees of straight up, and within 3 degrees of the
    direction toward the ground 3 m ahead of the ball (in view, out of its contact shadow);
    ``others``: more objects to Generate with it."""
    objects = [ball, *others]
    report = addon_part("operators.generate").generate(
        scene, bpy.context.evaluated_depsgraph_get(), objects
    )
    assert report.done == [o.name for o in objects], report.warnings
    image = addon_part("operators.node_trees.shading").map_of(ball)
    pixels = addon_part("operators.scene.images").read_pixels(image)[..., :3]
    bounds = addon_part("operators.scene.bounds")
    projection = bounds.camera_projection(scene)
    up = np.array(bounds.to_engine_frame(projection, vector=(0, 0, 1)))
    ahead = np.subtract(
        bounds.to_engine_frame(projection, point=(0.0, 2.2, 0.0)),
        bounds.to_engine_frame(projection, point=tuple(ball.location)),
    )
    ahead /= np.linalg.norm(ahead)
    d = addon_part("virtual_reflections.layouts").texel_directions("latlong", pixels.shape[1])
    near_up = d @ up > math.cos(math.radians(20))
    near_ahead = d @ ahead > math.cos(math.radians(3))
    return pixels[near_up].mean(0), pixels[near_ahead].mean(0)


def auto_sky(params):
    """Auto's unseen sky over this plate (params.AUTO_SKY_GAIN, AUTO_SKY_TINT)."""
    share = params.AUTO_SKY_TINT
    return params.AUTO_SKY_GAIN * LEVEL * ((1 - share) + share * np.array(GROUND) / LEVEL)


def test_the_named_surroundings_set_the_unseen_sky(addon):
    params = addon_part("virtual_reflections.params")
    scene, ball = make_shot()
    assert scene.virtual_reflections.surroundings == "AUTO"
    sky, ground = {}, {}
    for kind in ("AUTO", "OPEN", "ENCLOSED"):
        scene.virtual_reflections.surroundings = kind
        sky[kind], ground[kind] = up_and_ahead(scene, ball)
    # Auto: the plate's own colour, brighter, warm as the ground is
    np.testing.assert_allclose(sky["AUTO"], auto_sky(params), rtol=0.03)
    assert sky["AUTO"][0] > sky["AUTO"][2]
    for kind in ("OPEN", "ENCLOSED"):
        colour = sky[kind]
        assert np.ptp(colour) < 0.02 * colour.mean(), (kind, colour)  # a neutral grey
        gain = params.SKY_GAINS[kind.lower()]
        assert colour.mean() == pytest.approx(gain * LEVEL, rel=0.03), kind
    for kind in sky:  # the ground the plate shows is the plate's, whatever the sky
        np.testing.assert_allclose(ground[kind], GROUND, atol=0.03)
    assert sky["ENCLOSED"].mean() < sky["AUTO"].mean() < sky["OPEN"].mean()


def rough_material(name, roughness):
    mat = bpy.data.materials.new(name)
    if bpy.app.version < (5, 0, 0):
        mat.use_nodes = True
    mat.node_tree.nodes["Principled BSDF"].inputs["Roughness"].default_value = roughness
    return mat


def test_a_rough_surface_sees_a_brighter_sky(addon):
    """A rough surface (0.35) sees a brighter unseen sky than a mirror: the ground band's,
    neutral, params.sky_gain_for's gain (ROUGH_SKY_RATIOS times Auto's ground gain) times the
    plate's ground level (the straight-up texels, far from the plate's ground, keep the prior's
    level through the blur) — in the Mix look, whose map is pre-filtered for the roughness,
    and in the World look, whose map lights the surface; Replace, a mirror mode, keeps the
    mirror's, Auto's sky from the plate, and so does a world that also lights a mirror."""
    params = addon_part("virtual_reflections.params")
    scene, ball = make_shot()
    ball.data.materials.append(rough_material("Rough", 0.35))
    sky = {}
    for combine in ("REPLACE", "WORLD", "MIX"):
        scene.virtual_reflections.combine = combine
        sky[combine], _ = up_and_ahead(scene, ball)
    np.testing.assert_allclose(sky["REPLACE"], auto_sky(params), rtol=0.03)
    expected = params.sky_gain_for("auto", 0.35) * LEVEL
    assert expected > 2.0 * sky["REPLACE"].mean()
    for combine in ("WORLD", "MIX"):
        assert np.ptp(sky[combine]) < 0.02 * sky[combine].mean(), combine  # neutral
        assert sky[combine].mean() == pytest.approx(expected, rel=0.05), combine
    # A mirror beside it: the world they share holds the mirror's sky.
    bpy.ops.mesh.primitive_uv_sphere_add(radius=0.3, location=(1.2, -0.8, 0.3))
    mirror = bpy.context.active_object
    mirror.data.materials.append(rough_material("Mirror", 0.0))
    scene.virtual_reflections.combine = "WORLD"
    shared, _ = up_and_ahead(scene, ball, [mirror])
    assert shared.mean() / sky["REPLACE"].mean() == pytest.approx(1.0, rel=0.05)


def test_the_batch_option_sets_the_surroundings(addon):
    """--surroundings reaches the scene's setting; a word it does not know is refused."""
    options = addon_part("operators.batch.options")
    render = addon_part("operators.batch.render")
    scene, _ = make_shot()
    render.configure(scene, options.BatchOptions(plate="p.exr", out="o", surroundings="open"))
    assert scene.virtual_reflections.surroundings == "OPEN"
    render.configure(scene, options.BatchOptions(plate="p.exr", out="o"))
    assert scene.virtual_reflections.surroundings == "OPEN"  # not given: the shot's own
    with pytest.raises(
        ValueError, match="--surroundings must be auto, open, enclosed, world or custom"
    ):
        options.BatchOptions(plate="p.exr", out="o", surroundings="outdoors")


def test_custom_surroundings_take_the_artists_sky_brightness(addon):
    """Surroundings Custom: the unseen sky is a neutral grey Sky Brightness times the plate's
    ground level (straight up from the ball; by default an average place's, 1.6), the ground
    the plate shows unchanged; the map follows the setting; a rough surface takes Auto's ratio
    over it."""
    params = addon_part("virtual_reflections.params")
    scene, ball = make_shot()
    settings = scene.virtual_reflections
    assert settings.sky_brightness == pytest.approx(params.SKY_GAINS["auto"])
    settings.surroundings = "CUSTOM"
    start, _ = up_and_ahead(scene, ball)
    assert np.ptp(start) < 0.02 * start.mean()
    assert start.mean() == pytest.approx(params.SKY_GAINS["auto"] * LEVEL, rel=0.03)
    sky = {}
    for brightness in (0.5, 4.0):
        settings.sky_brightness = brightness
        sky[brightness], ground = up_and_ahead(scene, ball)
        np.testing.assert_allclose(ground, GROUND, atol=0.03)
        ratio = sky[brightness].mean() / start.mean()
        assert ratio == pytest.approx(brightness / params.SKY_GAINS["auto"], rel=0.03)
    assert params.sky_gain_for("custom", 0.35, 4.0) == pytest.approx(
        4.0 * params.sky_gain_for("auto", 0.35) / params.SKY_GAINS["auto"]
    )
    assert params.sky_gain_for("custom", 1.0, 100.0) == params.MAX_SKY_GAIN  # held in range
    # Sky Tint: the unseen sky takes its colour at the same luminance
    luma = LUMA
    settings.sky_tint = (1.0, 0.6, 0.3)  # a sunset
    orange, ground = up_and_ahead(scene, ball)
    np.testing.assert_allclose(ground, GROUND, atol=0.03)
    assert float(orange @ luma) == pytest.approx(float(sky[4.0] @ luma), rel=0.03)
    np.testing.assert_allclose(orange / orange[0], (1.0, 0.6, 0.3), rtol=0.05)
    drawn = draw_main_panel(scene)
    assert {"sky_brightness", "sky_tint"} <= set(drawn.props)
    settings.surroundings = "OPEN"  # a named kind: neutral, whatever the tint
    assert not {"sky_brightness", "sky_tint"} & set(draw_main_panel(scene).props)
    named, _ = up_and_ahead(scene, ball)
    assert np.ptp(named) < 0.02 * named.mean()


def test_the_batch_option_sets_the_sky_brightness(addon):
    """--sky-brightness sets Surroundings Custom and its brightness; --surroundings custom
    alone keeps the shot's brightness; a brightness with another named kind, or out of range,
    is refused in one line."""
    options = addon_part("operators.batch.options")
    render = addon_part("operators.batch.render")
    scene, _ = make_shot()
    render.configure(scene, options.BatchOptions(plate="p.exr", out="o", sky_brightness=2.5))
    settings = scene.virtual_reflections
    assert settings.surroundings == "CUSTOM"
    assert settings.sky_brightness == pytest.approx(2.5)
    settings.surroundings, settings.sky_brightness = "AUTO", 3.0
    render.configure(scene, options.BatchOptions(plate="p.exr", out="o", surroundings="custom"))
    assert (settings.surroundings, round(settings.sky_brightness, 4)) == ("CUSTOM", 3.0)
    with pytest.raises(ValueError, match="not with --surroundings open"):
        options.BatchOptions(plate="p.exr", out="o", surroundings="open", sky_brightness=2.0)
    render.configure(scene, options.BatchOptions(plate="p.exr", out="o", sky_tint=(0.5, 0.7, 1)))
    assert tuple(round(v, 4) for v in settings.sky_tint) == (0.5, 0.7, 1.0)
    for bad in ((0, 0, 0), (1, 2, 1), (1, 1), "blue"):
        with pytest.raises(ValueError, match="--sky-tint: expected R,G,B from 0 to 1"):
            options.BatchOptions(plate="p.exr", out="o", sky_tint=bad)
    with pytest.raises(ValueError, match="--sky-tint sets Surroundings Custom"):
        options.BatchOptions(plate="p.exr", out="o", surroundings="world", sky_tint=(1, 1, 1))
    for bad in (-1.0, 101.0, float("nan"), "bright"):
        with pytest.raises(ValueError, match="--sky-brightness: expected a number from 0 to 100"):
            options.BatchOptions(plate="p.exr", out="o", sky_brightness=bad)


def test_the_sky_texture_reaches_every_maps_params(addon, monkeypatch):
    """Sky Texture (0..1, default methods.SKY_TEXTURE; 0: the flat sky prior) is the
    Params.sky_texture of every mirror map Generate builds, under each Surroundings kind that
    uses the prior (a rough surface's map takes the share its roughness sees: none at 0.35),
    rounded so that a slider's float noise builds no new table; the panel shows it beside
    the Surroundings."""
    pipeline = addon_part("operators.pipeline")
    scene, ball = make_shot()
    settings = scene.virtual_reflections
    built = []
    map_table = pipeline.map_table

    def recording(plate_shape, box, map_params, *args, **kwargs):
        built.append(map_params)
        return map_table(plate_shape, box, map_params, *args, **kwargs)

    monkeypatch.setattr(pipeline, "map_table", recording)

    def textures():
        built.clear()
        up_and_ahead(scene, ball)
        assert built and all(p.method == "ground" for p in built), built
        return {p.world.sky_texture for p in built}

    assert settings.sky_texture == 0.75  # methods.SKY_TEXTURE
    assert textures() == {0.75}
    settings.sky_texture = 0.5
    for kind in ("AUTO", "OPEN", "ENCLOSED", "CUSTOM"):
        settings.surroundings = kind
        assert textures() == {0.5}, kind
        drawn = draw_main_panel(scene)
        assert "sky_texture" in drawn.props and "sky_texture" not in drawn.inactive, kind
    ball.data.materials.append(rough_material("Rough", 0.35))
    settings.combine = "MIX"  # a rough surface's map: its own, brighter prior, and no texture
    assert textures() == {0.0}  # (params.sky_texture_for: none from roughness 0.15 on)
    settings.combine = "REPLACE"
    settings.sky_texture = 0.5 + 1e-7  # a slider's float noise
    assert settings.sky_texture != 0.5
    intrinsics = (100.0, 100.0, 80.0, 45.0)
    assert pipeline.params(settings, intrinsics).world.sky_texture == 0.5
    settings.sky_texture = 0.0
    assert pipeline.params(settings, intrinsics).world.sky_texture == 0.0


def test_the_batch_option_sets_the_sky_texture(addon):
    """--sky-texture K sets the shot's Sky Texture under any Surroundings; without it the
    shot's own stays; out of 0..1 it is refused in one line."""
    options = addon_part("operators.batch.options")
    render = addon_part("operators.batch.render")
    scene, _ = make_shot()
    settings = scene.virtual_reflections
    render.configure(scene, options.BatchOptions(plate="p.exr", out="o", sky_texture=0.5))
    assert settings.sky_texture == pytest.approx(0.5) and settings.surroundings == "AUTO"
    render.configure(scene, options.BatchOptions(plate="p.exr", out="o", surroundings="open"))
    assert settings.sky_texture == pytest.approx(0.5)  # not given: the shot's own
    render.configure(
        scene, options.BatchOptions(plate="p.exr", out="o", surroundings="open", sky_texture=0)
    )
    assert (settings.surroundings, settings.sky_texture) == ("OPEN", 0.0)
    for bad in (-0.1, 2, float("nan"), "some"):
        with pytest.raises(ValueError) as refused:
            options.BatchOptions(plate="p.exr", out="o", sky_texture=bad)
        assert "--sky-texture: expected a number from 0 to 1" in str(refused.value)
        assert "\n" not in str(refused.value)


class _Layout:
    """Records what a panel draws: the properties, those of them greyed out (drawn in a
    layout, or a layout within it, whose ``active`` is off) and the labels (every other
    layout call draws nothing here)."""

    def __init__(self, parent=None):
        self.parent, self.active = parent, True
        if parent is None:
            self.props, self.inactive, self.labels = [], [], []
        else:
            self.props, self.inactive, self.labels = parent.props, parent.inactive, parent.labels

    def column(self, **_kw):
        return _Layout(self)

    row = box = column

    def greyed(self):
        return not self.active or (self.parent is not None and self.parent.greyed())

    def prop(self, _data, name, **_kw):
        self.props.append(name)
        if self.greyed():
            self.inactive.append(name)

    def label(self, text="", **_kw):
        self.labels.append(text)

    def operator(self, *_args, **_kw):
        return type("OperatorProperties", (), {})()

    def __getattr__(self, _name):  # template_ID, progress, separator...
        return lambda *_args, **_kw: None


def draw_method_panel(scene, selected=()):
    return draw_panel("VR_PT_method", scene, selected)


def draw_main_panel(scene):
    return draw_panel("VR_PT_main", scene)


def draw_panel(name, scene, selected=()):
    panel = addon_part("ui.panel")
    layout = _Layout()
    context = type(
        "Context",
        (),
        {
            "scene": scene,
            "region": type("Region", (), {"width": 300})(),
            "preferences": type("P", (), {"system": type("S", (), {"ui_scale": 1.0})()})(),
            "active_object": None,
            "selected_objects": list(selected),
            "evaluated_depsgraph_get": staticmethod(bpy.context.evaluated_depsgraph_get),
        },
    )()
    getattr(panel, name).draw(type("Panel", (), {"layout": layout})(), context)
    return layout


def test_the_panel_asks_for_the_surroundings_when_the_camera_sees_no_sky(addon):
    """The Surroundings sit in the main panel, under the Look (the setting that matters most
    for the unseen sky), not in the Method sub-panel: one home."""
    pipeline = addon_part("operators.pipeline")
    scene, _ = make_shot()
    assert pipeline.camera_sky(scene) == 0.0  # 35 degrees down, 22 high: ground only
    drawn = draw_main_panel(scene)
    assert "surroundings" in drawn.props
    assert "surroundings" not in draw_method_panel(scene).props
    assert any("sees no sky" in text for text in drawn.labels), drawn.labels
    scene.virtual_reflections.surroundings = "OPEN"  # named: nothing to ask
    assert not any("sky" in text for text in draw_main_panel(scene).labels)
    scene.virtual_reflections.surroundings = "AUTO"
    scene.camera.rotation_euler = (math.radians(90), 0.0, 0.0)  # level: half the frame is sky
    bpy.context.view_layer.update()
    assert pipeline.camera_sky(scene) == pytest.approx(0.5, abs=0.02)
    assert not any("sky" in text for text in draw_main_panel(scene).labels)
    scene.virtual_reflections.method = "CAMERA"  # no ground method: no Surroundings
    assert "surroundings" not in draw_main_panel(scene).props


def test_the_panel_says_where_the_ground_is_taken_from(addon):
    """No Ground chosen: the panel names the floor under the selected objects, or says the
    objects' lowest point is taken; with a Ground chosen, the field says it all."""
    scene, ball = make_shot()
    lines = [t for t in draw_method_panel(scene, [ball]).labels if t.startswith("Ground")]
    assert len(lines) == 1 and "lowest point" in lines[0], lines
    bpy.ops.mesh.primitive_plane_add(size=20.0, location=(0.0, 0.0, -0.2))
    floor = bpy.context.active_object
    floor.name = "Floor"
    drawn = draw_method_panel(scene, [ball]).labels
    assert any("'Floor', the floor under" in t for t in drawn), drawn
    scene.virtual_reflections.ground_object = floor
    assert not any(t.startswith("Ground") for t in draw_method_panel(scene, [ball]).labels)
    depsgraph = bpy.context.evaluated_depsgraph_get()
    floors = addon_part("operators.scene.floor")
    assert floors.ground_source(scene, depsgraph, [ball]) == "Ground: 'Floor', chosen"
