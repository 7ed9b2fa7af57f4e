"""The sample environment image: a 128 x 64 equirectangular sky (a blue gradient above a dim ground)
with a small, very bright sun, made here rather than downloaded.

`sky_texel(x, y)` is pure Python (Blender 3.4's Python, which has no NumPy, builds the `hdri` sample
of sample_blends/make_samples.py with it); `sky_pixels()` is the (H, W, 3) float32 array, row 0 at
the bottom (as engine/scene/textures.py keeps images).  Texel centres map to directions as Cycles'
equirectangular projection does (engine/lights/environment.py): u = 0.5 looks along +x, v = 1 up.

    python scripts/make_sample_hdr.py -o sky_sun.hdr        # Radiance .hdr (or .exr) via OpenImageIO
"""
import math

WIDTH, HEIGHT = 128, 64
SUN_DIRECTION = (-0.45, -0.55, 0.70)      # towards the sun: up, to the left of a camera on -y
SUN_RADIUS = math.radians(4.0)            # angular radius of the disk of bright texels
SUN_RADIANCE = (400.0, 370.0, 320.0)
ZENITH, HORIZON, GROUND = (0.18, 0.35, 0.85), (0.75, 0.85, 1.0), (0.20, 0.17, 0.14)


def texel_direction(x, y, width=WIDTH, height=HEIGHT):
    """Unit direction of texel (x, y)'s centre (y = 0: the bottom row)."""
    u, v = (x + 0.5) / width, (y + 0.5) / height
    phi, theta = math.pi - 2.0 * math.pi * u, math.pi * (1.0 - v)
    return (math.sin(theta) * math.cos(phi), math.sin(theta) * math.sin(phi), math.cos(theta))


def sky_texel(x, y, width=WIDTH, height=HEIGHT):
    """Linear RGB radiance of texel (x, y)."""
    d = texel_direction(x, y, width, height)
    n = math.sqrt(sum(c * c for c in SUN_DIRECTION))
    cos_sun = sum(a * b / n for a, b in zip(d, SUN_DIRECTION))
    if cos_sun >= math.cos(SUN_RADIUS):
        return SUN_RADIANCE
    if d[2] < 0.0:
        return GROUND
    t = d[2] ** 0.5
    return tuple(h + (z - h) * t for h, z in zip(HORIZON, ZENITH))


def sky_pixels(width=WIDTH, height=HEIGHT):
    import numpy as np
    return np.array([[sky_texel(x, y, width, height) for x in range(width)] for y in range(height)],
                    dtype=np.float32)


def write(path, width=WIDTH, height=HEIGHT):
    """Write the sky to `path` (top row first, as image files are) with OpenImageIO."""
    import OpenImageIO as oiio
    pixels = sky_pixels(width, height)[::-1].copy()
    out = oiio.ImageOutput.create(path)
    if out is None:
        raise OSError(oiio.geterror())
    out.open(path, oiio.ImageSpec(width, height, 3, "float"))
    out.write_image(pixels)
    out.close()


if __name__ == "__main__":
    import argparse
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("-o", "--output", default="sky_sun.hdr")
    args = parser.parse_args()
    write(args.output)
    print(f"wrote {args.output}")
