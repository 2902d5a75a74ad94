"""Which engine back end runs, where a pipeline TD and an artist can see it: the batch report
records it, the add-on's preferences name it and say what the optional one would give."""

from shots import addon_part


class _Layout:
    use_property_split = use_property_decorate = False

    def __init__(self):
        self.labels = []

    def column(self, **_kw):
        return self

    row = column

    def prop(self, *_a, **_kw):
        pass

    def label(self, text="", **_kw):
        self.labels.append(text)


def _preferences_text(addon):
    prefs = addon_part("preferences")
    layout = _Layout()
    prefs.VR_AddonPreferences.draw(type("Prefs", (), {"layout": layout})(), None)
    return layout.labels


def test_the_preferences_name_the_back_end_and_the_optional_one(addon, monkeypatch):
    backends = addon_part("virtual_reflections.backends")
    labels = _preferences_text(addon)
    engine = [t for t in labels if t.startswith("Engine: ")]
    assert engine == [f"Engine: {backends.describe()}"], labels
    assert engine[0][len("Engine: ") :] in backends.NAMES.values()
    hint = [t for t in labels if "numba" in t]
    assert bool(hint) == ("numba" not in backends.installed())
    # A Blender without Numba or OpenCV (every distribution build): NumPy, and the hint.
    monkeypatch.setattr(backends, "installed", lambda: [])
    monkeypatch.setattr(backends, "_kernels", [])
    monkeypatch.delenv("VR_GATHER", raising=False)
    labels = _preferences_text(addon)
    assert "Engine: NumPy" in labels and any("numba" in t for t in labels), labels
