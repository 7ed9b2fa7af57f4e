"""The sample tangent-space normal map: a 256 x 256 image of 8 x 8 tiles, each a round dome (a
cos^2 height profile, tilting the normal by up to about 40 degrees at its flank) on a flat ground,
made here rather than downloaded.

`normal_texel(x, y)` is pure Python (Blender 3.4's Python, which has no NumPy, builds the
`normal_map` sample of sample_blends/make_samples.py with it) and gives the colour 0.5 n + 0.5 of the
tangent-space normal n = (-dh/du, -dh/dv, 1) / |...| (x along the UV map's u, y along v, OpenGL's
convention, as Blender's Normal Map node reads it); `normal_pixels()` is the (H, W, 3) float32 array,
row 0 at the bottom (as engine/scene/textures.py keeps images).  The .blend packs it as an 8-bit
Non-Color image.

    python scripts/make_sample_normal_map.py -o bumps.png        # a PNG via OpenImageIO
"""
import math

WIDTH = HEIGHT = 256
TILES = 8                      # domes across and up
DOME_RADIUS = 0.8              # of the half tile: the domes do not touch
DOME_HEIGHT = 0.45             # of the half tile: the steepest slope is pi/2 x 0.45 / 0.8 ~ 0.88 (41 degrees)


def height_gradient(s, t):
    """(dh/ds, dh/dt) of one dome at tile coordinates (s, t) in [-1, 1]^2: h = H cos^2(pi r / 2R)."""
    r = math.hypot(s, t)
    if r >= DOME_RADIUS or r == 0.0:
        return 0.0, 0.0
    a = math.pi * r / (2.0 * DOME_RADIUS)
    dh_dr = -DOME_HEIGHT * math.sin(2.0 * a) * math.pi / (2.0 * DOME_RADIUS)
    return dh_dr * s / r, dh_dr * t / r


def normal_texel(x, y, width=WIDTH, height=HEIGHT):
    """The colour (r, g, b) in [0, 1] of texel (x, y) (y = 0: the bottom row)."""
    tile_w, tile_h = width / TILES, height / TILES
    s = 2.0 * (((x + 0.5) % tile_w) / tile_w) - 1.0
    t = 2.0 * (((y + 0.5) % tile_h) / tile_h) - 1.0
    gs, gt = height_gradient(s, t)
    n = (-gs, -gt, 1.0)
    length = math.sqrt(sum(c * c for c in n))
    return tuple(0.5 * c / length + 0.5 for c in n)


def normal_pixels(width=WIDTH, height=HEIGHT):
    import numpy as np
    return np.array([[normal_texel(x, y, width, height) for x in range(width)] for y in range(height)],
                    dtype=np.float32)


def write(path, width=WIDTH, height=HEIGHT):
    """Write the normal map to `path` (top row first, as image files are; 8 bits) with OpenImageIO."""
    import OpenImageIO as oiio
    pixels = normal_pixels(width, height)[::-1].copy()
    out = oiio.ImageOutput.create(path)
    if out is None:
        raise OSError(oiio.geterror())
    out.open(path, oiio.ImageSpec(width, height, 3, "uint8"))
    out.write_image(pixels)
    out.close()


if __name__ == "__main__":
    import argparse
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("-o", "--output", default="bumps.png")
    args = parser.parse_args()
    write(args.output)
    print(f"wrote {args.output}")
