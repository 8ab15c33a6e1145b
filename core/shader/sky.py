"""Blender's Sky Texture node as Cycles (Blender 5.0) computes it: the four sky models of its
Type, and the sun disc.

* Multiple Scattering (the default) and Single Scattering are physical atmospheres.  Cycles
  integrates the light the atmosphere scatters towards the viewer once per sky, on the CPU,
  into a 512 x 256 XYZ table over azimuth and elevation (``intern/sky``,
  ``SKY_multiple_scattering_precompute_texture`` / ``SKY_single_scattering_precompute_texture``)
  and its kernel (``kernel/svm/sky.h``) reads that table per direction with a Linear, Extend
  lookup.  Multiple Scattering marches 64 steps through a 100 km atmosphere over an Earth of
  6371 km, four wavelengths, with a transmittance table of 256 x 64 sun angles and altitudes,
  a fit of higher-order scattering and the light the ground (albedo 0.3) sends back up; it
  covers the whole sphere (below the horizon: the ground seen through the air).  Single
  Scattering marches 32 steps over 21 wavelengths (Rayleigh, Mie and ozone, the optical depth
  to the sun by an 8-node Gauss-Laguerre quadrature) above the horizon; the table's rows
  below it hold the horizon's colour, faded to black by 23.6 degrees down.
* The sun disc (both physical models): the sun's own light through the air at the disc's
  lowest and highest points (``SKY_*_precompute_sun``), blended across the disc by elevation
  and darkened towards its limb, added to the sky in XYZ; hidden where the Earth is in front
  of it (``SKY_earth_intersection_angle``).  The path integrator samples it on its own
  (``world_sun``, ``core.environment.SunGuidedMap``), as Cycles does.
* Preetham and Hosek / Wilkie are analytic fits of the sky's radiance against the angle from
  the zenith and the angle from the sun (``Sun Direction``, ``Turbidity``; Hosek / Wilkie
  ``Ground Albedo`` too), evaluated per direction.

Everything is computed as Cycles does it, in float32 and in the same order of operations
(the tables' integrations included: Blender builds ``intern/sky`` without fused multiply-adds
or fast math), and the transcendental functions rounded from float64 as glibc's float
functions are; the colours come out within float rounding of Cycles' own.  A table is
computed once per process for each combination of the options it depends on (``sky_table``:
about a second of CPU), so that a program carries only the node's options (plain numbers) to
the worker processes.

The node's Color is in the file's working colour space (``xyz_to_scene``: Cycles converts
the models' XYZ with the working space's matrix and clamps negative values to 0).  Its
unlinked Vector is the Generated coordinate, for the world the direction a ray escapes in.
Cycles first wraps Sun Elevation into [-90, 90] degrees and Sun Rotation into [0, 360)
(``SkyTextureNode::simplify_settings``), and so does ``sun_position``.
"""

from __future__ import annotations

import functools

import numpy as np

from .colour_models import XYZ_TO_REC709, apply_matrix
from .hosek_wilkie import hosek_wilkie_state
from .images import ImageData, image_from_pixels, lookup
from .registry import COLOR, VECTOR, node
from .textures import blockwise, float32_vector, mapped, texture_mapping_transform

SKY_TYPES = ("SINGLE_SCATTERING", "MULTIPLE_SCATTERING", "PREETHAM", "HOSEK_WILKIE")
#: The size of Cycles' table of the physical skies (``SkyLoader::load_metadata``).
TABLE_WIDTH, TABLE_HEIGHT = 512, 256
#: The smallest sun Cycles draws (``SkyTextureNode::get_sun_size``), radians.
MIN_SUN_SIZE = 0.0005

_F32 = np.float32
_PI = _F32(3.1415926535897932)
_HALF_PI = _F32(1.5707963267948966)
_TWO_PI = _F32(6.2831853071795864)
_ONE_OVER_PI = _F32(0.3183098861837067)
_ONE_OVER_FOUR_PI = _F32(0.0795774715459476)
_ONE_OVER_TWO_PI = _F32(0.159154943091895335768883763372514362)
_TWO_OVER_PI = _F32(0.636619772367581343075535053490057448)
_ZERO, _HALF, _ONE, _TWO = _F32(0.0), _F32(0.5), _F32(1.0), _F32(2.0)


def _libm(function):
    """A float function as glibc's float version computes it: in float64, rounded once."""
    def rounded(*arguments):
        return np.asarray(function(*(np.asarray(a, np.float64) for a in arguments))).astype(
            _F32)
    return rounded


_exp, _log, _pow, _sin, _cos, _tan = (_libm(f) for f in (np.exp, np.log, np.power, np.sin,
                                                          np.cos, np.tan))
_acos, _asin, _atan2 = _libm(np.arccos), _libm(np.arcsin), _libm(np.arctan2)


def _floats(*values):
    return [np.asarray(value, _F32) for value in values]


# --------------------------------------------------------------------------------------------
# The sun's position, as Cycles wraps it.

def sun_position(elevation: float, rotation: float) -> tuple:
    """(elevation, rotation) as Cycles passes them to the sky (``simplify_settings``): the
    elevation wrapped into [-pi/2, pi/2] (past the zenith, the sun comes down on the other
    side, its rotation turned half a turn), the rotation into [0, 2 pi) and then reversed
    (2 pi - rotation): the sun shines from (cos e sin r, cos e cos r, sin e) of the node's
    own elevation e and rotation r.  float32 scalars."""
    elevation, rotation = _F32(elevation), _F32(rotation)
    elevation = _F32(np.fmod(elevation, _TWO_PI))
    if abs(elevation) >= _PI:
        elevation = _F32(elevation - _F32(np.copysign(_TWO, elevation)) * _PI)
    if elevation >= _HALF_PI or elevation <= -_HALF_PI:
        elevation = _F32(_F32(np.copysign(_PI, elevation)) - elevation)
        rotation = _F32(rotation + _PI)
    rotation = _F32(np.fmod(rotation, _TWO_PI))
    if rotation < 0:
        rotation = _F32(rotation + _TWO_PI)
    return elevation, _F32(_TWO_PI - rotation)


# --------------------------------------------------------------------------------------------
# Multiple Scattering (``intern/sky/source/sky_multiple_scattering.cpp``), distances in km.

_EARTH_RADIUS = _F32(6371.0)
_ATMOSPHERE_THICKNESS = _F32(100.0)
_ATMOSPHERE_RADIUS = _EARTH_RADIUS + _ATMOSPHERE_THICKNESS
_TRANSMITTANCE_STEPS = 64
_IN_SCATTERING_STEPS = 64
_TRANSMITTANCE_WIDTH, _TRANSMITTANCE_HEIGHT = 256, 64
#: Rays of the table integrated at once.
_RAYS_PER_BLOCK = 8192


def _spectral(*values):
    """(4,) float32: one value per sampled wavelength (spectral quantities are (n, 4))."""
    return np.array(values, _F32)


#: Sampled at 630, 560, 490 and 430 nm.
_SUN_IRRADIANCE = _spectral(1.679, 1.828, 1.986, 1.307)
_MOLECULAR_SCATTERING = _spectral(6.605e-3, 1.067e-2, 1.842e-2, 3.156e-2)
_OZONE_CROSS_SECTION = _spectral(3.472e-25, 3.914e-25, 1.349e-25, 11.03e-27)
_OZONE_MEAN_DOBSON = _F32(334.5)
_AEROSOL_ABSORPTION = _spectral(2.8722e-24, 4.6168e-24, 7.9706e-24, 1.3578e-23)
_AEROSOL_SCATTERING = _spectral(1.5908e-22, 1.7711e-22, 2.0942e-22, 2.4033e-22)
_AEROSOL_BASE_DENSITY = _F32(1.3681e20)
_AEROSOL_BACKGROUND_RATIO = _F32(2e6) / _AEROSOL_BASE_DENSITY
_AEROSOL_HEIGHT_SCALE = _F32(0.73)
_GROUND_ALBEDO = _F32(0.3)
_G = _F32(0.8)                                  # the aerosols' anisotropy
_SQUARED_G = _G * _G
_RAYLEIGH_PHASE_SCALE = _F32(3.0 / 16.0) * _ONE_OVER_PI
#: The four wavelengths' contributions to X, Y and Z: (3, 4).
_SPECTRAL_XYZ = np.array([[53.386917738564668023, 43.904844466369358263,
                           1.6137278251608962005, 20.762668673810577145],
                          [22.981337506691024754, 71.347795700053393866,
                           18.422960591455485011, 2.3614213523314368527],
                          [0.0, 0.102506867965741307, 31.742921188390805758,
                           110.48009643252140334]], _F32)
_MULTIPLE_SCATTERING_FIT = _F32(0.02) * _spectral(0.217, 0.347, 0.594, 1.0)


def _ray_sphere_from_axis(height, direction_z, radius):
    """Blender's ``ray_sphere_intersection`` for rays from (0, 0, height) along unit
    directions whose z is ``direction_z``: the distance to the sphere of ``radius`` about
    the origin (the far side from inside it), -1 where the ray misses it."""
    b = height * direction_z
    c = height * height - radius * radius
    d = b * b - c
    root = np.sqrt(np.maximum(d, _ZERO))
    distance = np.where(d >= b * b, -b + root, -b - root)
    return np.where(((c > 0) & (b > 0)) | (d < 0), _F32(-1.0), distance)


class _Atmosphere:
    """The multiple-scattering atmosphere of given air, aerosol and ozone densities, and
    its table of transmittance towards the sun (``precompute_table``)."""

    def __init__(self, air: float, aerosol: float, ozone: float):
        self.air, self.aerosol, self.ozone = _F32(air), _F32(aerosol), _F32(ozone)

    def extinction_and_scattering(self, altitude):
        """(extinction, molecular scattering, aerosol scattering), each (n, 4), at altitudes
        (n,) in km."""
        aerosol = (_AEROSOL_BASE_DENSITY * (_exp(-altitude / _AEROSOL_HEIGHT_SCALE)
                                            + _AEROSOL_BACKGROUND_RATIO)) * self.aerosol
        aerosol = aerosol[:, None]
        log_h = _log(np.maximum(altitude, _F32(1e-4)))
        offset = log_h - _F32(3.22261)
        ozone = _F32(3.78547397e20) * _exp(-(offset * offset) * _F32(5.55555555) - log_h)
        molecular_absorption = ((_OZONE_CROSS_SECTION * _OZONE_MEAN_DOBSON) * ozone[:, None]
                                ) * self.ozone
        molecular_scattering = (_MOLECULAR_SCATTERING * _exp(
            _F32(-0.07771971) * _pow(altitude, _F32(1.16364243)))[:, None]) * self.air
        aerosol_scattering = _AEROSOL_SCATTERING * aerosol
        extinction = (_AEROSOL_ABSORPTION * aerosol + aerosol_scattering + molecular_absorption
                      + molecular_scattering)
        return extinction, molecular_scattering, aerosol_scattering

    def transmittance(self, cos_theta, normalized_altitude):
        """(n, 4) transmittance from altitudes (fractions of the atmosphere's thickness)
        towards the sun at cos_theta from the zenith, marched to the top of the atmosphere
        (``get_transmittance``)."""
        cos_theta, normalized_altitude = _floats(cos_theta, normalized_altitude)
        sun_x = -np.sqrt(_ONE - cos_theta * cos_theta)
        height = _EARTH_RADIUS + normalized_altitude * (_ATMOSPHERE_RADIUS - _EARTH_RADIUS)
        step = _ray_sphere_from_axis(height, cos_theta, _ATMOSPHERE_RADIUS) / _F32(
            _TRANSMITTANCE_STEPS)
        depth = np.zeros(np.shape(cos_theta) + (4,), _F32)
        for i in range(_TRANSMITTANCE_STEPS):
            t = _F32(i + 0.5) * step
            x, z = sun_x * t, height + cos_theta * t
            altitude = np.maximum(np.sqrt(x * x + z * z) - _EARTH_RADIUS, _ZERO)
            extinction, _, _ = self.extinction_and_scattering(altitude)
            depth += extinction * step[:, None]
        return _exp(-depth)

    def precompute_table(self):
        """The transmittance over the sun's cos_theta in [-1, 1] (256 columns) and the
        normalized altitude in [0, 1] (64 rows): (64 x 256, 4), row by row."""
        x = np.arange(_TRANSMITTANCE_WIDTH, dtype=_F32) / _F32(_TRANSMITTANCE_WIDTH - 1)
        y = np.arange(_TRANSMITTANCE_HEIGHT, dtype=_F32) / _F32(_TRANSMITTANCE_HEIGHT - 1)
        self.table = self.transmittance(np.tile(x * _TWO - _ONE, _TRANSMITTANCE_HEIGHT),
                                        np.repeat(y, _TRANSMITTANCE_WIDTH))
        # The last column (the sun at the zenith), which the ground's light reads.
        self.zenith_column = np.ascontiguousarray(
            self.table[_TRANSMITTANCE_WIDTH - 1::_TRANSMITTANCE_WIDTH])
        self.ground_to_sun = self.lookup_to_sun(np.zeros(1, _F32))

    def _lerp_columns(self, first, x):
        """(n, 4) the table interpolated between columns at positions x (n,) >= 0 of the
        rows starting at entries ``first``."""
        x1 = x.astype(np.int64)
        x2 = np.minimum(x1 + 1, _TRANSMITTANCE_WIDTH - 1)
        fx = (x - x1.astype(_F32))[:, None]
        a, b = self.table.take(first + x1, axis=0), self.table.take(first + x2, axis=0)
        return a + fx * (b - a)

    @staticmethod
    def _rows(normalized_altitude):
        """(y1, y2, fy): the two rows around altitudes (n,) and the weight of the second."""
        y = _F32(_TRANSMITTANCE_HEIGHT - 1) * np.clip(normalized_altitude, _ZERO, _ONE)
        y1 = y.astype(np.int64)
        return y1, np.minimum(y1 + 1, _TRANSMITTANCE_HEIGHT - 1), (y - y1.astype(_F32))[:, None]

    def lookup_transmittance(self, cos_theta, normalized_altitude):
        x = _F32(_TRANSMITTANCE_WIDTH - 1) * np.clip(cos_theta * _HALF + _HALF, _ZERO, _ONE)
        y1, y2, fy = self._rows(normalized_altitude)
        bottom = self._lerp_columns(y1 * _TRANSMITTANCE_WIDTH, x)
        top = self._lerp_columns(y2 * _TRANSMITTANCE_WIDTH, x)
        return bottom + fy * (top - bottom)

    def lookup_to_sun(self, normalized_altitude):
        """(n, 4) the zenith column at altitudes (n,)."""
        y1, y2, fy = self._rows(normalized_altitude)
        a, b = self.zenith_column.take(y1, axis=0), self.zenith_column.take(y2, axis=0)
        return a + fy * (b - a)

    def higher_orders(self, cos_theta, normalized_altitude, distance):
        """(n, 4) the fit of light scattered more than once, and the sunlight the ground
        reflects, reaching points at ``distance`` from the Earth's centre
        (``lookup_multiscattering``)."""
        ratio = _EARTH_RADIUS / distance
        omega = _TWO_PI * (_ONE - np.sqrt(np.maximum(_ONE - ratio * ratio, _ZERO)))
        to_ground = self._lerp_columns(
            0, _F32(_TRANSMITTANCE_WIDTH - 1) * np.clip(cos_theta * _HALF + _HALF, _ZERO, _ONE))
        ground_to_sample = self.ground_to_sun / self.lookup_to_sun(normalized_altitude)
        ground = (((((_ONE_OVER_FOUR_PI * omega) * (_GROUND_ALBEDO * _ONE_OVER_PI))[:, None]
                    * to_ground) * ground_to_sample) * cos_theta[:, None])
        fit = _MULTIPLE_SCATTERING_FIT * (_ONE / (_ONE + _F32(5.0) * _exp(
            _F32(-17.92) * cos_theta)))[:, None]
        return fit + ground

    def inscattering(self, sun_x, sun_z, height, dx, dy, dz, distance):
        """(n, 4) the light scattered towards rays from (0, 0, height) along unit directions
        (dx, dy, dz) (n,) over ``distance`` (n,), the sun towards (sun_x, 0, sun_z)
        (``get_inscattering``: Hillaire's energy-conserving integration of each step)."""
        cos_theta = (-dx) * sun_x + (-dz) * sun_z
        molecular_phase = (_RAYLEIGH_PHASE_SCALE * (_ONE + cos_theta * cos_theta))[:, None]
        den = (_ONE + _SQUARED_G) + (_TWO * _G) * cos_theta
        aerosol_phase = ((_ONE_OVER_FOUR_PI * (_ONE - _SQUARED_G)) / (den * np.sqrt(den)))[
            :, None]
        step = distance / _F32(_IN_SCATTERING_STEPS)
        minus_step = (-step)[:, None]
        radiance = np.zeros((len(dx), 4), _F32)
        transmittance = np.ones((len(dx), 4), _F32)
        for i in range(_IN_SCATTERING_STEPS):
            t = _F32(i + 0.5) * step
            x, y, z = dx * t, dy * t, height + dz * t
            centre_distance = np.sqrt(x * x + y * y + z * z)
            altitude = np.maximum(centre_distance - _EARTH_RADIUS, _ZERO)
            normalized = altitude / _ATMOSPHERE_THICKNESS
            sample_cos = (x / centre_distance) * sun_x + (z / centre_distance) * sun_z
            extinction, molecular, aerosol = self.extinction_and_scattering(altitude)
            to_sun = self.lookup_transmittance(sample_cos, normalized)
            more = self.higher_orders(sample_cos, normalized, centre_distance)
            source = _SUN_IRRADIANCE * (molecular * (molecular_phase * to_sun + more)
                                        + aerosol * (aerosol_phase * to_sun + more))
            step_transmittance = _exp(minus_step * extinction)
            integrated = (source - source * step_transmittance) / np.maximum(
                extinction, _F32(1e-7))
            radiance = radiance + transmittance * integrated
            transmittance *= step_transmittance
        return radiance


def _spectral_to_xyz(spectrum):
    """(3, n) XYZ of (n, 4) spectral radiance, summed wavelength by wavelength."""
    xyz = np.zeros((3, len(spectrum)), _F32)
    for i in range(4):
        xyz += _SPECTRAL_XYZ[:, i:i + 1] * spectrum[:, i]
    return xyz


def _multiple_scattering_altitude(altitude: float):
    return np.clip(_F32(altitude), _ONE, _F32(99999.0)) / _F32(1000.0)


def _multiple_scattering_table(sun_elevation, altitude, air, aerosol, ozone):
    """(256, 512, 3) XYZ over azimuth (columns, mirrored about the sun's) and elevation
    (rows, bottom up, l = 2 v - 1 at sign(l) l^2 x 90 degrees: more rows near the horizon)."""
    atmosphere = _Atmosphere(air, aerosol, ozone)
    atmosphere.precompute_table()
    height = _EARTH_RADIUS + _multiple_scattering_altitude(altitude)
    cos_zenith = _cos(_HALF_PI - _F32(sun_elevation))
    sun_x = -np.sqrt(_ONE - cos_zenith * cos_zenith)
    half = TABLE_WIDTH // 2
    column = np.tile(np.arange(half), TABLE_HEIGHT)
    row = np.repeat(np.arange(TABLE_HEIGHT), half)
    u = (column.astype(_F32) + _HALF) / _F32(TABLE_WIDTH)
    v = (row.astype(_F32) + _HALF) / _F32(TABLE_HEIGHT)
    azimuth = _TWO_PI * u
    l = v * _TWO - _ONE
    elevation = _F32(np.copysign(l * l, l)) * _HALF_PI
    cos_elevation = _cos(elevation)
    dx, dy, dz = cos_elevation * _cos(azimuth), cos_elevation * _sin(azimuth), _sin(elevation)
    atmosphere_distance = _ray_sphere_from_axis(height, dz, _ATMOSPHERE_RADIUS)
    ground_distance = _ray_sphere_from_axis(height, dz, _EARTH_RADIUS)
    distance = np.where(ground_distance < 0, atmosphere_distance, ground_distance)
    xyz = np.empty((3, len(dx)), _F32)
    for first in range(0, len(dx), _RAYS_PER_BLOCK):   # temporaries that stay in cache
        rays = slice(first, first + _RAYS_PER_BLOCK)
        xyz[:, rays] = _spectral_to_xyz(atmosphere.inscattering(
            sun_x, cos_zenith, height, dx[rays], dy[rays], dz[rays], distance[rays]))
    return _mirrored(xyz.T.reshape(TABLE_HEIGHT, half, 3))


def _mirrored(left):
    """The full table from its left half: Cycles computes azimuths up to 180 degrees and
    mirrors them."""
    return np.ascontiguousarray(np.concatenate([left, left[:, ::-1]], axis=1))


def _multiple_scattering_sun(sun_elevation, sun_size, altitude, air, aerosol, ozone):
    """(bottom, top): (3,) XYZ radiance of the sun at its disc's lowest and highest points
    (``SKY_multiple_scattering_precompute_sun``)."""
    half = _F32(sun_size) / _TWO
    solid_angle = _TWO_PI * (_ONE - _cos(half))
    normalized = _multiple_scattering_altitude(altitude) / _ATMOSPHERE_THICKNESS
    elevation = np.array([_F32(sun_elevation) - half, _F32(sun_elevation) + half], _F32)
    cos_theta = _cos(_HALF_PI - elevation)
    transmittance = _Atmosphere(air, aerosol, ozone).transmittance(
        cos_theta, np.full(2, normalized, _F32))
    xyz = _spectral_to_xyz(_SUN_IRRADIANCE * transmittance / solid_angle)
    return xyz[:, 0], xyz[:, 1]


# --------------------------------------------------------------------------------------------
# Single Scattering (``intern/sky/source/sky_single_scattering.cpp``), distances in metres.

_SS_EARTH_RADIUS = _F32(6360e3)
_SS_ATMOSPHERE_RADIUS = _F32(6420e3)
_RAYLEIGH_SCALE = _F32(8e3)
_MIE_SCALE = _F32(1.2e3)
_MIE_COEFFICIENT = _F32(2e-5)
_MIE_EXTINCTION = _F32(1.11) * _MIE_COEFFICIENT
_MIE_G = _F32(0.76)
_SQUARED_MIE_G = _MIE_G * _MIE_G
_SS_STEPS = 32
#: 21 wavelengths from 380 to 780 nm, 20 nm apart: the sun's irradiance at the top of the
#: atmosphere (W m^-2 nm^-1), Rayleigh scattering and ozone absorption (m^-1), and the CIE
#: 1931 colour-matching functions (x, y, z).
_STEP_LAMBDA = _F32(20.0)
_IRRADIANCE = np.array([
    1.45756829855592995315, 1.56596305559738380175, 1.65148449067670455293,
    1.71496242737209314555, 1.75797983805020541226, 1.78256407885924539336,
    1.79095108475838560302, 1.78541550133410664714, 1.76815554864306845317,
    1.74122069647250410362, 1.70647127164943679389, 1.66556087452739887134,
    1.61993437242451854274, 1.57083597368892080581, 1.51932335059305478886,
    1.46628494965214395407, 1.41245852740172450623, 1.35844961970384092709,
    1.30474913844739281998, 1.25174963272610817455, 1.19975998755420620867], _F32)[:, None]
_RAYLEIGH_COEFFICIENT = np.array([
    0.00005424820087636473, 0.00004418549866505454, 0.00003635151910165377,
    0.00003017929012024763, 0.00002526320226989157, 0.00002130859310621843,
    0.00001809838025320633, 0.00001547057129129042, 0.00001330284977336850,
    0.00001150184784075764, 0.00000999557429990163, 0.00000872799973630707,
    0.00000765513700977967, 0.00000674217203751443, 0.00000596134125832052,
    0.00000529034598065810, 0.00000471115687557433, 0.00000420910481110487,
    0.00000377218381260133, 0.00000339051255477280, 0.00000305591531679811], _F32)[:, None]
_OZONE_COEFFICIENT = np.array([
    0.00000000325126849861, 0.00000000585395365047, 0.00000001977191155085,
    0.00000007309568762914, 0.00000020084561514287, 0.00000040383958096161,
    0.00000063551335912363, 0.00000096707041180970, 0.00000154797400424410,
    0.00000209038647223331, 0.00000246128056164565, 0.00000273551299461512,
    0.00000215125863128643, 0.00000159051840791988, 0.00000112356197979857,
    0.00000073527551487574, 0.00000046450130357806, 0.00000033096079921048,
    0.00000022512612292678, 0.00000014879129266490, 0.00000016828623364192], _F32)[:, None]
_CMF_XYZ = np.array([
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
    [0.00004150994, 0.00001499000, 0.00000000000]], _F32)
#: Gauss-Laguerre quadrature of the optical depth along a ray (8 nodes, scaled so that the
#: last falls inside the atmosphere; the weights include exp(x)).
_QUADRATURE_NODES = np.array([0.006811185292, 0.03614807107, 0.09004346519, 0.1706680068,
                              0.2818362161, 0.4303406404, 0.6296271457, 0.9145252695], _F32)
_QUADRATURE_WEIGHTS = np.array([0.01750893642, 0.04135477391, 0.06678839063, 0.09507698807,
                                0.1283416365, 0.1707430204, 0.2327233347, 0.3562490486], _F32)


def _length(x, y, z):
    return np.sqrt(x * x + y * y + z * z)


def _densities(height):
    """(Rayleigh, Mie, ozone) densities at heights (m) above sea level; the ozone's layer
    (a tent 15 km either side of 25 km) in double precision, as Blender writes it."""
    ozone = np.maximum(0.0, 1.0 - np.abs(height.astype(np.float64) - 25000.0) / 15000.0)
    return (_exp(-height / _RAYLEIGH_SCALE), _exp(-height / _MIE_SCALE), ozone.astype(_F32))


def _atmosphere_exit(px, py, pz, dx, dy, dz):
    """The distance from points (px, py, pz) inside the atmosphere along unit directions to
    its top (``atmosphere_intersection``)."""
    b = _F32(-2.0) * (dx * -px + dy * -py + dz * -pz)
    c = (px * px + py * py + pz * pz) - _SS_ATMOSPHERE_RADIUS * _SS_ATMOSPHERE_RADIUS
    return (-b + np.sqrt(b * b - _F32(4.0) * c)) / _TWO


def _optical_depth(px, py, pz, dx, dy, dz):
    """(Rayleigh, Mie, ozone) optical depths (their densities' integrals) from points along
    unit directions to the top of the atmosphere (``ray_optical_depth``)."""
    t = _atmosphere_exit(px, py, pz, dx, dy, dz)
    ex, ey, ez = px + dx * t, py + dy * t, pz + dz * t
    length = _length(px - ex, py - ey, pz - ez)
    sx, sy, sz = length * dx, length * dy, length * dz
    depth = [np.zeros(np.shape(length), _F32) for _ in range(3)]
    for node_, weight in zip(_QUADRATURE_NODES, _QUADRATURE_WEIGHTS):
        height = _length(px + node_ * sx, py + node_ * sy, pz + node_ * sz) - _SS_EARTH_RADIUS
        for total, density in zip(depth, _densities(height)):
            total += density * weight
    return [total * length for total in depth]


def _spectrum_to_xyz(spectrum):
    """(3, n) XYZ of (21, n) spectra."""
    xyz = np.zeros((3, spectrum.shape[1]), _F32)
    for i in range(len(_CMF_XYZ)):
        xyz += _CMF_XYZ[i][:, None] * spectrum[i]
    return xyz * _STEP_LAMBDA


def _single_scattering(dx, dy, dz, sun, height, density_scale):
    """(21, n) spectral radiance scattered once towards the camera at (0, 0, height) along
    unit directions (n,), the sun along (3,) ``sun`` (``single_scattering``)."""
    t = _atmosphere_exit(_ZERO, _ZERO, height, dx, dy, dz)
    ex, ey, ez = _ZERO + dx * t, _ZERO + dy * t, height + dz * t
    length = _length(_ZERO - ex, _ZERO - ey, height - ez)
    segment_length = length / _F32(_SS_STEPS)
    sx, sy, sz = segment_length * dx, segment_length * dy, segment_length * dz
    mu = dx * sun[0] + dy * sun[1] + dz * sun[2]
    rayleigh_phase = (_F32(0.1875) * _ONE_OVER_PI) * (_ONE + mu * mu)
    mie_phase = ((_F32(3.0) * (_ONE - _SQUARED_MIE_G)) * (_ONE + mu * mu)) / (
        ((_F32(8.0) * _PI) * (_TWO + _SQUARED_MIE_G))
        * _pow(_ONE + _SQUARED_MIE_G - (_TWO * _MIE_G) * mu, _F32(1.5)))
    n = len(dx)
    spectrum = np.zeros((len(_IRRADIANCE), n), _F32)
    depth = [np.zeros(n, _F32) for _ in range(3)]
    px, py, pz = _ZERO + _HALF * sx, _ZERO + _HALF * sy, height + _HALF * sz
    sun_below = sun[2] < 0
    for _ in range(_SS_STEPS):
        altitude = _length(px, py, pz) - _SS_EARTH_RADIUS
        density = [scale * value for scale, value in zip(density_scale, _densities(altitude))]
        for total, value in zip(depth, density):
            total += segment_length * value
        lit = slice(None)
        if sun_below:   # where the Earth is not in the way of the sun (``surface_intersection``)
            b = _F32(-2.0) * (sun[0] * -px + sun[1] * -py + sun[2] * -pz)
            c = (px * px + py * py + pz * pz) - _SS_EARTH_RADIUS * _SS_EARTH_RADIUS
            lit = np.flatnonzero(~(b * b - _F32(4.0) * c >= 0))
        light = _optical_depth(px[lit], py[lit], pz[lit],
                               *(np.full(len(px[lit]), s, _F32) for s in sun))
        total = [d[lit] + scale * l for d, scale, l in zip(depth, density_scale, light)]
        attenuation = _exp(-((total[0] * _RAYLEIGH_COEFFICIENT + total[1] * _MIE_EXTINCTION)
                             + total[2] * _OZONE_COEFFICIENT))
        scattered = (rayleigh_phase[lit] * (density[0][lit] * _RAYLEIGH_COEFFICIENT)
                     + mie_phase[lit] * (density[1][lit] * _MIE_COEFFICIENT)) + _ZERO
        spectrum[:, lit] += ((attenuation * scattered) * _IRRADIANCE) * segment_length[lit]
        px, py, pz = px + sx, py + sy, pz + sz
    return spectrum


def _single_scattering_altitude(altitude: float):
    return np.clip(_F32(altitude), _ONE, _F32(59999.0))


def _geographical_direction(latitude, longitude):
    cos_latitude = _cos(latitude)
    return cos_latitude * _cos(longitude), cos_latitude * _sin(longitude), _sin(latitude)


def _single_scattering_table(sun_elevation, altitude, air, aerosol, ozone):
    """(256, 512, 3) XYZ: rows from the horizon (128) up at latitude 90 (y / 128 - 1)^2
    degrees, columns at longitude 360 x / 512 - 180 (mirrored); the rows below the horizon
    its row again, faded to black as (1 - 2.5 sin(latitude))^3 of their mirrored latitude."""
    height = _SS_EARTH_RADIUS + _single_scattering_altitude(altitude)
    sun = np.array(_geographical_direction(_F32(sun_elevation), _ZERO), _F32)
    half_width, half_height = TABLE_WIDTH // 2, TABLE_HEIGHT // 2
    row = np.arange(TABLE_HEIGHT)
    offset = row.astype(_F32) / _F32(half_height) - _ONE
    latitude = _HALF_PI * (offset * offset)
    above = row[half_height:]
    longitude = (_TWO_PI / _F32(TABLE_WIDTH)) * np.arange(half_width).astype(_F32) - _PI
    dx, dy, dz = _geographical_direction(np.repeat(latitude[above], half_width),
                                         np.tile(longitude, len(above)))
    spectrum = _single_scattering(dx, dy, dz, sun, height,
                                  (_F32(air), _F32(aerosol), _F32(ozone)))
    left = np.empty((TABLE_HEIGHT, half_width, 3), _F32)
    left[above] = _spectrum_to_xyz(spectrum).T.reshape(len(above), half_width, 3)
    rise = _sin(latitude[:half_height])
    base = _ONE - rise * _F32(2.5)
    fade = np.where(rise < _F32(0.4), (base * base) * base, _ZERO)
    left[:half_height] = left[half_height] * fade[:, None, None]
    return _mirrored(left)


def _single_scattering_sun(sun_elevation, sun_size, altitude, air, aerosol):
    """(bottom, top) (3,) XYZ radiance of the sun at its disc's lowest and highest points,
    each clamped to the horizon; black once the whole disc has set."""
    half = _F32(sun_size) / _TWO
    solid_angle = _TWO_PI * (_ONE - _cos(half))
    elevation = np.maximum(np.array([_F32(sun_elevation) - half,
                                     _F32(sun_elevation) + half], _F32), _ZERO)
    if elevation[1] <= 0:
        return np.zeros(3, _F32), np.zeros(3, _F32)
    height = _SS_EARTH_RADIUS + _single_scattering_altitude(altitude)
    direction = _geographical_direction(elevation, _ZERO)
    depth = _optical_depth(np.zeros(2, _F32), np.zeros(2, _F32), np.full(2, height, _F32),
                           *direction)
    spectrum = _IRRADIANCE * _exp(-((_RAYLEIGH_COEFFICIENT * depth[0]) * _F32(air)
                                    + (_MIE_EXTINCTION * depth[1]) * _F32(aerosol))) / solid_angle
    xyz = _spectrum_to_xyz(spectrum)
    return xyz[:, 0], xyz[:, 1]


# --------------------------------------------------------------------------------------------
# The physical skies' tables and sun, computed once per process for each set of options.

@functools.lru_cache(maxsize=8)
def sky_table(sky_type: str, sun_elevation: float, altitude: float, air_density: float,
              aerosol_density: float, ozone_density: float) -> ImageData:
    """The table of a physical sky (Cycles' sky image: XYZ, 512 x 256, row 0 at the bottom)
    for its sun elevation (as ``sun_position`` wraps it) and atmosphere."""
    if sky_type == "MULTIPLE_SCATTERING":
        xyz = _multiple_scattering_table(sun_elevation, altitude, air_density, aerosol_density,
                                         ozone_density)
    else:
        xyz = _single_scattering_table(sun_elevation, altitude, air_density, aerosol_density,
                                       ozone_density)
    return image_from_pixels(f"{sky_type.lower().replace('_', ' ')} sky", xyz)


@functools.lru_cache(maxsize=32)
def sun_pixels(sky_type: str, sun_elevation: float, sun_size: float, altitude: float,
               air_density: float, aerosol_density: float, ozone_density: float) -> tuple:
    """(bottom, top): (3,) XYZ radiance at the lowest and highest points of the sun's disc
    of diameter ``sun_size`` (Single Scattering has no ozone in the sun's light)."""
    if sky_type == "MULTIPLE_SCATTERING":
        return _multiple_scattering_sun(sun_elevation, sun_size, altitude, air_density,
                                        aerosol_density, ozone_density)
    return _single_scattering_sun(sun_elevation, sun_size, altitude, air_density,
                                  aerosol_density)


def earth_angle(altitude: float):
    """How far below the horizon the Earth's edge is seen from ``altitude`` (m), negative
    radians (``SKY_earth_intersection_angle``): the sun disc is hidden below it."""
    return -(_HALF_PI - _asin(_EARTH_RADIUS / (_EARTH_RADIUS + _F32(altitude) / _F32(1000.0))))


def sun_diameter(size: float, disc: bool = True):
    """The sun's angular diameter as Cycles draws it, -1 without a disc."""
    return max(_F32(size), _F32(MIN_SUN_SIZE)) if disc else _F32(-1.0)


# --------------------------------------------------------------------------------------------
# The kernel: the sky seen along each direction (``kernel/svm/sky.h``).

def _spherical(direction):
    """(theta from +Z, phi = atan2(y, x)) of (3, n) unit directions (Cycles'
    ``direction_to_spherical``)."""
    x, y, z = direction
    return _acos(np.clip(z, -_ONE, _ONE)), _atan2(y, x)


def _xyz_to_rgb(xyz, xyz_to_scene):
    return np.maximum(apply_matrix(xyz_to_scene, xyz), _ZERO)


def _physical_sky(direction, table: ImageData, sun, xyz_to_scene):
    """(3, n) the physical sky's colour along (3, n) float32 directions: the sun's disc
    (where it is not behind the Earth) over the table's sky, in XYZ, then to RGB clamped
    at 0.  sun: (bottom, top, elevation, rotation, diameter (-1: no disc), intensity,
    earth angle)."""
    bottom, top, elevation, rotation, diameter, intensity, earth = sun
    theta, phi = _spherical(direction)
    dir_elevation = _HALF_PI - theta
    u = (-phi - _HALF_PI + rotation) * _ONE_OVER_TWO_PI
    u -= np.floor(u)
    v = np.copysign(np.sqrt(np.abs(dir_elevation) * _TWO_OVER_PI), dir_elevation)
    xyz, _ = lookup(table, u, v * _HALF + _HALF, "Linear", "EXTEND", False, _F32)
    if diameter >= 0:
        sun_theta, sun_phi = elevation - _HALF_PI, rotation - _HALF_PI
        sin_theta = _sin(sun_theta)
        sun_direction = np.array([sin_theta * _cos(sun_phi), sin_theta * _sin(sun_phi),
                                  _cos(sun_theta)], _F32)[:, None]
        angle = _TWO * _atan2(_length(*(direction - sun_direction)),
                              _length(*(direction + sun_direction)))
        half = diameter * _HALF
        inside = np.flatnonzero((angle < half) & (dir_elevation > earth))
        if len(inside):
            t = (dir_elevation[inside] - elevation) / diameter + _HALF
            ratio = angle[inside] / half
            limb = _ONE - _F32(0.6) * (_ONE - np.sqrt(_ONE - ratio * ratio))
            disc = bottom[:, None] + t * (top - bottom)[:, None]
            xyz[:, inside] += (disc * intensity) * limb
    return _xyz_to_rgb(xyz, xyz_to_scene)


# --------------------------------------------------------------------------------------------
# Preetham and Hosek / Wilkie.

def _perez(config, theta, gamma):
    cos_gamma = _cos(gamma)
    return (_ONE + config[0] * _exp(config[1] / _cos(theta))) * (
        (_ONE + config[2] * _exp(config[3] * gamma)) + config[4] * cos_gamma * cos_gamma)


def _sun_angles(direction) -> tuple:
    """(theta, phi) of the normalized Sun Direction as Cycles computes them at compile time:
    acos(z), atan2(x, y)."""
    x, y, z = (_F32(c) for c in direction)
    length = np.sqrt(x * x + y * y + z * z)
    x, y, z = x / length, y / length, z / length
    return _acos(z), _atan2(x, y)


def preetham_parameters(sun_direction, turbidity: float) -> tuple:
    """(theta, phi, (Y, x, y) zenith values, (3, 5) Perez coefficients of Y, x and y) of
    Preetham's model (``sky_texture_precompute_preetham``)."""
    theta, phi = _sun_angles(sun_direction)
    t = _F32(turbidity)
    theta2 = theta * theta
    theta3 = theta2 * theta
    t2 = t * t
    chi = (_F32(4.0 / 9.0) - t / _F32(120.0)) * (_PI - _TWO * theta)
    zenith_luminance = ((_F32(4.0453) * t - _F32(4.9710)) * _tan(chi) - _F32(0.2155) * t
                        + _F32(2.4192)) * _F32(0.06)

    def chromaticity(a, b, c):
        return ((a[0] * theta3 + a[1] * theta2 + a[2] * theta) * t2
                + (b[0] * theta3 + b[1] * theta2 + b[2] * theta + b[3]) * t
                + (c[0] * theta3 + c[1] * theta2 + c[2] * theta + c[3]))

    f = _F32
    zenith_x = chromaticity((f(0.00166), f(-0.00375), f(0.00209)),
                            (f(-0.02903), f(0.06377), f(-0.03202), f(0.00394)),
                            (f(0.11693), f(-0.21196), f(0.06052), f(0.25886)))
    zenith_y = chromaticity((f(0.00275), f(-0.00610), f(0.00317)),
                            (f(-0.04214), f(0.08970), f(-0.04153), f(0.00516)),
                            (f(0.15346), f(-0.26756), f(0.06670), f(0.26688)))
    slopes = np.array([[0.1787, -0.3554, -0.0227, 0.1206, -0.0670],
                       [-0.0193, -0.0665, -0.0004, -0.0641, -0.0033],
                       [-0.0167, -0.0950, -0.0079, -0.0441, -0.0109]], _F32)
    offsets = np.array([[-1.4630, 0.4275, 5.3251, -2.5771, 0.3703],
                        [-0.2592, 0.0008, 0.2125, -0.8989, 0.0452],
                        [-0.2608, 0.0092, 0.2102, -1.6537, 0.0529]], _F32)
    config = slopes * t + offsets
    zenith = np.array([zenith_luminance, zenith_x, zenith_y], _F32)
    zenith = zenith / np.array([_perez(row, _ZERO, theta) for row in config], _F32)
    return theta, phi, zenith, config


def _sun_gamma(direction, sun_theta, sun_phi):
    """(theta clamped to just above the horizon, gamma: the angle to the sun) of (3, n)
    directions (``sky_angle_between``)."""
    theta, phi = _spherical(direction)
    phi = -phi + _HALF_PI
    cos_psi = (_sin(theta) * _sin(sun_theta)) * _cos(sun_phi - phi) + _cos(theta) * _cos(
        sun_theta)
    gamma = _acos(np.clip(cos_psi, -_ONE, _ONE))
    return np.minimum(theta, _HALF_PI - _F32(0.001)), gamma


def _preetham_sky(direction, parameters, xyz_to_scene):
    sun_theta, sun_phi, zenith, config = parameters
    theta, gamma = _sun_gamma(direction, sun_theta, sun_phi)
    luminance = zenith[0] * _perez(config[0], theta, gamma)
    x = zenith[1] * _perez(config[1], theta, gamma)
    y = zenith[2] * _perez(config[2], theta, gamma)
    safe_y = np.where(y != 0, y, _ONE)
    big_x = np.where(y != 0, (x / safe_y) * luminance, _ZERO)
    big_z = np.where((y != 0) & (luminance != 0), (_ONE - x - y) / safe_y * luminance, _ZERO)
    return _xyz_to_rgb(np.stack([big_x, luminance, big_z]), xyz_to_scene)


def hosek_parameters(sun_direction, turbidity: float, ground_albedo: float) -> tuple:
    """(theta, phi, (3,) radiances, (3, 9) configurations) of Hosek and Wilkie's model
    (``sky_texture_precompute_hosek``): the sun clamped to the horizon, the turbidity to
    [1, 10] (Blender's property stops at 1: Cycles would read outside its data below)."""
    theta, phi = _sun_angles(sun_direction)
    theta = np.clip(theta, _ZERO, _HALF_PI)
    configurations, radiances = hosek_wilkie_state(
        float(np.clip(_F32(turbidity), _ONE, _F32(10.0))), float(_F32(ground_albedo)),
        float(_HALF_PI - theta))
    return theta, phi, radiances.astype(_F32), configurations.astype(_F32)


def _hosek_sky(direction, parameters, xyz_to_scene):
    sun_theta, sun_phi, radiances, configurations = parameters
    theta, gamma = _sun_gamma(direction, sun_theta, sun_phi)
    cos_theta, cos_gamma = _cos(theta), _cos(gamma)
    ray = cos_gamma * cos_gamma
    zenith = np.sqrt(cos_theta)
    xyz = []
    for c, radiance in zip(configurations, radiances):
        mie = (_ONE + ray) / _pow(_ONE + c[8] * c[8] - _TWO * c[8] * cos_gamma, _F32(1.5))
        value = (_ONE + c[0] * _exp(c[1] / (cos_theta + _F32(0.01)))) * (
            c[2] + c[3] * _exp(c[4] * gamma) + c[5] * ray + c[6] * mie + c[7] * zenith)
        xyz.append(value * radiance)
    return _xyz_to_rgb(np.stack(xyz), xyz_to_scene) * (_TWO_PI / _F32(683.0))


# --------------------------------------------------------------------------------------------
# The node.

def _check(name: str, value):
    if not np.isfinite(value):
        raise ValueError(f"Sky Texture: {name} must be a finite number, got {value!r}")
    return float(value)


@node("ShaderNodeTexSky", inputs=(("Vector", VECTOR),), outputs=(("Color", COLOR),),
      options=("sky_type", "sun_disc", "sun_size", "sun_intensity", "sun_elevation",
               "sun_rotation", "altitude", "air_density", "aerosol_density", "ozone_density",
               "sun_direction", "turbidity", "ground_albedo", "texture_mapping",
               "xyz_to_scene"),
      implicit={"Vector": "generated"})
def sky_texture(points, vector, *, sky_type="MULTIPLE_SCATTERING", sun_disc=True,
                sun_size=0.009512, sun_intensity=1.0, sun_elevation=np.radians(15.0),
                sun_rotation=0.0, altitude=100.0, air_density=1.0, aerosol_density=1.0,
                ozone_density=1.0, sun_direction=(0.0, 0.0, 1.0), turbidity=2.2,
                ground_albedo=0.3, texture_mapping=None, xyz_to_scene=XYZ_TO_REC709):
    """Blender's Sky Texture (module docstring): the sky's colour along the Vector (the
    world's direction), in the working space of ``xyz_to_scene`` (its XYZ -> RGB matrix)."""
    if sky_type not in SKY_TYPES:
        raise ValueError(f"Sky Texture: sky_type must be one of {', '.join(SKY_TYPES)}, got "
                         f"{sky_type!r}")
    numbers = {name: _check(name, value) for name, value in (
        ("sun_size", sun_size), ("sun_intensity", sun_intensity),
        ("sun_elevation", sun_elevation), ("sun_rotation", sun_rotation),
        ("altitude", altitude), ("air_density", air_density),
        ("aerosol_density", aerosol_density), ("ozone_density", ozone_density),
        ("turbidity", turbidity), ("ground_albedo", ground_albedo))}
    if sky_type == "PREETHAM":
        kernel = functools.partial(_preetham_sky, parameters=preetham_parameters(
            sun_direction, numbers["turbidity"]), xyz_to_scene=xyz_to_scene)
    elif sky_type == "HOSEK_WILKIE":
        kernel = functools.partial(_hosek_sky, parameters=hosek_parameters(
            sun_direction, numbers["turbidity"], numbers["ground_albedo"]),
            xyz_to_scene=xyz_to_scene)
    else:
        elevation, rotation = sun_position(numbers["sun_elevation"], numbers["sun_rotation"])
        atmosphere = (numbers["altitude"], numbers["air_density"], numbers["aerosol_density"],
                      numbers["ozone_density"])
        table = sky_table(sky_type, float(elevation), *atmosphere)
        diameter = sun_diameter(numbers["sun_size"], bool(sun_disc))
        bottom = top = np.zeros(3, _F32)
        if diameter >= 0:
            bottom, top = sun_pixels(sky_type, float(elevation), float(diameter), *atmosphere)
        sun = (bottom, top, elevation, rotation, diameter, _F32(numbers["sun_intensity"]),
               earth_angle(numbers["altitude"]))
        kernel = functools.partial(_physical_sky, table=table, sun=sun,
                                   xyz_to_scene=xyz_to_scene)
    direction = mapped(float32_vector(vector), texture_mapping)
    return blockwise(lambda d: (kernel(d),), [direction], (COLOR,), cost=16)


# --------------------------------------------------------------------------------------------
# The sun as a light.

def world_sun(program):
    """(direction (3,) float64 unit, half angle) of the sun disc a world ``program`` draws,
    for the integrator to sample it on its own as Cycles does (``use_sun_guiding``); None
    unless exactly one physical Sky Texture with its disc on reads the Generated coordinate
    (Blender 5 lets no link into a physical sky's Vector; were one to, the sun could be
    anywhere, and Cycles samples the map alone).  The direction is the kernel's sun undone
    through the node's Texture Mapping."""
    from .program import Coordinate
    suns = []
    for instruction in program.instructions:
        if instruction.node != "ShaderNodeTexSky":
            continue
        options = dict(instruction.options)
        if (options.get("sky_type", "MULTIPLE_SCATTERING") not in (
                "SINGLE_SCATTERING", "MULTIPLE_SCATTERING")
                or not options.get("sun_disc", True)):
            continue
        if instruction.arguments[0] != Coordinate("generated"):
            return None
        elevation, rotation = sun_position(options.get("sun_elevation", np.radians(15.0)),
                                           options.get("sun_rotation", 0.0))
        longitude = float(rotation) + np.pi / 2
        direction = np.array([np.cos(elevation) * np.cos(longitude),
                              np.cos(elevation) * np.sin(longitude), np.sin(elevation)])
        matrix = texture_mapping_transform(options.get("texture_mapping"))
        if matrix is not None:
            direction = np.linalg.solve(matrix[:, :3].astype(np.float64), direction)
        suns.append((direction / np.linalg.norm(direction),
                     float(sun_diameter(options.get("sun_size", 0.009512))) / 2))
    return suns[0] if len(suns) == 1 else None


def without_sun_discs(program):
    """``program`` with every Sky Texture's sun disc off: the world Cycles bakes its map of
    when it samples the sun on its own (the kernel leaves the disc out of that bake)."""
    from dataclasses import replace
    instructions = tuple(
        replace(instruction, options=tuple(sorted({**dict(instruction.options),
                                                   "sun_disc": False}.items())))
        if instruction.node == "ShaderNodeTexSky" else instruction
        for instruction in program.instructions)
    return replace(program, instructions=instructions)
