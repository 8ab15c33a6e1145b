"""Colour models and colour-space data the shader nodes share, as Cycles computes them:
RGB <-> HSV and HSL over (3, ...) arrays, the scene-linear luminance weights, Cycles' fit of
a black body's colour and the CIE 1931 colour-matching functions the Wavelength node reads.

Every conversion takes and returns (3, ...) arrays (rows R, G, B or H, S, V/L) and works on
any broadcastable shape, so a (3, 1) constant and a (3, n) bundle go through the same code.
"""

from __future__ import annotations

import numpy as np

#: Luminance weights of Linear Rec.709 (Blender's default working space): the Y row of its
#: RGB -> XYZ matrix, as Blender's colour management gives it.  The add-on passes the
#: weights of the file's own working space (``addon.export.node_options``).
REC709_LUMINANCE = (0.21263907849788666, 0.7151690721511841, 0.0721927359700203)

#: CIE XYZ (D65 white) -> Linear Rec.709, as Blender's colour management gives it: Cycles'
#: Wavelength node converts its XYZ colour with the working space's matrix.
XYZ_TO_REC709 = ((3.2409704, -1.5373846, -0.4986115),
                 (-0.9692435, 1.875967, 0.0415547),
                 (0.0556299, -0.2039765, 1.0569712))

#: Cycles' own XYZ -> Rec.709 matrix (Bruce Lindbloom's sRGB figures): Cycles moves a
#: Rec.709 colour (Blackbody's) into another working space through XYZ with it.
CYCLES_XYZ_TO_REC709 = ((3.2404542, -1.5371385, -0.4985314),
                        (-0.9692660, 1.8760108, 0.0415560),
                        (0.0556434, -0.2040259, 1.0572252))

IDENTITY = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))


def apply_matrix(matrix, colour):
    """(3, ...) ``matrix`` (3 x 3 nested tuples) times each colour of a (3, ...) array."""
    colour = np.asarray(colour)
    m = np.asarray(matrix, colour.dtype if colour.dtype.kind == "f" else np.float64)
    return np.tensordot(m, colour, axes=1)


def _channels(colour):
    colour = np.asarray(colour)
    if colour.dtype.kind != "f":
        colour = colour.astype(np.float64)
    return colour[0], colour[1], colour[2]


def rgb_to_hsv(rgb):
    """Cycles' ``rgb_to_hsv``: hue in [0, 1), saturation (max - min) / max, value max."""
    r, g, b = _channels(rgb)
    high = np.maximum(np.maximum(r, g), b)
    low = np.minimum(np.minimum(r, g), b)
    delta = high - low
    with np.errstate(divide="ignore", invalid="ignore"):
        saturation = np.where(high != 0, delta / np.where(high != 0, high, 1), 0)
        chromatic = saturation != 0
        safe_delta = np.where(chromatic, delta, 1)
        cr, cg, cb = (high - r) / safe_delta, (high - g) / safe_delta, (high - b) / safe_delta
    hue = np.where(r == high, cb - cg, np.where(g == high, 2 + cr - cb, 4 + cg - cr)) / 6
    hue = np.where(hue < 0, hue + 1, hue)
    hue = np.where(chromatic, hue, 0)
    return np.stack(np.broadcast_arrays(hue, saturation, high))


def hsv_to_rgb(hsv):
    """Cycles' ``hsv_to_rgb`` (a hue of exactly 1 is 0; a hue outside [0, 1) takes the last
    sector's formula, as in Cycles)."""
    h, s, v = _channels(hsv)
    h = np.where(h == 1, 0, h) * 6
    sector = np.floor(h)
    f = h - sector
    p, q, t = v * (1 - s), v * (1 - s * f), v * (1 - s * (1 - f))
    # Sectors 0-4 as Cycles names them; anything else (5, or a hue outside [0, 1]) is 5.
    sector = np.where((sector >= 0) & (sector <= 4), sector, 5)
    r = np.where(sector == 1, q, np.where(sector == 4, t,
                                          np.where((sector == 2) | (sector == 3), p, v)))
    g = np.where(sector == 0, t, np.where(sector == 3, q, np.where(sector >= 4, p, v)))
    b = np.where(sector <= 1, p, np.where(sector == 2, t, np.where(sector == 5, q, v)))
    grey = s == 0
    return np.stack(np.broadcast_arrays(np.where(grey, v, r), np.where(grey, v, g),
                                        np.where(grey, v, b)))


def rgb_to_hsl(rgb):
    """Cycles' ``rgb_to_hsl`` (lightness capped at 1)."""
    r, g, b = _channels(rgb)
    high = np.maximum(np.maximum(r, g), b)
    low = np.minimum(np.minimum(r, g), b)
    lightness = np.minimum(1, (high + low) / 2)
    delta = high - low
    grey = high == low
    with np.errstate(divide="ignore", invalid="ignore"):
        saturation = np.where(lightness > 0.5, delta / (2 - high - low), delta / (high + low))
        safe_delta = np.where(grey, 1, delta)
        hue = np.where(high == r, (g - b) / safe_delta + np.where(g < b, 6, 0),
                       np.where(high == g, (b - r) / safe_delta + 2, (r - g) / safe_delta + 4))
    hue = np.where(grey, 0, hue) / 6
    saturation = np.where(grey, 0, saturation)
    return np.stack(np.broadcast_arrays(hue, saturation, lightness))


def hsl_to_rgb(hsl):
    """Cycles' ``hsl_to_rgb``."""
    h, s, lightness = _channels(hsl)
    nr = np.clip(np.abs(h * 6 - 3) - 1, 0, 1)
    ng = np.clip(2 - np.abs(h * 6 - 2), 0, 1)
    nb = np.clip(2 - np.abs(h * 6 - 4), 0, 1)
    chroma = (1 - np.abs(2 * lightness - 1)) * s
    return np.stack(np.broadcast_arrays((nr - 0.5) * chroma + lightness,
                                        (ng - 0.5) * chroma + lightness,
                                        (nb - 0.5) * chroma + lightness))


# Cycles' piecewise fit of a black body's colour in Linear Rec.709, normalised to luminance 1
# (kernel/tables.h, adapted from Open Shading Language): R and G are a / T + b T + c, B is a
# cubic in T, in 7 temperature bands whose lower bounds are BLACKBODY_BANDS.
BLACKBODY_BANDS = (965.0, 1167.0, 1449.0, 1902.0, 3315.0, 6365.0)
BLACKBODY_R = ((1.61919106e+03, -2.05010916e-03, 5.02995757e+00),
               (2.48845471e+03, -1.11330907e-03, 3.22621544e+00),
               (3.34143193e+03, -4.86551192e-04, 1.76486769e+00),
               (4.09461742e+03, -1.27446582e-04, 7.25731635e-01),
               (4.67028036e+03, 2.91258199e-05, 1.26703442e-01),
               (4.59509185e+03, 2.87495649e-05, 1.50345020e-01),
               (3.78717450e+03, 9.35907826e-06, 3.99075871e-01))
BLACKBODY_G = ((-4.88999748e+02, 6.04330754e-04, -7.55807526e-02),
               (-7.55994277e+02, 3.16730098e-04, 4.78306139e-01),
               (-1.02363977e+03, 1.20223470e-04, 9.36662319e-01),
               (-1.26571316e+03, 4.87340896e-06, 1.27054498e+00),
               (-1.42529332e+03, -4.01150431e-05, 1.43972784e+00),
               (-1.17554822e+03, -2.16378048e-05, 1.30408023e+00),
               (-5.00799571e+02, -4.59832026e-06, 1.09098763e+00))
BLACKBODY_B = ((5.96945309e-11, -4.85742887e-08, -9.70622247e-05, -4.07936148e-03),
               (2.40430366e-11, 5.55021075e-08, -1.98503712e-04, 2.89312858e-02),
               (-1.40949732e-11, 1.89878968e-07, -3.56632824e-04, 9.10767778e-02),
               (-3.61460868e-11, 2.84822009e-07, -4.93211319e-04, 1.56723440e-01),
               (-1.97075738e-11, 1.75359352e-07, -2.50542825e-04, -2.22783266e-02),
               (-1.61997957e-13, -1.64216008e-08, 3.86216271e-04, -7.38077418e-01),
               (6.72650283e-13, -2.73078809e-08, 4.24098264e-04, -7.52335691e-01))
#: The fit's colour above 12000 K and below 800 K (where it stops: very dim light).
BLACKBODY_HOT = (0.8262954810464208, 0.9945080501520986, 1.566307710274283)
BLACKBODY_COLD = (5.413294490189271, -0.20319390035873933, -0.0822535242887164)


def blackbody_rec709(temperature):
    """(3, ...) the Linear Rec.709 colour of a black body at ``temperature`` kelvin (Cycles'
    fit, unclamped: it is negative outside the Rec.709 gamut)."""
    t = np.asarray(temperature)
    if t.dtype.kind != "f":
        t = t.astype(np.float64)
    band = np.searchsorted(BLACKBODY_BANDS, t, side="right")
    r, g, b = (np.asarray(table, t.dtype)[band] for table in (BLACKBODY_R, BLACKBODY_G,
                                                              BLACKBODY_B))
    with np.errstate(divide="ignore", invalid="ignore"):
        inverse = 1 / t
    colour = np.stack([r[..., 0] * inverse + r[..., 1] * t + r[..., 2],
                       g[..., 0] * inverse + g[..., 1] * t + g[..., 2],
                       ((b[..., 0] * t + b[..., 1]) * t + b[..., 2]) * t + b[..., 3]])
    hot = np.asarray(BLACKBODY_HOT, t.dtype).reshape((3,) + (1,) * t.ndim)
    cold = np.asarray(BLACKBODY_COLD, t.dtype).reshape((3,) + (1,) * t.ndim)
    colour = np.where(t >= 12000, hot, colour)
    return np.where(t < 800, cold, colour)


#: CIE 1931 2-degree colour-matching functions x, y, z from 380 to 780 nm in 5 nm steps, to
#: four decimals (the table Cycles' Wavelength node interpolates).
CIE_1931 = (
    (0.0014, 0.0000, 0.0065), (0.0022, 0.0001, 0.0105), (0.0042, 0.0001, 0.0201),
    (0.0076, 0.0002, 0.0362), (0.0143, 0.0004, 0.0679), (0.0232, 0.0006, 0.1102),
    (0.0435, 0.0012, 0.2074), (0.0776, 0.0022, 0.3713), (0.1344, 0.0040, 0.6456),
    (0.2148, 0.0073, 1.0391), (0.2839, 0.0116, 1.3856), (0.3285, 0.0168, 1.6230),
    (0.3483, 0.0230, 1.7471), (0.3481, 0.0298, 1.7826), (0.3362, 0.0380, 1.7721),
    (0.3187, 0.0480, 1.7441), (0.2908, 0.0600, 1.6692), (0.2511, 0.0739, 1.5281),
    (0.1954, 0.0910, 1.2876), (0.1421, 0.1126, 1.0419), (0.0956, 0.1390, 0.8130),
    (0.0580, 0.1693, 0.6162), (0.0320, 0.2080, 0.4652), (0.0147, 0.2586, 0.3533),
    (0.0049, 0.3230, 0.2720), (0.0024, 0.4073, 0.2123), (0.0093, 0.5030, 0.1582),
    (0.0291, 0.6082, 0.1117), (0.0633, 0.7100, 0.0782), (0.1096, 0.7932, 0.0573),
    (0.1655, 0.8620, 0.0422), (0.2257, 0.9149, 0.0298), (0.2904, 0.9540, 0.0203),
    (0.3597, 0.9803, 0.0134), (0.4334, 0.9950, 0.0087), (0.5121, 1.0000, 0.0057),
    (0.5945, 0.9950, 0.0039), (0.6784, 0.9786, 0.0027), (0.7621, 0.9520, 0.0021),
    (0.8425, 0.9154, 0.0018), (0.9163, 0.8700, 0.0017), (0.9786, 0.8163, 0.0014),
    (1.0263, 0.7570, 0.0011), (1.0567, 0.6949, 0.0010), (1.0622, 0.6310, 0.0008),
    (1.0456, 0.5668, 0.0006), (1.0026, 0.5030, 0.0003), (0.9384, 0.4412, 0.0002),
    (0.8544, 0.3810, 0.0002), (0.7514, 0.3210, 0.0001), (0.6424, 0.2650, 0.0000),
    (0.5419, 0.2170, 0.0000), (0.4479, 0.1750, 0.0000), (0.3608, 0.1382, 0.0000),
    (0.2835, 0.1070, 0.0000), (0.2187, 0.0816, 0.0000), (0.1649, 0.0610, 0.0000),
    (0.1212, 0.0446, 0.0000), (0.0874, 0.0320, 0.0000), (0.0636, 0.0232, 0.0000),
    (0.0468, 0.0170, 0.0000), (0.0329, 0.0119, 0.0000), (0.0227, 0.0082, 0.0000),
    (0.0158, 0.0057, 0.0000), (0.0114, 0.0041, 0.0000), (0.0081, 0.0029, 0.0000),
    (0.0058, 0.0021, 0.0000), (0.0041, 0.0015, 0.0000), (0.0029, 0.0010, 0.0000),
    (0.0020, 0.0007, 0.0000), (0.0014, 0.0005, 0.0000), (0.0010, 0.0004, 0.0000),
    (0.0007, 0.0002, 0.0000), (0.0005, 0.0002, 0.0000), (0.0003, 0.0001, 0.0000),
    (0.0002, 0.0001, 0.0000), (0.0002, 0.0001, 0.0000), (0.0001, 0.0000, 0.0000),
    (0.0001, 0.0000, 0.0000), (0.0001, 0.0000, 0.0000), (0.0000, 0.0000, 0.0000))


def wavelength_xyz(wavelength):
    """(3, ...) CIE XYZ of light of ``wavelength`` nm, linearly interpolated in ``CIE_1931``;
    zero outside the table.  As in Cycles the index is the wavelength's 5 nm step truncated
    toward zero, so 375-380 nm extrapolates the first interval."""
    lam = np.asarray(wavelength)
    if lam.dtype.kind != "f":
        lam = lam.astype(np.float64)
    position = (lam - 380) * (1 / 5)
    with np.errstate(invalid="ignore"):
        step = np.trunc(np.nan_to_num(position, nan=-1.0, posinf=80, neginf=-1.0))
    inside = (step >= 0) & (step < 80)
    index = np.where(inside, step, 0).astype(np.intp)
    table = np.asarray(CIE_1931, lam.dtype)
    low, high = table[index], table[index + 1]
    fraction = (position - index.astype(lam.dtype))[..., None]
    xyz = low + (high - low) * fraction
    xyz = np.where(inside[..., None], xyz, 0)
    return np.moveaxis(xyz, -1, 0)
