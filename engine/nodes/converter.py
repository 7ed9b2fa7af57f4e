"""Converter nodes: Combine / Separate XYZ, Color (RGB, HSV, HSL) and 3.4's RGB and HSV nodes, RGB to
BW, Blackbody and Wavelength: Cycles' SVM kernels (svm_node_combine_vector, svm_node_separate_color,
NODE_CONVERT_CF, svm_node_blackbody, svm_node_wavelength) over NumPy arrays.

RGB to BW, Wavelength (and the luminance a colour-to-float link takes) use the scene-linear working
space of the running Blender, as Cycles reads it from OpenColorIO (ShaderManager::init_xyz_transforms):
Blender 4.0+ (its config's Linear Rec.709 and CIE-XYZ D65) gives the XYZ to RGB matrix of the Rec.709
primaries and D65 white, and Y = 0.2126390 R + 0.7151687 G + 0.0721923 B; Blender 3.x's config gives
the inverse of its srgb_to_xyz matrix, Y = 0.2126729 R + 0.7151522 G + 0.0721750 B (both measured in
Cycles: tests/nodes/test_converter.py).  Blackbody's fit is Rec.709, which is the working space.
Blackbody is computed in float32 in Cycles' order (its cubic in t cancels; float64 would differ by up
to 1e-5).
"""
from __future__ import annotations

import numpy as np

from .color import hsl_to_rgb, hsv_to_rgb, rgb_to_hsl, rgb_to_hsv


def _legacy(ctx) -> bool:
    return tuple(getattr(ctx, "cycles_version", (5, 0)))[:2] < (4, 0)


# -- working colour space -------------------------------------------------------------------------------
def _rgb_to_xyz_from_primaries(xy_r, xy_g, xy_b, xy_white):
    def xyz(c):
        return np.array([c[0] / c[1], 1.0, (1.0 - c[0] - c[1]) / c[1]])
    p = np.stack([xyz(xy_r), xyz(xy_g), xyz(xy_b)], axis=1)
    return p * np.linalg.solve(p, xyz(xy_white))


RGB_TO_XYZ = {   # rows: X, Y, Z of linear R, G, B
    "blender4": _rgb_to_xyz_from_primaries((0.64, 0.33), (0.30, 0.60), (0.15, 0.06), (0.3127, 0.3290)),
    "blender3": np.array([[0.4124564, 0.3575761, 0.1804375],      # its config's luts/srgb_to_xyz.spimtx
                          [0.2126729, 0.7151522, 0.0721750],
                          [0.0193339, 0.1191920, 0.9503041]]),
}
XYZ_TO_RGB = {key: np.linalg.inv(m) for key, m in RGB_TO_XYZ.items()}


def _space(cycles_version) -> str:
    return "blender3" if tuple(cycles_version)[:2] < (4, 0) else "blender4"


def luminance_weights(cycles_version=(5, 0)) -> np.ndarray:
    """Cycles' rgb_to_y for the running Blender: the weights of RGB to BW and of colour-to-float links."""
    return RGB_TO_XYZ[_space(cycles_version)][1]


def xyz_to_rgb(xyz, cycles_version=(5, 0)):
    return XYZ_TO_RGB[_space(cycles_version)] @ xyz


# -- Combine / Separate ---------------------------------------------------------------------------------
def combine_xyz_kernel(inputs, props, ctx):
    return {"Vector": np.stack([inputs["X"], inputs["Y"], inputs["Z"]])}


def separate_xyz_kernel(inputs, props, ctx):
    v = inputs["Vector"]
    return {"X": v[0], "Y": v[1], "Z": v[2]}


COMBINE = {"RGB": lambda c: c, "HSV": hsv_to_rgb, "HSL": hsl_to_rgb}
SEPARATE = {"RGB": lambda c: c, "HSV": rgb_to_hsv, "HSL": rgb_to_hsl}


def combine_color_kernel(inputs, props, ctx):
    c = np.stack([inputs["Red"], inputs["Green"], inputs["Blue"]])
    return {"Color": COMBINE[props.get("mode", "RGB")](c)}


def separate_color_kernel(inputs, props, ctx):
    c = SEPARATE[props.get("mode", "RGB")](inputs["Color"])
    return {"Red": c[0], "Green": c[1], "Blue": c[2]}


def combine_rgb_kernel(inputs, props, ctx):          # Blender 3.x
    return {"Image": np.stack([inputs["R"], inputs["G"], inputs["B"]])}


def separate_rgb_kernel(inputs, props, ctx):         # Blender 3.x
    c = inputs["Image"]
    return {"R": c[0], "G": c[1], "B": c[2]}


def combine_hsv_kernel(inputs, props, ctx):          # Blender 3.x
    return {"Color": hsv_to_rgb(np.stack([inputs["H"], inputs["S"], inputs["V"]]))}


def separate_hsv_kernel(inputs, props, ctx):         # Blender 3.x
    c = rgb_to_hsv(inputs["Color"])
    return {"H": c[0], "S": c[1], "V": c[2]}


def rgb_to_bw_kernel(inputs, props, ctx):
    return {"Val": luminance_weights(getattr(ctx, "cycles_version", (5, 0))) @ inputs["Color"]}


# -- Blackbody ------------------------------------------------------------------------------------------
# CIE 1931 colour matching functions x, y, z at 380, 385, ..., 780 nm (Cycles' cie_color_match).
CIE_XYZ = np.array([
    [0.0014, 0.0, 0.0065], [0.0022, 0.0001, 0.0105], [0.0042, 0.0001, 0.0201], [0.0076, 0.0002, 0.0362],
    [0.0143, 0.0004, 0.0679], [0.0232, 0.0006, 0.1102], [0.0435, 0.0012, 0.2074], [0.0776, 0.0022, 0.3713],
    [0.1344, 0.004, 0.6456], [0.2148, 0.0073, 1.0391], [0.2839, 0.0116, 1.3856], [0.3285, 0.0168, 1.623],
    [0.3483, 0.023, 1.7471], [0.3481, 0.0298, 1.7826], [0.3362, 0.038, 1.7721], [0.3187, 0.048, 1.7441],
    [0.2908, 0.06, 1.6692], [0.2511, 0.0739, 1.5281], [0.1954, 0.091, 1.2876], [0.1421, 0.1126, 1.0419],
    [0.0956, 0.139, 0.813], [0.058, 0.1693, 0.6162], [0.032, 0.208, 0.4652], [0.0147, 0.2586, 0.3533],
    [0.0049, 0.323, 0.272], [0.0024, 0.4073, 0.2123], [0.0093, 0.503, 0.1582], [0.0291, 0.6082, 0.1117],
    [0.0633, 0.71, 0.0782], [0.1096, 0.7932, 0.0573], [0.1655, 0.862, 0.0422], [0.2257, 0.9149, 0.0298],
    [0.2904, 0.954, 0.0203], [0.3597, 0.9803, 0.0134], [0.4334, 0.995, 0.0087], [0.5121, 1.0, 0.0057],
    [0.5945, 0.995, 0.0039], [0.6784, 0.9786, 0.0027], [0.7621, 0.952, 0.0021], [0.8425, 0.9154, 0.0018],
    [0.9163, 0.87, 0.0017], [0.9786, 0.8163, 0.0014], [1.0263, 0.757, 0.0011], [1.0567, 0.6949, 0.001],
    [1.0622, 0.631, 0.0008], [1.0456, 0.5668, 0.0006], [1.0026, 0.503, 0.0003], [0.9384, 0.4412, 0.0002],
    [0.8544, 0.381, 0.0002], [0.7514, 0.321, 0.0001], [0.6424, 0.265, 0.0], [0.5419, 0.217, 0.0],
    [0.4479, 0.175, 0.0], [0.3608, 0.1382, 0.0], [0.2835, 0.107, 0.0], [0.2187, 0.0816, 0.0],
    [0.1649, 0.061, 0.0], [0.1212, 0.0446, 0.0], [0.0874, 0.032, 0.0], [0.0636, 0.0232, 0.0],
    [0.0468, 0.017, 0.0], [0.0329, 0.0119, 0.0], [0.0227, 0.0082, 0.0], [0.0158, 0.0057, 0.0],
    [0.0114, 0.0041, 0.0], [0.0081, 0.0029, 0.0], [0.0058, 0.0021, 0.0], [0.0041, 0.0015, 0.0],
    [0.0029, 0.001, 0.0], [0.002, 0.0007, 0.0], [0.0014, 0.0005, 0.0], [0.001, 0.0004, 0.0],
    [0.0007, 0.0002, 0.0], [0.0005, 0.0002, 0.0], [0.0003, 0.0001, 0.0], [0.0002, 0.0001, 0.0],
    [0.0002, 0.0001, 0.0], [0.0001, 0.0, 0.0], [0.0001, 0.0, 0.0], [0.0001, 0.0, 0.0],
    [0.0, 0.0, 0.0],
])
# Cycles' blackbody fit (Rec.709, 800 K to 12000 K): a/t + b t + c for red and green, a cubic for blue,
# one row per temperature band (BLACKBODY_BANDS).
BLACKBODY_R = np.array([
    [1619.19106, -0.00205010916, 5.02995757],
    [2488.45471, -0.00111330907, 3.22621544],
    [3341.43193, -0.000486551192, 1.76486769],
    [4094.61742, -0.000127446582, 0.725731635],
    [4670.28036, 2.91258199e-05, 0.126703442],
    [4595.09185, 2.87495649e-05, 0.15034502],
    [3787.1745, 9.35907826e-06, 0.399075871],
], dtype=np.float32)
BLACKBODY_G = np.array([
    [-488.999748, 0.000604330754, -0.0755807526],
    [-755.994277, 0.000316730098, 0.478306139],
    [-1023.63977, 0.00012022347, 0.936662319],
    [-1265.71316, 4.87340896e-06, 1.27054498],
    [-1425.29332, -4.01150431e-05, 1.43972784],
    [-1175.54822, -2.16378048e-05, 1.30408023],
    [-500.799571, -4.59832026e-06, 1.09098763],
], dtype=np.float32)
BLACKBODY_B = np.array([
    [5.96945309e-11, -4.85742887e-08, -9.70622247e-05, -0.00407936148],
    [2.40430366e-11, 5.55021075e-08, -0.000198503712, 0.0289312858],
    [-1.40949732e-11, 1.89878968e-07, -0.000356632824, 0.0910767778],
    [-3.61460868e-11, 2.84822009e-07, -0.000493211319, 0.15672344],
    [-1.97075738e-11, 1.75359352e-07, -0.000250542825, -0.0222783266],
    [-1.61997957e-13, -1.64216008e-08, 0.000386216271, -0.738077418],
    [6.72650283e-13, -2.73078809e-08, 0.000424098264, -0.752335691],
], dtype=np.float32)
BLACKBODY_BANDS = np.array([965.0, 1167.0, 1449.0, 1902.0, 3315.0, 6365.0], dtype=np.float32)
BLACKBODY_HOT = np.array([0.8262954810464208, 0.9945080501520986, 1.566307710274283])       # t >= 12000 K
BLACKBODY_COLD = np.array([5.413294490189271, -0.20319390035873933, -0.0822535242887164])   # t < 800 K


def blackbody_rec709(t):
    """svm_math_blackbody_color_rec709 (float32, Cycles' operation order), rows (3, N); may be negative."""
    t32 = np.asarray(t, dtype=np.float32)
    band = np.searchsorted(BLACKBODY_BANDS, t32, side="right")
    r, g, b = BLACKBODY_R[band].T, BLACKBODY_G[band].T, BLACKBODY_B[band].T
    with np.errstate(all="ignore"):
        inv = np.float32(1.0) / t32
        rgb = np.stack([r[0] * inv + r[1] * t32 + r[2],
                        g[0] * inv + g[1] * t32 + g[2],
                        ((b[0] * t32 + b[1]) * t32 + b[2]) * t32 + b[3]]).astype(np.float64)
    rgb = np.where(t32 >= 12000.0, BLACKBODY_HOT[:, None], rgb)
    return np.where(t32 < 800.0, BLACKBODY_COLD[:, None], rgb)


def blackbody_kernel(inputs, props, ctx):
    return {"Color": np.maximum(blackbody_rec709(inputs["Temperature"]), 0.0)}


# -- Wavelength -----------------------------------------------------------------------------------------
def wavelength_xyz(nm):
    """svm_math_wavelength_color_xyz: the CIE table interpolated (5 nm steps, 0 outside 380-775 nm)."""
    ii = (np.asarray(nm, dtype=np.float64) - 380.0) * (1.0 / 5.0)
    i = np.trunc(np.nan_to_num(ii, nan=-1.0, posinf=1e9, neginf=-1e9)).astype(np.int64)   # C's (int) cast
    inside = (i >= 0) & (i < 80)
    k = np.clip(i, 0, 79)
    f = ii - k
    xyz = CIE_XYZ[k].T * (1.0 - f) + CIE_XYZ[k + 1].T * f
    return np.where(inside, xyz, 0.0)


def wavelength_kernel(inputs, props, ctx):
    rgb = xyz_to_rgb(wavelength_xyz(inputs["Wavelength"]), getattr(ctx, "cycles_version", (5, 0)))
    return {"Color": np.maximum(rgb * (1.0 / 2.52), 0.0)}


KERNELS = {
    "ShaderNodeCombineXYZ": combine_xyz_kernel,
    "ShaderNodeSeparateXYZ": separate_xyz_kernel,
    "ShaderNodeCombineColor": combine_color_kernel,
    "ShaderNodeSeparateColor": separate_color_kernel,
    "ShaderNodeCombineRGB": combine_rgb_kernel,
    "ShaderNodeSeparateRGB": separate_rgb_kernel,
    "ShaderNodeCombineHSV": combine_hsv_kernel,
    "ShaderNodeSeparateHSV": separate_hsv_kernel,
    "ShaderNodeRGBToBW": rgb_to_bw_kernel,
    "ShaderNodeBlackbody": blackbody_kernel,
    "ShaderNodeWavelength": wavelength_kernel,
}
