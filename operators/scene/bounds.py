"""Where an object lands on the plate: its screen-space bounding box in plate pixels.

Plate pixels (docs/conventions.md, "Plate pixels"): origin at the top-left of the rendered frame,
x to the right, y **down**; pixel ``(px, py)`` covers ``[px, px + 1) x [py, py + 1)``, its centre
at ``+ 0.5``. A box ``(x0, y0, x1, y1)`` covers ``[x0, x1) x [y0, y1)`` (x1/y1 exclusive); the
pixels it touches are ``range(floor(x0), ceil(x1)) x range(floor(y0), ceil(y1))``. Boxes may reach
outside the frame.

Camera space is Blender's camera-local frame: the camera looks down -Z, +X right, +Y up; the depth
of a point is ``-z``. The frame is the render's viewplane (Blender's
``BKE_camera_params_compute_viewplane``, Cycles' ``blender_camera_viewplane``): sensor fit, lens
shift, pixel aspect, and the render size after ``resolution_percentage``. Renders don't show
geometry nearer than ``clip_start``, so geometry is clipped against the plane ``z = -clip_start``
before it is projected (perspective and orthographic alike); what is left projects to finite
pixels, clamped to +-LIMIT.
"""

import math
from dataclasses import dataclass

import numpy as np

# Bounds are clamped to +-LIMIT pixels: geometry grazing the near plane projects very far out.
LIMIT = 1e6


@dataclass(frozen=True)
class ScreenBounds:
    """A box in plate pixels (origin top-left, y down, x1/y1 exclusive), from the render camera.

    ``width``/``height`` are the render size in pixels (after resolution_percentage).
    ``visible`` is False when nothing of the object is in view: off to a side, or entirely behind
    the near plane (then the box is all zeros). ``vertex_count``: vertices of the evaluated mesh.
    """

    x0: float
    y0: float
    x1: float
    y1: float
    width: int
    height: int
    visible: bool
    vertex_count: int

    def pixel_box(self, clamp: bool = False) -> tuple[int, int, int, int]:
        """The pixels the box touches, ``(x0, y0, x1, y1)`` integers, x1/y1 exclusive;
        with ``clamp``, cut to the frame (may then be empty: x1 <= x0 or y1 <= y0)."""
        box = [math.floor(self.x0), math.floor(self.y0), math.ceil(self.x1), math.ceil(self.y1)]
        if clamp:
            box = [min(max(v, 0), size) for v, size in zip(box, (self.width, self.height) * 2)]
        return tuple(box)

    def extent(self) -> float:
        """The larger side of the box cut to the frame, in render pixels (0 when outside)."""
        w = min(self.x1, self.width) - max(self.x0, 0.0)
        h = min(self.y1, self.height) - max(self.y0, 0.0)
        return max(w, h, 0.0)


@dataclass(frozen=True, eq=False)
class CameraProjection:
    """World -> plate pixels for one camera and render setting; reuse it for many objects.

    ``world_to_camera``: (4, 4) float64, the inverse of the camera's world matrix with its scale
    removed (renders ignore camera scale). ``frame``: (left, right, bottom, top) of the rendered
    frame in camera space, on the plane z = -1 (perspective) or in scene units (orthographic).
    Points are columns here, ``(3, N)``, so that each coordinate is one contiguous row.
    """

    world_to_camera: np.ndarray
    frame: tuple[float, float, float, float]
    orthographic: bool
    clip_start: float
    width: int
    height: int

    def to_camera(self, points: np.ndarray, matrix=None) -> np.ndarray:
        """(3, N) points -> (3, N) camera space, in the points' dtype; ``matrix`` (4, 4), e.g. an
        object's matrix_world, first takes them to world space."""
        m = self.world_to_camera
        if matrix is not None:  # Compose in float64: large, cancelling translations stay exact.
            m = m @ np.asarray(matrix, dtype=np.float64)
        m = m.astype(points.dtype, copy=False)
        out = m[:3, :3] @ points
        out += m[:3, 3:]
        return out

    def frame_coords(self, points: np.ndarray):
        """(3, N) camera-space points in front of the camera -> (x, y), each (N,), on the frame's
        plane: divided by depth (perspective) or as they are (orthographic)."""
        if self.orthographic:
            return points[0], points[1]
        depth = -points[2]
        return points[0] / depth, points[1] / depth

    def to_pixels(self, x, y):
        """Frame coordinates (arrays or floats) -> plate pixels (px, py), y down."""
        left, right, bottom, top = self.frame
        px = (x - left) * (self.width / (right - left))
        py = (top - y) * (self.height / (top - bottom))
        return px, py

    def plate_scale(self, plate_shape) -> tuple[float, float]:
        """(sx, sy): render pixels -> pixels of a plate of ``plate_shape`` (H, W, ...)."""
        return plate_shape[1] / self.width, plate_shape[0] / self.height

    def intrinsics(self, sx: float = 1.0, sy: float = 1.0):
        """(fx, fy, cx, cy) of a perspective camera in plate pixels (render pixels scaled by
        ``sx``, ``sy``; lens shift and pixel aspect included), or None when orthographic."""
        if self.orthographic:
            return None
        left, right, bottom, top = self.frame  # on the plane z = -1
        fx = self.width / (right - left) * sx
        fy = self.height / (top - bottom) * sy
        return (fx, fy, -left * fx, top * fy)


def camera_projection(scene, camera_obj=None) -> CameraProjection:
    """The projection of ``camera_obj`` (default: the scene camera) for the scene's render size.

    Raises ValueError for a missing or non-camera object and for panoramic/custom cameras.
    """
    camera_obj = camera_obj if camera_obj is not None else scene.camera
    if camera_obj is None:
        raise ValueError(f"scene '{scene.name}' has no camera: set scene.camera or pass one")
    if camera_obj.type != "CAMERA":
        raise ValueError(f"object '{camera_obj.name}' is a {camera_obj.type}, not a camera")
    cam = camera_obj.data
    if cam.type == "PANO":
        raise ValueError(f"camera '{camera_obj.name}': panoramic cameras are not supported")
    if cam.type not in {"PERSP", "ORTHO"}:
        raise ValueError(f"camera '{camera_obj.name}': {cam.type} cameras are not supported")

    render = scene.render
    width = render.resolution_x * render.resolution_percentage // 100
    height = render.resolution_y * render.resolution_percentage // 100
    camera_to_world = np.array(camera_obj.matrix_world, dtype=np.float64)
    camera_to_world[:3, :3] /= np.linalg.norm(camera_to_world[:3, :3], axis=0)
    return CameraProjection(
        world_to_camera=np.linalg.inv(camera_to_world),
        frame=_frame(cam, width * render.pixel_aspect_x, height * render.pixel_aspect_y),
        orthographic=cam.type == "ORTHO",
        clip_start=cam.clip_start,
        width=width,
        height=height,
    )


def _frame(cam, display_width, display_height):
    """(left, right, bottom, top) of the frame on z = -1, or in ortho units, from the render size
    in square units (Camera.view_frame gives the same, but for the size before the percentage)."""
    if cam.sensor_fit == "AUTO":
        horizontal = display_width >= display_height
    else:
        horizontal = cam.sensor_fit == "HORIZONTAL"
    if cam.type == "ORTHO":
        size = cam.ortho_scale
    else:  # AUTO fits the sensor width to the longer side.
        size = (cam.sensor_height if cam.sensor_fit == "VERTICAL" else cam.sensor_width) / cam.lens
    # `size` spans the fitted side, the other follows the display aspect; shift is in `size` units.
    if horizontal:
        half_w, half_h = size / 2, size / 2 * display_height / display_width
    else:
        half_w, half_h = size / 2 * display_width / display_height, size / 2
    cx, cy = cam.shift_x * size, cam.shift_y * size
    return (cx - half_w, cx + half_w, cy - half_h, cy + half_h)


def object_bounds(obj, depsgraph, scene, camera_obj=None, *, projection=None) -> ScreenBounds:
    """Screen bounds of ``obj``'s evaluated geometry (modifiers applied; curves, text, metaballs
    as meshes) through ``camera_obj`` (default: the scene camera), or through ``projection``
    from :func:`camera_projection` when bounding many objects.

    Raises ValueError when there is no camera or the object has no geometry.
    """
    projection = projection or camera_projection(scene, camera_obj)
    obj_eval = obj.evaluated_get(depsgraph)
    try:
        mesh = obj_eval.to_mesh()
    except RuntimeError:  # Empties, lights, cameras: "Object does not have geometry data".
        mesh = None
    try:
        if mesh is None or len(mesh.vertices) == 0:
            raise ValueError(f"object '{obj.name}' ({obj.type}) has no geometry to bound")
        # The raw attribute reads ~30x faster than mesh.vertices.foreach_get("co").
        local = _read(mesh.attributes["position"].data, "vector", 3, np.float32)
        cam = projection.to_camera(local.T, obj_eval.matrix_world)
        points = _clip_near(cam, projection.clip_start, mesh)
    finally:
        obj_eval.to_mesh_clear()
    return _bounds(projection, points, len(local))


def _read(collection, attribute, width, dtype):
    """One foreach_get of a bpy collection -> (len, width) array."""
    buf = np.empty(len(collection) * width, dtype=dtype)
    collection.foreach_get(attribute, buf)
    return buf.reshape(-1, width)


def _edges(mesh):
    """(E, 2) int32 vertex indices of the mesh's edges (of its triangles if it has no edges)."""
    if len(mesh.edges) == 0:
        tris = _read(mesh.loop_triangles, "vertices", 3, np.int32)
        return np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]])
    # The raw attribute reads ~100x faster than mesh.edges.foreach_get("vertices").
    attribute = mesh.attributes.get(".edge_verts")
    if attribute is not None and attribute.data_type == "INT32_2D":
        return _read(attribute.data, "value", 2, np.int32)
    return _read(mesh.edges, "vertices", 2, np.int32)


def _clip_near(cam, near, mesh):
    """(3, N) camera-space vertices -> (3, M) points whose projections bound the mesh's part in
    front of the plane z = -near: the vertices in front, and where edges cross the plane (a face
    clipped by the plane is bounded by its corners in front and its edges' crossings)."""
    depth = -cam[2]
    front = depth >= near
    if front.all():
        return cam
    edges = _edges(mesh)
    a, b = edges[front[edges[:, 0]] != front[edges[:, 1]]].T
    t = (near - depth[a]) / (depth[b] - depth[a])
    crossings = cam[:, a] + t * (cam[:, b] - cam[:, a])
    crossings[2] = -near  # exactly on the plane, whatever the rounding
    return np.concatenate([cam[:, front], crossings], axis=1)


def _bounds(projection, points, vertex_count):
    """(3, M) camera-space points in front -> ScreenBounds (pixels are monotonic in frame x/y)."""
    width, height = projection.width, projection.height
    if points.shape[1] == 0:
        return ScreenBounds(0.0, 0.0, 0.0, 0.0, width, height, False, vertex_count)
    x, y = projection.frame_coords(points)
    x0, y1 = projection.to_pixels(float(x.min()), float(y.min()))
    x1, y0 = projection.to_pixels(float(x.max()), float(y.max()))
    x0, y0, x1, y1 = (min(max(v, -LIMIT), LIMIT) for v in (x0, y0, x1, y1))
    visible = x0 < width and x1 > 0 and y0 < height and y1 > 0
    return ScreenBounds(x0, y0, x1, y1, width, height, visible, vertex_count)


def world_box(obj, depsgraph) -> tuple[np.ndarray, np.ndarray]:
    """(min (3,), max (3,)) float64 world-space corners of ``obj``'s evaluated bounding box
    (Blender's world: Z up)."""
    obj_eval = obj.evaluated_get(depsgraph)
    corners = np.array(obj_eval.bound_box, dtype=np.float64)  # (8, 3) local
    matrix = np.array(obj_eval.matrix_world, dtype=np.float64)
    world = corners @ matrix[:3, :3].T + matrix[:3, 3]
    return world.min(0), world.max(0)


def to_engine_frame(projection: CameraProjection, point=None, vector=None) -> tuple:
    """A world point or direction in the engine's camera frame (docs/conventions.md: +Z the
    view direction, +Y up, +X the plate's left): Blender's camera-local frame turned 180
    degrees about Y."""
    m = projection.world_to_camera
    if point is not None:
        local = m[:3, :3] @ np.asarray(point, np.float64) + m[:3, 3]
    else:
        local = m[:3, :3] @ np.asarray(vector, np.float64)
    return (-float(local[0]), float(local[1]), -float(local[2]))
