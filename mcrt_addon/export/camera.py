"""Camera export: Blender camera object -> tracer Camera (perspective lens, sensor, fit, shift).

A render border is exported as a smaller camera that sees exactly the border's pixels of the full
frame: the sub-rectangle of a pinhole image is itself a pinhole image with a narrower sensor and
a shift, so the tracer needs no crop support.
"""
import numpy as np

from .util import ExportError


def frame_window(lens, sensor_width, sensor_height, sensor_fit, shift_x, shift_y, width, height):
    """Blender's view plane at distance ``lens`` (mm): (xmin, xmax, ymin, ymax, mm_per_pixel).

    Follows BKE_camera_params_compute_viewplane: AUTO uses sensor_width for the larger image side;
    shift is in units of the fitted side.
    """
    if sensor_fit == "AUTO":
        sensor = sensor_width
        fit = "HORIZONTAL" if width >= height else "VERTICAL"
    elif sensor_fit == "HORIZONTAL":
        sensor, fit = sensor_width, "HORIZONTAL"
    else:
        sensor, fit = sensor_height, "VERTICAL"
    fitted_pixels = width if fit == "HORIZONTAL" else height
    pix = sensor / fitted_pixels
    xd, yd = shift_x * fitted_pixels, shift_y * fitted_pixels
    return ((-0.5 * width + xd) * pix, (0.5 * width + xd) * pix,
            (-0.5 * height + yd) * pix, (0.5 * height + yd) * pix, pix)


def orthonormal_matrix(matrix):
    """Camera-to-world matrix without scale (Cycles clears the camera's scale too)."""
    m = np.array(matrix, dtype=np.float64).reshape(4, 4)
    if not np.isfinite(m).all():
        raise ExportError("transform has NaN or infinite values (check its location, rotation and scale)")
    for axis in range(3):
        n = np.linalg.norm(m[:3, axis])
        if not np.isfinite(n) or n < 1e-12:
            raise ExportError("transform has zero scale")
        m[:3, axis] /= n
    return m


def export_camera(cam_obj, resolution, crop=None, *, Camera, warnings):
    """``crop`` = (x0, y0, x1, y1) in full-frame pixels, y counted from the bottom (Blender's border)."""
    if cam_obj is None:
        raise ExportError("Scene has no active camera")
    if cam_obj.type != "CAMERA":
        raise ExportError(f"Object '{cam_obj.name}' is used as camera but is a {cam_obj.type.lower()}")
    data = cam_obj.data
    if data.type != "PERSP":
        raise ExportError(f"Camera '{cam_obj.name}': only perspective cameras are supported "
                          f"(this one is {data.type.lower()})")
    if getattr(data, "dof", None) is not None and data.dof.use_dof:
        warnings.append(f"Camera '{cam_obj.name}': depth of field is ignored (pinhole camera)")
    try:
        matrix = orthonormal_matrix(cam_obj.matrix_world)
    except ExportError as exc:
        raise ExportError(f"Camera '{cam_obj.name}': {exc}") from None
    width, height = resolution
    params = dict(lens=float(data.lens), sensor_width=float(data.sensor_width),
                  sensor_height=float(data.sensor_height), sensor_fit=str(data.sensor_fit),
                  shift_x=float(data.shift_x), shift_y=float(data.shift_y))
    if crop is not None and tuple(crop) != (0, 0, width, height):
        params = crop_params(params, width, height, crop)
    return Camera(matrix=matrix, name=cam_obj.name, **params)


def crop_params(params, width, height, crop):
    """Camera parameters that see only the pixels ``crop`` of the full ``width`` x ``height`` frame."""
    x0, y0, x1, y1 = crop
    xmin, _, ymin, _, pix = frame_window(params["lens"], params["sensor_width"], params["sensor_height"],
                                         params["sensor_fit"], params["shift_x"], params["shift_y"],
                                         width, height)
    w_mm = (x1 - x0) * pix
    cx = xmin + 0.5 * (x0 + x1) * pix
    cy = ymin + 0.5 * (y0 + y1) * pix
    return dict(lens=params["lens"], sensor_width=w_mm, sensor_height=(y1 - y0) * pix,
                sensor_fit="HORIZONTAL", shift_x=cx / w_mm, shift_y=cy / w_mm)


def pixel_directions(camera, width, height):
    """World-space unit directions through the pixel centres, (H, W, 3), row 0 = TOP.

    Reference implementation of Blender's pinhole model used by the tests (not by rendering).
    """
    xmin, xmax, ymin, ymax, pix = frame_window(camera.lens, camera.sensor_width, camera.sensor_height,
                                               camera.sensor_fit, camera.shift_x, camera.shift_y,
                                               width, height)
    xs = xmin + (np.arange(width) + 0.5) * pix
    ys = ymax - (np.arange(height) + 0.5) * pix
    X, Y = np.meshgrid(xs, ys)
    local = np.stack([X, Y, -np.full_like(X, camera.lens)], axis=-1)
    m = np.asarray(camera.matrix, dtype=np.float64)
    d = local @ m[:3, :3].T
    return d / np.linalg.norm(d, axis=-1, keepdims=True)
