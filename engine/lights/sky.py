"""Blender's Sky Texture as Cycles renders it, in NumPy: 5.0's Single Scattering (the Nishita model)
and Multiple Scattering (5.0's default), 3.4's Nishita (its own table layout and kernel, below) and
Preetham (`PreethamSky`, closed form); Hosek / Wilkie is not ported.  For each: the sky's precomputed
table, its lookup per direction, the sun disc, and the bake into an equirectangular image for the
image world (engine/lights/environment.py); docs/world.md "Sky Texture".

Cycles does it in three steps, ported here in float64 with the same constants and quadratures
(Single Scattering described; Multiple Scattering's table below `MultipleScattering`):
1. `single_scattering_table`: at shader compile time a 512 x 256 float table of CIE XYZ radiance
   (Cycles' SKY_single_scattering_precompute_texture): row y >= 128 looks at elevation
   pi/2 ((y - 128) / 128)^2 (more rows near the horizon), column x at azimuth 2 pi x / 512 - pi from
   the sun; single in-scattering along the view ray in 32 segments (Rayleigh, Mie with g = 0.76,
   ozone absorption; 21 wavelengths 380..780 nm), the sun's optical depth by an 8-node
   Gauss-Laguerre quadrature.  Rows below the horizon repeat the horizon row faded by
   (1 - 2.5 sin e)^3 (0 from sin e = 0.4 on).
2. `sun_pixels`: the sun's XYZ radiance at the bottom and the top of its disc (the sun's
   transmittance along those directions over its solid angle).
3. `SkyTexture.radiance`: per direction (Cycles' sky_radiance_nishita): the table looked up with
   linear interpolation and extension Extend at x = fract((-atan2(dy, dx) - pi/2 + rotation) / 2 pi),
   y = sign(e) sqrt(|e| / (pi/2)) / 2 + 1/2; inside the sun disc (above the Earth's edge, seen from
   the altitude) the disc's radiance between bottom and top with limb darkening 0.6, times
   Sun Intensity; XYZ -> the working space's RGB (engine/nodes/converter.py), clamped at 0.

The world in this tracer: `bake` evaluates the sky without the disc at the centres of an
equirectangular image (the image world's importance sampler and MIS follow), and `sun_light` is
the disc as a distant light of the disc's angle with the irradiance the disc gives (its radiance
integrated over the disc), which engine/lights/distant.py samples by its cone.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..nodes.converter import xyz_to_rgb

RAYLEIGH_SCALE = 8e3           # m
MIE_SCALE = 1.2e3              # m
MIE_COEFF = 2e-5               # 1/m
MIE_G = 0.76
EARTH_RADIUS = 6360e3          # m
ATMOSPHERE_RADIUS = 6420e3     # m
STEPS = 32                     # segments of the view ray
TABLE_WIDTH, TABLE_HEIGHT = 512, 256
STEP_LAMBDA = (780 - 380) / 20.0
# Sun irradiance at the top of the atmosphere (W m^-2 nm^-1), 380..780 nm in steps of 20 nm.
IRRADIANCE = np.array([
    1.45756829855592995315, 1.56596305559738380175, 1.65148449067670455293, 1.71496242737209314555,
    1.75797983805020541226, 1.78256407885924539336, 1.79095108475838560302, 1.78541550133410664714,
    1.76815554864306845317, 1.74122069647250410362, 1.70647127164943679389, 1.66556087452739887134,
    1.61993437242451854274, 1.57083597368892080581, 1.51932335059305478886, 1.46628494965214395407,
    1.41245852740172450623, 1.35844961970384092709, 1.30474913844739281998, 1.25174963272610817455,
    1.19975998755420620867])
RAYLEIGH_COEFF = np.array([
    5.424820087636473e-05, 4.418549866505454e-05, 3.635151910165377e-05, 3.017929012024763e-05,
    2.526320226989157e-05, 2.130859310621843e-05, 1.809838025320633e-05, 1.547057129129042e-05,
    1.330284977336850e-05, 1.150184784075764e-05, 9.99557429990163e-06, 8.72799973630707e-06,
    7.65513700977967e-06, 6.74217203751443e-06, 5.96134125832052e-06, 5.29034598065810e-06,
    4.71115687557433e-06, 4.20910481110487e-06, 3.77218381260133e-06, 3.39051255477280e-06,
    3.05591531679811e-06])
OZONE_COEFF = np.array([
    3.25126849861e-09, 5.85395365047e-09, 1.977191155085e-08, 7.309568762914e-08, 2.0084561514287e-07,
    4.0383958096161e-07, 6.3551335912363e-07, 9.6707041180970e-07, 1.54797400424410e-06,
    2.09038647223331e-06, 2.46128056164565e-06, 2.73551299461512e-06, 2.15125863128643e-06,
    1.59051840791988e-06, 1.12356197979857e-06, 7.3527551487574e-07, 4.6450130357806e-07,
    3.3096079921048e-07, 2.2512612292678e-07, 1.4879129266490e-07, 1.6828623364192e-07])
CMF_XYZ = np.array([   # CIE 1931 colour matching functions at the 21 wavelengths
    [0.00136800000, 0.00003900000, 0.00645000100], [0.01431000000, 0.00039600000, 0.06785001000],
    [0.13438000000, 0.00400000000, 0.64560000000], [0.34828000000, 0.02300000000, 1.74706000000],
    [0.29080000000, 0.06000000000, 1.66920000000], [0.09564000000, 0.13902000000, 0.81295010000],
    [0.00490000000, 0.32300000000, 0.27200000000], [0.06327000000, 0.71000000000, 0.07824999000],
    [0.29040000000, 0.95400000000, 0.02030000000], [0.59450000000, 0.99500000000, 0.00390000000],
    [0.91630000000, 0.87000000000, 0.00165000100], [1.06220000000, 0.63100000000, 0.00080000000],
    [0.85444990000, 0.38100000000, 0.00019000000], [0.44790000000, 0.17500000000, 0.00002000000],
    [0.16490000000, 0.06100000000, 0.00000000000], [0.04677000000, 0.01700000000, 0.00000000000],
    [0.01135916000, 0.00410200000, 0.00000000000], [0.00289932700, 0.00104700000, 0.00000000000],
    [0.00069007860, 0.00024920000, 0.00000000000], [0.00016615050, 0.00006000000, 0.00000000000],
    [0.00004150994, 0.00001499000, 0.00000000000]])
# Gauss-Laguerre (8 nodes) on [0, 25] scaled to the ray's length, exp(x) folded into the weights.
QUADRATURE_NODES = np.array([0.006811185292, 0.03614807107, 0.09004346519, 0.1706680068,
                             0.2818362161, 0.4303406404, 0.6296271457, 0.9145252695])
QUADRATURE_WEIGHTS = np.array([0.01750893642, 0.04135477391, 0.06678839063, 0.09507698807,
                               0.1283416365, 0.1707430204, 0.2327233347, 0.3562490486])
LIMB_DARKENING = 0.6


def geographical_to_direction(lat, lon):
    lat, lon = np.asarray(lat, dtype=np.float64), np.asarray(lon, dtype=np.float64)
    return np.stack([np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.sin(lat) + 0 * lon], axis=-1)


def _densities(height):
    """(..., 3) Rayleigh, Mie and ozone density factors at heights above sea level (m)."""
    ozone = np.maximum(0.0, 1.0 - np.abs(height - 25000.0) / 15000.0)
    return np.stack([np.exp(-height / RAYLEIGH_SCALE), np.exp(-height / MIE_SCALE), ozone], axis=-1)


def _to_atmosphere(pos, d):
    """(...,) distance from points pos along unit directions d to the atmosphere's top."""
    b = 2.0 * np.sum(d * pos, axis=-1)
    c = np.sum(pos * pos, axis=-1) - ATMOSPHERE_RADIUS ** 2
    return 0.5 * (-b + np.sqrt(b * b - 4.0 * c))


def _optical_depth(pos, d):
    """(..., 3) Rayleigh, Mie, ozone optical depth factors from pos along d out of the atmosphere."""
    length = _to_atmosphere(pos, d)
    p = pos[..., None, :] + QUADRATURE_NODES[:, None] * (length[..., None] * 1.0)[..., None] * d[..., None, :]
    height = np.linalg.norm(p, axis=-1) - EARTH_RADIUS
    return np.einsum("...qk,q->...k", _densities(height), QUADRATURE_WEIGHTS) * length[..., None]


def _phases(mu):
    rayleigh = (0.1875 / math.pi) * (1.0 + mu * mu)
    g2 = MIE_G * MIE_G
    mie = 3.0 * (1.0 - g2) * (1.0 + mu * mu) / (8.0 * math.pi * (2.0 + g2) * (1.0 + g2 - 2.0 * MIE_G * mu) ** 1.5)
    return rayleigh, mie


def _spectrum_to_xyz(spectrum):
    return (spectrum @ CMF_XYZ) * STEP_LAMBDA


def single_scattering(dirs, sun_dir, altitude, air, aerosol, ozone):
    """(N, 3) XYZ in-scattered radiance along unit view directions dirs (N, 3) from altitude (m)."""
    cam = np.array([0.0, 0.0, EARTH_RADIUS + altitude])
    length = _to_atmosphere(np.broadcast_to(cam, dirs.shape), dirs)
    seg = length / STEPS                                            # (N,)
    t = (np.arange(STEPS) + 0.5)[None, :] * seg[:, None]           # segment middles (N, S)
    p = cam + t[..., None] * dirs[:, None, :]                       # (N, S, 3)
    scale = np.array([air, aerosol, ozone])
    density = scale * _densities(np.linalg.norm(p, axis=-1) - EARTH_RADIUS)     # (N, S, 3)
    depth = np.cumsum(density, axis=1) * seg[:, None, None]        # up to and including the segment
    # The Earth in the way of the sun (Cycles' surface_intersection).
    if sun_dir[2] >= 0.0:
        lit = np.ones(p.shape[:2], dtype=bool)
    else:
        b = 2.0 * np.einsum("nsk,k->ns", p, sun_dir)
        lit = b * b - 4.0 * (np.sum(p * p, axis=-1) - EARTH_RADIUS ** 2) < 0.0
    light = scale * _optical_depth(p, np.broadcast_to(sun_dir, p.shape))         # (N, S, 3)
    total = depth + light
    coeff = np.stack([RAYLEIGH_COEFF, np.full(21, 1.11 * MIE_COEFF), OZONE_COEFF])  # (3, 21)
    attenuation = np.exp(-(total @ coeff))                                          # (N, S, 21)
    rayleigh, mie = _phases(dirs @ sun_dir)                                          # (N,)
    scatter = (density[..., 0:1] * rayleigh[:, None, None] * RAYLEIGH_COEFF
               + density[..., 1:2] * (mie[:, None, None] * MIE_COEFF))               # (N, S, 21)
    spectrum = np.sum(np.where(lit[..., None], attenuation * scatter, 0.0), axis=1) * IRRADIANCE * seg[:, None]
    return _spectrum_to_xyz(spectrum)


def single_scattering_table(sun_elevation, altitude, air, aerosol, ozone,
                            width: int = TABLE_WIDTH, height: int = TABLE_HEIGHT):
    """(height, width, 3) XYZ: Cycles' single-scattering sky table (row 0 is the lowest)."""
    altitude = min(max(altitude, 1.0), 59999.0)
    half_w, half_h = width // 2, height // 2
    sun_dir = geographical_to_direction(sun_elevation, 0.0)
    table = np.zeros((height, width, 3))
    lat = 0.5 * np.pi * (np.arange(half_h, height) / half_h - 1.0) ** 2
    lon = (2.0 * np.pi / width) * np.arange(half_w) - np.pi
    dirs = geographical_to_direction(lat[:, None], lon[None, :]).reshape(-1, 3)
    xyz = np.concatenate([single_scattering(chunk, sun_dir, altitude, air, aerosol, ozone)
                          for chunk in np.array_split(dirs, max(1, len(dirs) // 2048))])
    xyz = xyz.reshape(height - half_h, half_w, 3)
    table[half_h:, :half_w] = xyz
    table[half_h:, half_w:] = xyz[:, ::-1]                           # the sky is mirrored about the sun
    z = np.sin(0.5 * np.pi * (np.arange(half_h) / half_h - 1.0) ** 2)
    fade = np.where(z < 0.4, (1.0 - 2.5 * z) ** 3, 0.0)
    table[:half_h] = table[half_h][None] * fade[:, None, None]
    return table


def sun_pixels(sun_elevation, angular_diameter, altitude, air, aerosol):
    """(bottom, top) XYZ radiance of the sun disc's lowest and highest points (0 below the horizon)."""
    altitude = min(max(altitude, 1.0), 59999.0)
    half = 0.5 * angular_diameter
    solid_angle = 2.0 * np.pi * (1.0 - math.cos(half))
    bottom, top = max(sun_elevation - half, 0.0), max(sun_elevation + half, 0.0)
    if not top > 0.0:
        return np.zeros(3), np.zeros(3)
    cam = np.array([[0.0, 0.0, EARTH_RADIUS + altitude]] * 2)
    depth = _optical_depth(cam, geographical_to_direction(np.array([bottom, top]), 0.0))   # (2, 3)
    tau = np.outer(depth[:, 0] * air, RAYLEIGH_COEFF) + (depth[:, 1] * aerosol * 1.11 * MIE_COEFF)[:, None]
    xyz = _spectrum_to_xyz(IRRADIANCE * np.exp(-tau) / solid_angle)
    return xyz[0], xyz[1]


# -- Blender 5.0's Multiple Scattering (Cycles' sky_multiple_scattering.cpp, after F. Garcia Linan) ----
# Four wavelengths (630, 560, 490, 430 nm) -> XYZ by a fitted matrix, lengths in km; a 256 x 64 table
# of the transmittance to the sun (zenith cosine x altitude, 64 steps each); per table texel 64 steps
# along the view ray (to the atmosphere's top or the ground) of single scattering from the sun through
# that table plus a fitted multiple-scattering term and the ground's (albedo 0.3) second order,
# integrated per step as exp(-extinction dt) (Hillaire's energy-conserving step).  Rows span the
# whole sphere (elevation sign(l) l^2 pi/2), no fade below the horizon.
MS_EARTH_RADIUS = 6371.0
MS_ATMOSPHERE_RADIUS = MS_EARTH_RADIUS + 100.0
MS_STEPS = 64
MS_LUT_X, MS_LUT_Y = 256, 64
MS_G = 0.8
MS_GROUND_ALBEDO = 0.3
SUN_SPECTRAL_IRRADIANCE = np.array([1.679, 1.828, 1.986, 1.307])
MOLECULAR_SCATTERING_BASE = np.array([6.605e-3, 1.067e-2, 1.842e-2, 3.156e-2])
OZONE_ABSORPTION_CROSS_SECTION = np.array([3.472e-25, 3.914e-25, 1.349e-25, 11.03e-27])
OZONE_MEAN_DOBSON = 334.5
AEROSOL_ABSORPTION_CROSS_SECTION = np.array([2.8722e-24, 4.6168e-24, 7.9706e-24, 1.3578e-23])
AEROSOL_SCATTERING_CROSS_SECTION = np.array([1.5908e-22, 1.7711e-22, 2.0942e-22, 2.4033e-22])
AEROSOL_BASE_DENSITY, AEROSOL_BACKGROUND_DENSITY, AEROSOL_HEIGHT_SCALE = 1.3681e20, 2e6, 0.73
SPECTRAL_XYZ = np.array([   # rows: the four wavelengths' X, Y, Z
    [53.386917738564668023, 22.981337506691024754, 0.0],
    [43.904844466369358263, 71.347795700053393866, 0.102506867965741307],
    [1.6137278251608962005, 18.422960591455485011, 31.742921188390805758],
    [20.762668673810577145, 2.3614213523314368527, 110.48009643252140334]])
MS_FIT = 0.02 * np.array([0.217, 0.347, 0.594, 1.0])


def _ray_sphere(pos, d, radius):
    """(...,) Cycles' sky ray_sphere_intersection: the nearer hit ahead, the far one from inside, -1 for none."""
    b = np.sum(pos * d, axis=-1)
    c = np.sum(pos * pos, axis=-1) - radius * radius
    disc = b * b - c
    root = np.sqrt(np.maximum(disc, 0.0))
    t = np.where(disc >= b * b, -b + root, -b - root)
    return np.where(((c > 0.0) & (b > 0.0)) | (disc < 0.0), -1.0, t)


class MultipleScattering:
    """The atmosphere of Blender 5.0's Multiple Scattering sky: (..., 4) spectra in its four
    wavelengths; the transmittance table is made on construction (Cycles' precompute_lut)."""

    def __init__(self, air, aerosol, ozone):
        self.air, self.aerosol, self.ozone = air, aerosol, ozone
        u = np.arange(MS_LUT_X) / (MS_LUT_X - 1)
        v = np.arange(MS_LUT_Y) / (MS_LUT_Y - 1)
        self.lut = self.transmittance(2.0 * u[None, :] - 1.0, v[:, None])          # (Y, X, 4)

    def extinction_and_scattering(self, h):
        """(extinction, molecular scattering, aerosol scattering), each (..., 4), at altitudes h (km)."""
        h = np.asarray(h, dtype=np.float64)[..., None]
        aerosol = AEROSOL_BASE_DENSITY * (np.exp(-h / AEROSOL_HEIGHT_SCALE)
                                          + AEROSOL_BACKGROUND_DENSITY / AEROSOL_BASE_DENSITY) * self.aerosol
        log_h = np.log(np.maximum(h, 1e-4))
        ozone = 3.78547397e20 * np.exp(-(log_h - 3.22261) ** 2 * 5.55555555 - log_h)
        molecular_abs = OZONE_ABSORPTION_CROSS_SECTION * OZONE_MEAN_DOBSON * ozone * self.ozone
        molecular = MOLECULAR_SCATTERING_BASE * np.exp(-0.07771971 * h ** 1.16364243) * self.air
        aerosol_sca = AEROSOL_SCATTERING_CROSS_SECTION * aerosol
        return AEROSOL_ABSORPTION_CROSS_SECTION * aerosol + aerosol_sca + molecular_abs + molecular, molecular, aerosol_sca

    def transmittance(self, cos_theta, normalized_altitude):
        """(..., 4) transmittance to the sun at zenith cosine cos_theta from an altitude in [0, 1] (Cycles' get_transmittance)."""
        cos_theta, normalized_altitude = np.broadcast_arrays(np.asarray(cos_theta, np.float64),
                                                             np.asarray(normalized_altitude, np.float64))
        d = np.stack([-np.sqrt(np.maximum(1.0 - cos_theta ** 2, 0.0)), 0.0 * cos_theta, cos_theta], axis=-1)
        r = MS_EARTH_RADIUS + (MS_ATMOSPHERE_RADIUS - MS_EARTH_RADIUS) * normalized_altitude
        origin = np.stack([0.0 * r, 0.0 * r, r], axis=-1)
        step = _ray_sphere(origin, d, MS_ATMOSPHERE_RADIUS) / MS_STEPS
        total = np.zeros(cos_theta.shape + (4,))
        for i in range(MS_STEPS):
            x = origin + d * ((i + 0.5) * step)[..., None]
            h = np.maximum(np.linalg.norm(x, axis=-1) - MS_EARTH_RADIUS, 0.0)
            total += self.extinction_and_scattering(h)[0] * step[..., None]
        return np.exp(-total)

    def _lut(self, cos_theta, normalized_altitude):
        """Cycles' lookup_transmittance (bilinear, corner-aligned texels, clamped)."""
        x = (MS_LUT_X - 1) * np.clip(cos_theta * 0.5 + 0.5, 0.0, 1.0)
        y = (MS_LUT_Y - 1) * np.clip(normalized_altitude, 0.0, 1.0)
        x1, y1 = x.astype(np.int64), y.astype(np.int64)
        x2, y2 = np.minimum(x1 + 1, MS_LUT_X - 1), np.minimum(y1 + 1, MS_LUT_Y - 1)
        fx, fy = (x - x1)[..., None], (y - y1)[..., None]
        lut = self.lut
        bottom = lut[y1, x1] * (1 - fx) + lut[y1, x2] * fx
        top = lut[y2, x1] * (1 - fx) + lut[y2, x2] * fx
        return bottom * (1 - fy) + top * fy

    def _multiscattering(self, cos_theta, normalized_altitude, distance):
        omega = 2.0 * np.pi * (1.0 - np.sqrt(np.maximum(1.0 - (MS_EARTH_RADIUS / distance) ** 2, 0.0)))
        to_ground = self._lut(cos_theta, 0.0 * cos_theta)
        ground_to_sample = (self._lut(np.ones_like(cos_theta), 0.0 * cos_theta)
                            / self._lut(np.ones_like(cos_theta), normalized_altitude))
        ground = ((1.0 / (4.0 * np.pi)) * omega[..., None] * (MS_GROUND_ALBEDO / np.pi) * to_ground
                  * ground_to_sample * cos_theta[..., None])
        fit = MS_FIT * (1.0 / (1.0 + 5.0 * np.exp(-17.92 * cos_theta)))[..., None]
        return fit + ground

    def inscattering(self, sun_dir, origin, dirs, t_d):
        """(N, 4) in-scattered radiance along unit dirs (N, 3) from origin (3,) over distances t_d (N,)."""
        cos = -(dirs @ sun_dir)
        molecular_phase = (3.0 / 16.0 / np.pi) * (1.0 + cos * cos)
        den = 1.0 + MS_G * MS_G + 2.0 * MS_G * cos
        aerosol_phase = (1.0 / (4.0 * np.pi)) * (1.0 - MS_G * MS_G) / (den * np.sqrt(den))
        dt = t_d / MS_STEPS
        radiance = np.zeros((len(dirs), 4))
        transmittance = np.ones((len(dirs), 4))
        for i in range(MS_STEPS):
            x = origin + dirs * ((i + 0.5) * dt)[:, None]
            r = np.linalg.norm(x, axis=-1)
            h = np.maximum(r - MS_EARTH_RADIUS, 0.0)
            hn = h / (MS_ATMOSPHERE_RADIUS - MS_EARTH_RADIUS)
            sample_cos = (x @ sun_dir) / r
            extinction, molecular, aerosol = self.extinction_and_scattering(h)
            to_sun = self._lut(sample_cos, hn)
            ms = self._multiscattering(sample_cos, hn, r)
            source = SUN_SPECTRAL_IRRADIANCE * (molecular * (molecular_phase[:, None] * to_sun + ms)
                                                + aerosol * (aerosol_phase[:, None] * to_sun + ms))
            step = np.exp(-dt[:, None] * extinction)
            radiance += transmittance * (source - source * step) / np.maximum(extinction, 1e-7)
            transmittance *= step
        return radiance


def multiple_scattering_table(sun_elevation, altitude, air, aerosol, ozone,
                              width: int = TABLE_WIDTH, height: int = TABLE_HEIGHT):
    """(height, width, 3) XYZ: Cycles' Multiple Scattering sky table (row 0 looks straight down,
    row y at elevation sign(l) l^2 pi/2, l = 2 (y + 1/2) / height - 1; column x at azimuth
    2 pi (x + 1/2) / width, the sun at azimuth pi)."""
    atmosphere = MultipleScattering(air, aerosol, ozone)
    altitude = min(max(altitude, 1.0), 99999.0) / 1000.0
    half_w = width // 2
    cos_sun = math.cos(0.5 * math.pi - sun_elevation)
    sun_dir = np.array([-math.sqrt(max(1.0 - cos_sun * cos_sun, 0.0)), 0.0, cos_sun])
    l = 2.0 * (np.arange(height) + 0.5) / height - 1.0
    elevation = np.copysign(l * l, l) * (0.5 * np.pi)
    azimuth = 2.0 * np.pi * (np.arange(half_w) + 0.5) / width
    e, a = np.meshgrid(elevation, azimuth, indexing="ij")
    dirs = np.stack([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)], axis=-1).reshape(-1, 3)
    origin = np.array([0.0, 0.0, MS_EARTH_RADIUS + altitude])
    # The distances in float32 as Cycles computes them: a ray that meets the ground near the viewer
    # loses digits in -b - sqrt(b^2 - c), and Cycles' sky below the horizon carries that.
    o, d32 = np.broadcast_to(origin, dirs.shape).astype(np.float32), dirs.astype(np.float32)
    atmos = _ray_sphere(o, d32, np.float32(MS_ATMOSPHERE_RADIUS)).astype(np.float64)
    ground = _ray_sphere(o, d32, np.float32(MS_EARTH_RADIUS)).astype(np.float64)
    t_d = np.where(ground < 0.0, atmos, ground)
    chunks = np.array_split(np.arange(len(dirs)), max(1, len(dirs) // 4096))
    xyz = np.concatenate([atmosphere.inscattering(sun_dir, origin, dirs[c], t_d[c]) for c in chunks]) @ SPECTRAL_XYZ
    half = xyz.reshape(height, half_w, 3)
    return np.concatenate([half, half[:, ::-1]], axis=1)


def multiple_scattering_sun_pixels(sun_elevation, angular_diameter, altitude, air, aerosol, ozone):
    """(bottom, top) XYZ radiance of the sun disc's lowest and highest points (Multiple Scattering)."""
    atmosphere = MultipleScattering.__new__(MultipleScattering)
    atmosphere.air, atmosphere.aerosol, atmosphere.ozone = air, aerosol, ozone
    altitude = min(max(altitude, 1.0), 99999.0) / 1000.0
    half = 0.5 * angular_diameter
    solid_angle = 2.0 * np.pi * (1.0 - math.cos(half))
    cos = np.cos(0.5 * np.pi - np.array([sun_elevation - half, sun_elevation + half]))
    t = atmosphere.transmittance(cos, np.full(2, altitude / (MS_ATMOSPHERE_RADIUS - MS_EARTH_RADIUS)))
    xyz = (SUN_SPECTRAL_IRRADIANCE * t / solid_angle) @ SPECTRAL_XYZ
    return xyz[0], xyz[1]


# -- Blender 3.4's Nishita (Cycles 3.4's sky_nishita.cpp and kernel) -------------------------------------
# The same single scattering (the node clamps the altitude to [1, 59999] m as 5.0) except a 512 x 128
# table of the upper hemisphere only (row y at elevation (pi/2 + pi/512) (y/128)^2), and the kernel's own
# lookup, ground fade and sun (see SkyTexture._xyz_34).  The sun's optical depth is the 8-node
# Gauss-Laguerre quadrature, as 5.0's: measured in Blender 3.4.1's Cycles (a panoramic render agrees to
# 1e-3; the 16 midpoint segments of the Cycles 3.4.0 sources would be 3 % brighter at the horizon).
NISHITA34_WIDTH, NISHITA34_HEIGHT = 512, 128


def nishita34_table(sun_elevation, altitude, air, dust, ozone,
                    width: int = NISHITA34_WIDTH, height: int = NISHITA34_HEIGHT):
    """(height, width, 3) XYZ: Cycles 3.4's Nishita table (SKY_nishita_skymodel_precompute_texture)."""
    altitude = min(max(altitude, 1.0), 59999.0)
    half_w = width // 2
    sun_dir = geographical_to_direction(sun_elevation, 0.0)
    lat = (0.5 * np.pi + 0.25 * np.pi / height) * (np.arange(height) / height) ** 2
    lon = (2.0 * np.pi / width) * np.arange(half_w) - np.pi
    dirs = geographical_to_direction(lat[:, None], lon[None, :]).reshape(-1, 3)
    xyz = np.concatenate([single_scattering(chunk, sun_dir, altitude, air, dust, ozone)
                          for chunk in np.array_split(dirs, max(1, len(dirs) // 2048))])
    half = xyz.reshape(height, half_w, 3)
    return np.concatenate([half, half[:, ::-1]], axis=1)


def nishita34_sun_pixels(sun_elevation, angular_diameter, altitude, air, dust):
    """(bottom, top) XYZ radiance of the sun disc's lowest and highest points (each at least at the horizon)."""
    altitude = min(max(altitude, 1.0), 59999.0)
    half = 0.5 * angular_diameter
    solid_angle = 2.0 * np.pi * (1.0 - math.cos(half))
    elevations = np.array([max(sun_elevation - half, 0.0), max(sun_elevation + half, 0.0)])
    cam = np.array([[0.0, 0.0, EARTH_RADIUS + altitude]] * 2)
    depth = _optical_depth(cam, geographical_to_direction(elevations, 0.0))
    tau = np.outer(depth[:, 0] * air, RAYLEIGH_COEFF) + (depth[:, 1] * dust * 1.11 * MIE_COEFF)[:, None]
    xyz = _spectrum_to_xyz(IRRADIANCE * np.exp(-tau) / solid_angle)
    return xyz[0], xyz[1]


def earth_intersection_angle(altitude):
    """The angle below the horizon at which the Earth's edge is seen from `altitude` (m)
    (Cycles' SKY_earth_intersection_angle, with its Earth of 6371 km)."""
    return 0.5 * math.pi - math.asin(6371.0 / (6371.0 + altitude / 1000.0))


def wrapped_sun(elevation, rotation):
    """Cycles' SkyTextureNode::simplify_settings: elevation into [-pi/2, pi/2] (the rotation turned
    by pi when it wraps over the zenith), then the kernel's rotation 2 pi - rotation."""
    e, r = math.fmod(elevation, 2.0 * math.pi), rotation
    if abs(e) >= math.pi:
        e -= math.copysign(2.0, e) * math.pi
    if e >= 0.5 * math.pi or e <= -0.5 * math.pi:
        e = math.copysign(math.pi, e) - e
        r += math.pi
    r = math.fmod(r, 2.0 * math.pi)
    if r < 0.0:
        r += 2.0 * math.pi
    return e, 2.0 * math.pi - r


def _lookup_extend(table, x, y):
    """Bilinear lookup with extension Extend, texel centres at (i + 1/2) / size (Cycles' kernel)."""
    h, w = table.shape[:2]
    fx, fy = x * w - 0.5, y * h - 0.5
    ix, iy = np.floor(fx).astype(np.int64), np.floor(fy).astype(np.int64)
    tx, ty = (fx - ix)[:, None], (fy - iy)[:, None]
    x0, x1 = np.clip(ix, 0, w - 1), np.clip(ix + 1, 0, w - 1)
    y0, y1 = np.clip(iy, 0, h - 1), np.clip(iy + 1, 0, h - 1)
    return ((1 - ty) * ((1 - tx) * table[y0, x0] + tx * table[y0, x1])
            + ty * ((1 - tx) * table[y1, x0] + tx * table[y1, x1]))


def _precise_angle(a, b):
    return 2.0 * np.arctan2(np.linalg.norm(a - b, axis=-1), np.linalg.norm(a + b, axis=-1))


@dataclass
class SkyParameters:
    """The Sky Texture node's settings (radians, metres) as Blender stores them."""
    sky_type: str = "SINGLE_SCATTERING"   # or "MULTIPLE_SCATTERING" (5.0's default), "NISHITA" (3.4's)
    sun_elevation: float = math.radians(15.0)
    sun_rotation: float = 0.0
    sun_disc: bool = True
    sun_size: float = 0.009512
    sun_intensity: float = 1.0
    altitude: float = 100.0
    air_density: float = 1.0
    aerosol_density: float = 1.0
    ozone_density: float = 1.0


class SkyTexture:
    """One Sky Texture node as Cycles renders it: `radiance(d)` RGB along world directions."""

    def __init__(self, params: SkyParameters, cycles_version=(5, 0), table_size=None):
        """table_size: Cycles' (512 x 256, 3.4's Nishita 512 x 128); smaller only for fast structural tests."""
        self.params, self.cycles_version = params, tuple(cycles_version)[:2]
        if table_size is None:
            table_size = (NISHITA34_WIDTH, NISHITA34_HEIGHT) if params.sky_type == "NISHITA" else (TABLE_WIDTH, TABLE_HEIGHT)
        self.sun_size = max(params.sun_size, 0.0005)                # Cycles' get_sun_size
        atmosphere = (params.altitude, params.air_density, params.aerosol_density, params.ozone_density)
        self.legacy = params.sky_type == "NISHITA"
        if self.legacy:      # Cycles 3.4: the elevation as it is, the rotation 2 pi - (rotation mod 2 pi)
            r = math.fmod(params.sun_rotation, 2.0 * math.pi)
            self.elevation, self.rotation = params.sun_elevation, 2.0 * math.pi - (r + 2.0 * math.pi if r < 0.0 else r)
            self.table = nishita34_table(self.elevation, *atmosphere, *table_size)
            self.bottom, self.top = nishita34_sun_pixels(self.elevation, self.sun_size, *atmosphere[:3])
            self.sun_direction = geographical_to_direction(self.elevation, self.rotation + 0.5 * math.pi)
            return
        self.elevation, self.rotation = wrapped_sun(params.sun_elevation, params.sun_rotation)
        if params.sky_type == "MULTIPLE_SCATTERING":
            self.table = multiple_scattering_table(self.elevation, *atmosphere, *table_size)
            self.bottom, self.top = multiple_scattering_sun_pixels(self.elevation, self.sun_size, *atmosphere)
        elif params.sky_type == "SINGLE_SCATTERING":
            self.table = single_scattering_table(self.elevation, *atmosphere, *table_size)
            self.bottom, self.top = sun_pixels(self.elevation, self.sun_size, *atmosphere[:3])
        else:
            raise ValueError(f"sky type {params.sky_type!r} is not ported")
        self.earth_angle = -earth_intersection_angle(params.altitude)
        e, r = self.elevation, self.rotation - 0.5 * math.pi
        # spherical_to_direction(e - pi/2, rotation - pi/2)
        self.sun_direction = np.array([-math.cos(e) * math.cos(r), -math.cos(e) * math.sin(r), math.sin(e)])

    def _xyz_34(self, d, sun: bool):
        """Cycles 3.4's sky_radiance_nishita: x = (atan2(dx, dy) + pi + rotation) / 2 pi (less 1 once
        above 1), y = sqrt(e / (pi/2)); inside the disc its radiance replaces the sky's; below the
        horizon the table's lowest row (looked up at y = -0.5) faded by (1 + 2.5 z)^3, 0 below z = -0.4."""
        theta = np.arccos(np.clip(d[:, 2], -1.0, 1.0))
        x = (np.arctan2(d[:, 0], d[:, 1]) + np.pi + self.rotation) / (2.0 * np.pi)
        x = np.where(x > 1.0, x - 1.0, x)
        up = d[:, 2] >= 0.0
        y = np.where(up, np.sqrt(np.maximum((0.5 * np.pi - theta) / (0.5 * np.pi), 0.0)), -0.5)
        xyz = _lookup_extend(self.table, x, y)
        fade = np.where(d[:, 2] < -0.4, 0.0, np.maximum(1.0 + 2.5 * d[:, 2], 0.0) ** 3)
        xyz = np.where(up[:, None], xyz, xyz * fade[:, None])
        if sun and self.params.sun_disc:
            half = 0.5 * self.sun_size
            angle = _precise_angle(d, self.sun_direction[None, :])
            inside = up & (angle < half)
            bottom, top = self.elevation - half, self.elevation + half
            if inside.any() and top > 0.0:
                e = 0.5 * np.pi - theta[inside]
                t = ((e - self.elevation) / self.sun_size + 0.5) if bottom > 0.0 else e / top
                limb = 1.0 - LIMB_DARKENING * (1.0 - np.sqrt(1.0 - (angle[inside] / half) ** 2))
                xyz[inside] = (((1.0 - t)[:, None] * self.bottom + t[:, None] * self.top)
                               * (self.params.sun_intensity * limb)[:, None])
        return xyz

    def _xyz(self, d, sun: bool):
        """(N, 3) XYZ along unit directions d (N, 3): the table, and the disc when `sun`."""
        d = np.asarray(d, dtype=np.float64)
        if self.legacy:
            return self._xyz_34(d, sun)
        theta = np.arccos(np.clip(d[:, 2], -1.0, 1.0))
        phi = np.arctan2(d[:, 1], d[:, 0])
        elevation = 0.5 * np.pi - theta
        x = (-phi - 0.5 * np.pi + self.rotation) / (2.0 * np.pi)
        x = x - np.floor(x)
        y = np.copysign(np.sqrt(np.abs(elevation) * (2.0 / np.pi)), elevation) * 0.5 + 0.5
        xyz = _lookup_extend(self.table, x, y)
        if sun and self.params.sun_disc:
            half = 0.5 * self.sun_size
            angle = _precise_angle(d, self.sun_direction[None, :])
            inside = (angle < half) & (elevation > self.earth_angle)
            if inside.any():
                t = ((elevation[inside] - self.elevation) / self.sun_size + 0.5)[:, None]
                limb = 1.0 - LIMB_DARKENING * (1.0 - np.sqrt(1.0 - (angle[inside] / half) ** 2))
                disc = ((1.0 - t) * self.bottom + t * self.top) * (self.params.sun_intensity * limb)[:, None]
                xyz[inside] += disc
        return xyz

    def radiance(self, d, sun: bool = True):
        """(N, 3) linear RGB along unit world directions d (N, 3), as Cycles' kernel gives it."""
        return np.maximum(xyz_to_rgb(self._xyz(d, sun).T, self.cycles_version).T, 0.0)

    def bake(self, width: int = 2048, height: int = 1024):
        """(height, width, 3) float32 equirectangular image (bottom row first, the image world's
        convention: engine/lights/environment.py) of the sky without the sun disc."""
        from .environment import equirectangular_to_direction
        u = (np.arange(width) + 0.5) / width
        v = (np.arange(height) + 0.5) / height
        d, _ = equirectangular_to_direction(np.tile(u, height), np.repeat(v, width))
        return self.radiance(d.T, sun=False).reshape(height, width, 3).astype(np.float32)

    def sun_irradiance(self, n: int = 64):
        """(3,) RGB irradiance [W/m^2] on a surface facing the sun from its disc (Cycles' disc
        radiance minus the sky under it, integrated over the disc by an n x n midpoint rule); 0
        without a disc or when it is below the Earth's edge."""
        if not self.params.sun_disc:
            return np.zeros(3)
        half = 0.5 * self.sun_size
        s = self.sun_direction
        a = np.cross(s, [0.0, 0.0, 1.0]) if abs(s[2]) < 0.999 else np.cross(s, [1.0, 0.0, 0.0])
        a /= np.linalg.norm(a)
        b = np.cross(s, a)
        cos_max = math.cos(half)
        # uniform over the cone: cos alpha in [cos_max, 1], azimuth in [0, 2 pi)
        c = 1.0 - (np.arange(n) + 0.5) / n * (1.0 - cos_max)
        p = (np.arange(n) + 0.5) / n * 2.0 * np.pi
        c, p = np.meshgrid(c, p, indexing="ij")
        sin = np.sqrt(1.0 - c * c)
        d = (c[..., None] * s + sin[..., None] * (np.cos(p)[..., None] * a + np.sin(p)[..., None] * b)).reshape(-1, 3)
        disc = self.radiance(d, sun=True) - self.radiance(d, sun=False)
        return disc.mean(axis=0) * 2.0 * np.pi * (1.0 - cos_max)


# -- Preetham (Cycles' sky_texture_precompute_preetham and sky_radiance_preetham) ------------------------
def _perez(lam, theta, gamma):
    return ((1.0 + lam[0] * np.exp(lam[1] / np.cos(theta)))
            * (1.0 + lam[2] * np.exp(lam[3] * gamma) + lam[4] * np.cos(gamma) ** 2))


class PreethamSky:
    """The Preetham et al. daylight model of Blender's Sky Texture type PREETHAM (Sun Direction,
    Turbidity; no sun disc): zenith x, y, Y and the Perez coefficients of the sun's zenith angle,
    per direction xyY = zenith x perez(theta, gamma) / perez(0, theta_sun), theta clamped to the horizon
    less 0.001 (the sky below the horizon repeats the horizon's)."""

    sun_size = 0.0

    def __init__(self, sun_direction, turbidity: float, cycles_version=(5, 0)):
        self.cycles_version = tuple(cycles_version)[:2]
        s = np.asarray(sun_direction, dtype=np.float64)
        n = np.linalg.norm(s)
        self.sun_direction = s / n if n > 0 else np.array([0.0, 0.0, 1.0])     # Blender normalises it
        s = self.sun_direction
        self.theta = math.acos(min(max(float(s[2]), -1.0), 1.0))
        self.phi = math.atan2(float(s[0]), float(s[1]))
        t, th = float(turbidity), self.theta
        th2, th3, t2 = th * th, th ** 3, t * t
        chi = (4.0 / 9.0 - t / 120.0) * (math.pi - 2.0 * th)
        zenith_Y = ((4.0453 * t - 4.9710) * math.tan(chi) - 0.2155 * t + 2.4192) * 0.06
        zenith_x = ((0.00166 * th3 - 0.00375 * th2 + 0.00209 * th) * t2
                    + (-0.02903 * th3 + 0.06377 * th2 - 0.03202 * th + 0.00394) * t
                    + (0.11693 * th3 - 0.21196 * th2 + 0.06052 * th + 0.25886))
        zenith_y = ((0.00275 * th3 - 0.00610 * th2 + 0.00317 * th) * t2
                    + (-0.04214 * th3 + 0.08970 * th2 - 0.04153 * th + 0.00516) * t
                    + (0.15346 * th3 - 0.26756 * th2 + 0.06670 * th + 0.26688))
        self.perez_Y = [0.1787 * t - 1.4630, -0.3554 * t + 0.4275, -0.0227 * t + 5.3251,
                        0.1206 * t - 2.5771, -0.0670 * t + 0.3703]
        self.perez_x = [-0.0193 * t - 0.2592, -0.0665 * t + 0.0008, -0.0004 * t + 0.2125,
                        -0.0641 * t - 0.8989, -0.0033 * t + 0.0452]
        self.perez_y = [-0.0167 * t - 0.2608, -0.0950 * t + 0.0092, -0.0079 * t + 0.2102,
                        -0.0441 * t - 1.6537, -0.0109 * t + 0.0529]
        self.zenith = [z / float(_perez(p, 0.0, th)) for z, p in
                       ((zenith_Y, self.perez_Y), (zenith_x, self.perez_x), (zenith_y, self.perez_y))]

    def radiance(self, d, sun: bool = True):
        """(N, 3) linear RGB along unit world directions d (N, 3)."""
        d = np.asarray(d, dtype=np.float64)
        theta = np.arccos(np.clip(d[:, 2], -1.0, 1.0))
        phi = np.arctan2(d[:, 0], d[:, 1])
        cos_gamma = (np.sin(self.theta) * np.sin(theta) * np.cos(phi - self.phi)
                     + np.cos(self.theta) * np.cos(theta))
        gamma = np.arccos(np.clip(cos_gamma, -1.0, 1.0))
        theta = np.minimum(theta, 0.5 * np.pi - 0.001)
        Y = self.zenith[0] * _perez(self.perez_Y, theta, gamma)
        x = self.zenith[1] * _perez(self.perez_x, theta, gamma)
        y = self.zenith[2] * _perez(self.perez_y, theta, gamma)
        safe = np.where(y != 0.0, y, 1.0)
        xyz = np.stack([np.where(y != 0.0, x / safe * Y, 0.0), Y,
                        np.where(y != 0.0, (1.0 - x - y) / safe * Y, 0.0)])
        return np.maximum(xyz_to_rgb(xyz, self.cycles_version).T, 0.0)

    def bake(self, width: int = 2048, height: int = 1024):
        return SkyTexture.bake(self, width, height)

    def sun_irradiance(self, n: int = 64):
        return np.zeros(3)
