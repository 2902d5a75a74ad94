"""What the artist reads: one-line tooltips, the operators in the Object menu (so menu search,
F3, finds them), plain names that do not sort beside Blender's "VR Scene Inspection"."""

import types

import bpy
import pytest
from shots import add_camera, addon_part, ramp_plate


def _operators():
    return {name: getattr(bpy.ops.vr, name).get_rna_type() for name in dir(bpy.ops.vr)}


def _descriptions(rna):
    for prop in rna.properties:
        if prop.identifier != "rna_type":
            yield f"{rna.identifier}.{prop.identifier}", prop.description
            if prop.type == "POINTER" and prop.fixed_type.identifier.startswith("VR"):
                yield from _descriptions(prop.fixed_type)


def test_tooltips_are_one_line(addon):
    texts = {}
    for name, rna in _operators().items():
        texts[f"vr.{name}"] = rna.description
        texts.update(_descriptions(rna))
    scene = bpy.types.Scene.bl_rna.properties["virtual_reflections"].fixed_type
    obj = bpy.types.Object.bl_rna.properties["virtual_reflections"].fixed_type
    texts.update(_descriptions(scene))
    texts.update(_descriptions(obj))
    assert len(texts) > 30
    for where, text in texts.items():
        assert "\n" not in text, f"{where}: {text!r}"
    for name, rna in _operators().items():
        assert rna.description.strip(), f"vr.{name} has no tooltip"


def test_the_object_menu_lists_the_main_operators(addon):
    menus = addon_part("ui.menus")
    assert menus._draw_in_object_menu in bpy.types.VIEW3D_MT_object._dyn_ui_initialize()
    listed = [op for op, _ in menus.ITEMS]
    for op in ("vr.generate", "vr.remove", "vr.render_passes", "vr.setup_plate"):
        assert op in listed
        assert hasattr(bpy.ops.vr, op.split(".")[1]), op  # registered
    drawn = []

    class Layout:  # records what the menu draws
        def operator(self, idname, **_kw):
            drawn.append(idname)

    menus.VR_MT_object.draw(type("Menu", (), {"layout": Layout()})(), bpy.context)
    assert drawn == listed


def test_names_do_not_sort_beside_blenders_vr_tools(addon):
    panels = addon_part("ui.panel")
    assert {c.bl_category for c in panels.classes} == {"Reflections"}
    for name, rna in _operators().items():
        assert not rna.name.upper().startswith("VR"), f"vr.{name}: {rna.name}"


# --- issue 42, item 6: what the tooltips and the panel say -----------------------------------


def _scene_property(name):
    return bpy.types.Scene.bl_rna.properties["virtual_reflections"].fixed_type.properties[name]


def test_auto_resolution_says_it_rounds_up(addon):
    auto = next(i for i in _scene_property("resolution").enum_items if i.identifier == "AUTO")
    assert "below" not in auto.description and "rounded up" in auto.description
    assert "full-size render" in auto.description  # not a preview's Resolution %


def test_undo_set_up_names_all_it_restores(addon):
    text = bpy.ops.vr.undo_setup_plate.get_rna_type().description
    for what in ("render size", "view transform", "camera background", "focal length"):
        assert what in text, what
    assert "compositor" in text and "ground" in text


def test_set_up_ground_says_what_each_engine_shows(addon):
    ground = bpy.ops.vr.setup_plate.get_rna_type().properties["ground"].description
    assert "Cycles" in ground and "EEVEE" in ground


@pytest.mark.parametrize("name", ["method", "front", "resolution", "combine"])
def test_choice_lists_say_what_they_choose(addon, name):
    prop = _scene_property(name)
    assert len(prop.description) > 30, f"{name}: {prop.description!r}"
    assert prop.description not in {item.description for item in prop.enum_items}


class _Layout:
    """Records the text a panel draws (labels, properties, operators) and takes any call."""

    def __init__(self, texts):
        self.__dict__["texts"] = texts

    def __getattr__(self, name):
        def call(*args, **kwargs):
            if "text" in kwargs:
                self.texts.append(kwargs["text"])
            return _Layout(self.texts)

        return call


def _object_panel_texts(obj):
    texts = []
    context = types.SimpleNamespace(
        scene=bpy.context.scene,
        active_object=obj,
        preferences=types.SimpleNamespace(system=types.SimpleNamespace(ui_scale=1.0)),
        region=types.SimpleNamespace(width=600),
    )
    bpy.types.VR_PT_object.draw(types.SimpleNamespace(layout=_Layout(texts)), context)
    return " ".join(texts)


def _generated_ball(method):
    scene = bpy.context.scene
    add_camera(scene, distance=8.0, size=(96, 64))
    scene.virtual_reflections.plate_image = ramp_plate(96, 64)
    scene.virtual_reflections.method = method
    scene.virtual_reflections.resolution = "256"
    bpy.ops.mesh.primitive_uv_sphere_add(radius=1.0, segments=16, ring_count=8)
    ball = bpy.context.active_object
    report = addon_part("operators.generate").generate(
        scene, bpy.context.evaluated_depsgraph_get(), [ball]
    )
    assert report.done == [ball.name], report.warnings
    return ball


def test_an_object_generated_while_selected_says_it_reflects(addon):
    ball = _generated_ball("GROUND")
    assert not ball.virtual_reflections.enabled  # generated for the selection, not marked
    text = _object_panel_texts(ball)
    assert "Reflect the Plate" not in text  # a mark that stays off on a reflecting object
    assert "Reflects the plate" in text and "not marked" in text
    ball.virtual_reflections.enabled = True
    assert "not marked" not in _object_panel_texts(ball)


@pytest.mark.parametrize("method", ["GROUND", "CAMERA"])
def test_the_segmentation_says_what_the_method_uses(addon, method):
    text = _object_panel_texts(_generated_ball(method))
    assert "no regions" in text and "camera's view" in text and "paper's" in text
    assert ("ground" in text) == (method == "GROUND")


def test_set_up_warnings_say_warning_once(addon, tmp_path):
    """Blender's report puts "Warning:" before a warning itself."""
    scene = bpy.context.scene
    add_camera(scene, size=(1920, 1080))  # framed 16:9, the plate is 3:2
    scene.virtual_reflections.plate_image = ramp_plate(96, 64)
    reports = []
    operator = types.SimpleNamespace(ground=False, lens=False)
    operator.report = lambda level, text: reports.append((set(level), text))
    assert bpy.types.VR_OT_setup_plate.execute(operator, bpy.context) == {"FINISHED"}
    warnings = [text for level, text in reports if level == {"WARNING"}]
    assert any("the camera was framed for" in w for w in warnings), reports
    assert not [w for w in warnings if w.startswith("Warning")], warnings
