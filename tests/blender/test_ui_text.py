"""What the artist reads: one-line tooltips, the operators in the Object menu (so menu search,
F3, finds them), plain names that do not sort beside Blender's "VR Scene Inspection"."""

import bpy
from shots import addon_part


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
