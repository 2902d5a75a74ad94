"""Named ways to make a lat-long environment map from a plate, for comparisons.

METHODS maps a name to `fn(plate_linear (H, W, 3), bbox, hfov_deg, width) -> (width/2, width, 3)`
float32 lat-long in the camera frame (CONVENTIONS.md). The accuracy study
(`python -m virtual_reflections evaluate`) charts them against each other.
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
    "frustum": _engine(method="frustum"),
    "frustum, sharp edges": _engine(method="frustum", extend_blur=0.25, extend_cap=0.03),
    "frustum, soft edges": _engine(method="frustum", extend_blur=4.0, extend_cap=0.5),
}
