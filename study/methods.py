"""Named ways to make a lat-long environment map from a plate, for comparisons.

METHODS maps a name to `fn(plate_linear (H, W, 3), bbox, hfov_deg, width) -> (width/2, width, 3)`
float32 lat-long in the camera frame (docs/conventions.md). The accuracy study
(`python -m study evaluate`) charts them against each other; "camera" (the add-on's
Camera View, with Params' defaults) is its default, the distant model; "camera + horizon" is
the map of the add-on's default, Camera View + Ground, whose ground (read per shading point
in the material) this distant truth has at infinity.
"""

from __future__ import annotations

import math

from virtual_reflections.envmap import environment_map
from virtual_reflections.params import SKY_GAINS, Params

# The accuracy study's camera pitch (degrees, negative: looking down; its Config.pitch): the
# world's horizon of every view, which "camera + horizon" is given as the add-on gives it.
PITCH_DEG = -8.0


def world_up(pitch_deg: float) -> tuple:
    """The world's up direction in the engine's camera frame (docs/conventions.md: +Z the view
    direction, +Y up, +X the plate's left) of a camera pitched by ``pitch_deg``, no roll."""
    pitch = math.radians(pitch_deg)
    return (0.0, math.cos(pitch), math.sin(pitch))


def _engine(**kwargs):
    def make(plate, bbox, hfov_deg, width):
        params = Params(hfov=hfov_deg, **kwargs)
        return environment_map(plate, bbox, params, "latlong", width)

    return make


METHODS = {
    # the product's default: the edges fade within 20 degrees into a fill by elevation and side
    # (the plate's left half to the left, its right half to the right, both behind), as bright
    # as the geometric mean of the log-average and the mean, its shared tint half kept
    "camera": _engine(method="camera"),
    # the add-on's default's map (Camera View + Ground in the Replace look, the ground itself
    # read per shading point in the material, here at infinity as the truth's): the camera view
    # with the world's horizon, the sky prior alone above it (Auto's gain)
    "camera + horizon": _engine(
        method="camera", up=world_up(PITCH_DEG), sky_gain=SKY_GAINS["auto"]
    ),
    # the previous default: the edges extended into every unseen direction, no fill
    "camera, edges only": _engine(method="camera", extend_fade=None),
    # the previous fill: by elevation only (left and right mixed), a log-average (darker than
    # the plate's light), fading within 10 degrees, widening toward the whole plate's
    "camera, fill by elevation": _engine(
        method="camera", extend_fade=10.0, fill_sides=False, fill_energy=0.0, fill_spread=1.0
    ),
    # that fill never widening, with a longer fade
    "camera, sharp fill": _engine(
        method="camera", extend_fade=20.0, fill_sides=False, fill_energy=0.0, fill_spread=0.0
    ),
}
DEFAULT = "camera"
