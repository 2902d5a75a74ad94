"""Named ways to make a lat-long environment map from a plate, for comparisons.

METHODS maps a name to `fn(plate_linear (H, W, 3), bbox, hfov_deg, width) -> (width/2, width, 3)`
float32 lat-long in the camera frame (CONVENTIONS.md). The accuracy study
(`python -m virtual_reflections evaluate`) charts them against each other; "frustum" (the
add-on's Camera View, with Params' defaults) is the product's default.
"""

from __future__ import annotations

from .envmap import environment_map
from .params import Params


def _engine(**kwargs):
    def make(plate, bbox, hfov_deg, width):
        params = Params(hfov=hfov_deg, **kwargs)
        return environment_map(plate, bbox, params, "latlong", width)

    return make


METHODS = {
    # the product's default: the edges extended into every unseen direction (left stays left)
    "frustum": _engine(method="frustum"),
    # the edges fade within 10 degrees into a log-average of the plate by elevation, widening
    # toward the whole plate's beyond its top and bottom
    "frustum, fill": _engine(method="frustum", extend_fade=10.0),
    # the fill by elevation alone, never widening, and a longer fade
    "frustum, sharp fill": _engine(method="frustum", extend_fade=20.0, fill_spread=0.0),
    # one log-average of the whole plate instead of one per elevation
    "frustum, flat fill": _engine(method="frustum", extend_fade=10.0, fill_width=90.0),
}
DEFAULT = "frustum"
