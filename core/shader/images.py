"""Image textures as Cycles samples them: the image data the core holds, the texel lookups
(interpolation, extension, UDIM tiles, alpha, sRGB decoding) and the Image Texture and
Environment Texture nodes.

The add-on reads each Blender image once per export into an ``ImageData`` (its colour
conversion done there, ``addon.export.images``); every material and world that uses the
image holds that one object, and its texels reach worker processes once, through the
render's shared memory (an array that big goes out of band: ``core.workers``).

A lookup follows Cycles' CPU kernel (``kernel/device/cpu/image.h``, ``kernel/svm/image.h``):

* texel (i, j) covers [i, i + 1) / width x [j, j + 1) / height of the unit square, row 0 at
  v = 0 (the bottom row, as Blender's ``Image.pixels`` and Cycles store images);
* Closest reads the texel under (u, v); Linear blends the 2 x 2 texels around it and Cubic
  the 4 x 4 with the uniform cubic B-spline weights (which smooth, and do not pass through
  the texels' values); Smart is Cubic, as on Cycles' CPU;
* Repeat wraps texel indices, Extend clamps them, Mirror reflects them, and Clip reads
  transparent black outside the image (so a Linear or Cubic lookup fades out across the
  border);
* byte images in the sRGB colour space keep their sRGB-encoded bytes and are decoded after
  interpolation, as Cycles' byte textures are (``NODE_IMAGE_COMPRESS_AS_SRGB``): a Linear
  lookup halfway between black and white gives srgb_to_linear(0.5) = 0.214, not 0.5;
* colours are stored premultiplied by alpha (Cycles associates alpha when it loads an image,
  unless it is Non-Color, Channel Packed or None); the Color output stays premultiplied
  unless the node's Alpha output is used, in which case it is divided back out
  (``NODE_IMAGE_ALPHA_UNASSOCIATE``), as in Cycles.

Everything is whole-array: a lookup of n points computes n texel indices per tap and gathers
them from the one texel array; no loop runs over points and no image is copied.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..colour import srgb_to_linear
from ..validation import value_text
from .registry import COLOR, FLOAT, VECTOR, node

INTERPOLATIONS = ("Closest", "Linear", "Cubic", "Smart")
EXTENSIONS = ("REPEAT", "EXTEND", "CLIP", "MIRROR")
PROJECTIONS = ("FLAT", "BOX", "SPHERE", "TUBE")
ENVIRONMENT_PROJECTIONS = ("EQUIRECTANGULAR", "MIRROR_BALL")
ALPHA_MODES = ("STRAIGHT", "PREMUL", "CHANNEL_PACKED", "NONE")
TEXEL_TYPES = (np.dtype(np.uint8), np.dtype(np.float16), np.dtype(np.float32))

#: What Cycles returns for an image it cannot read, and where a UV lies in no UDIM tile
#: (``TEX_IMAGE_MISSING_R/G/B/A``): magenta, opaque.
MISSING_RGBA = (1.0, 0.0, 1.0, 1.0)
#: The first UDIM tile's number; tile 1001 + 10 v + u covers [u, u + 1) x [v, v + 1), u < 10.
UDIM_FIRST = 1001
UDIM_COLUMNS = 10


@dataclass(frozen=True)
class Tile:
    """One UDIM tile of an image: its number, size, and the row of ``ImageData.texels``
    holding its first texel."""

    number: int
    width: int
    height: int
    offset: int


@dataclass(frozen=True, eq=False)
class ImageData:
    """One image as the core samples it.

    name: the Blender image's name (for messages).
    texels: (N, C) read-only texels, C = 1 (grey), 3 (RGB) or 4 (RGBA); uint8 (bytes,
        value / 255), float16 or float32.  A single image is width x height texels, row by
        row from the bottom; a UDIM image holds its tiles one after another (``tiles``).
    width, height: the image's size (a UDIM image's: its first tile's).
    srgb: the texels are sRGB-encoded and decoded after interpolation (byte images in the
        sRGB colour space, as Cycles keeps them); otherwise they are scene-linear (or data).
    associated: colours are premultiplied by alpha (``lookup``'s ``unassociate``).
    alpha_mode: Blender's alpha mode (STRAIGHT, PREMUL, CHANNEL_PACKED, NONE), for messages.
    tiles: the UDIM tiles in increasing number, () for an image that is not tiled.
    """

    name: str
    texels: np.ndarray
    width: int
    height: int
    srgb: bool = False
    associated: bool = False
    alpha_mode: str = "STRAIGHT"
    tiles: tuple = ()

    def __post_init__(self):
        texels = self.texels
        if texels.ndim != 2 or texels.shape[1] not in (1, 3, 4):
            raise ValueError(f"image '{self.name}': texels must be (N, 1, 3 or 4), got "
                             f"{texels.shape}")
        if texels.dtype not in TEXEL_TYPES:
            raise ValueError(f"image '{self.name}': texels must be uint8, float16 or float32, "
                             f"got {texels.dtype}")
        if self.alpha_mode not in ALPHA_MODES:
            raise ValueError(f"image '{self.name}': alpha mode must be one of {ALPHA_MODES}, "
                             f"got {self.alpha_mode!r}")
        if self.width < 1 or self.height < 1:
            raise ValueError(f"image '{self.name}': size must be positive, got "
                             f"{self.width} x {self.height}")
        expected = (sum(tile.width * tile.height for tile in self.tiles) if self.tiles
                    else self.width * self.height)
        if len(texels) != expected:
            raise ValueError(f"image '{self.name}': {len(texels)} texels for {expected}")
        if not texels.flags.c_contiguous:
            raise ValueError(f"image '{self.name}': texels must be C-contiguous")
        # Read-only: the one array every material and worker shares must never change.
        texels.setflags(write=False)

    @property
    def channels(self) -> int:
        return self.texels.shape[1]

    @property
    def nbytes(self) -> int:
        return self.texels.nbytes

    def tile_texels(self, number: int = 0) -> np.ndarray:
        """(H, W, C) view of a tile's texels (number 0: a single image's), row 0 at the
        bottom."""
        if not self.tiles:
            return self.texels.reshape(self.height, self.width, -1)
        for tile in self.tiles:
            if tile.number == number:
                return self.texels[tile.offset:tile.offset + tile.width * tile.height].reshape(
                    tile.height, tile.width, -1)
        raise KeyError(f"image '{self.name}' has no tile {number}")


def missing_image(name: str) -> ImageData:
    """What Cycles samples for an image it cannot read: one magenta texel (sampled with the
    node's interpolation and extension, as Cycles' 1 x 1 stand-in is)."""
    return ImageData(name, np.array([MISSING_RGBA[:3]], np.float32), 1, 1)


def first_tile(image: ImageData) -> ImageData:
    """A UDIM image's first tile as an image of its own (its texels a view, not a copy); an
    image that is not tiled, itself."""
    if not image.tiles:
        return image
    return ImageData(image.name, image.texels[:image.width * image.height], image.width,
                     image.height, image.srgb, image.associated, image.alpha_mode)


def image_from_pixels(name: str, pixels: np.ndarray, **settings) -> ImageData:
    """An ImageData from (H, W, C) pixels (row 0 at the bottom), C-contiguous, not copied
    when it already is."""
    pixels = np.ascontiguousarray(pixels)
    height, width = pixels.shape[:2]
    return ImageData(name, pixels.reshape(height * width, -1), width, height, **settings)


# --------------------------------------------------------------------------------------------
# Texel indices.

def _floor_fraction(x):
    """(integer part, fraction) as Cycles' ``frac``: int(x) - (x < 0), so that an exact
    negative integer -k gives (-k - 1, 1), as the kernel does."""
    whole = np.trunc(x)
    whole -= x < 0
    return whole.astype(np.int64), x - whole


def _wrap(index, size, extension: str):
    """Texel indices wrapped for Repeat, Extend and Mirror (Clip: unchanged; ``_Texels``
    reads zero outside the image)."""
    if extension == "REPEAT":
        return np.mod(index, size)
    if extension == "EXTEND":
        return np.clip(index, 0, size - 1)
    if extension == "MIRROR":
        folded = np.abs(index + (index < 0)) % (2 * size)
        return np.where(folded >= size, 2 * size - folded - 1, folded)
    return index


class _Texels:
    """Gathers texels of one image for n points: the points' tile (size and first row)
    fixed at construction; sums of weighted texels as (n, C) float32."""

    def __init__(self, image: ImageData, width, height, offset, clip: bool):
        self.image, self.width, self.height, self.offset, self.clip = (
            image, width, height, offset, clip)
        # One texel as one item of a 1-D array: a gather is a single take of whole texels
        # (3-16 bytes each) rather than C strided reads.
        self.items = image.texels.view(
            np.dtype((np.void, image.channels * image.texels.itemsize))).reshape(-1)
        # Bytes are value / 255: the scale rides on the weights.
        self.scale = np.float32(1 / 255) if image.texels.dtype == np.uint8 else None

    def column(self, ix):
        """(index, inside or None) of texel columns ix, wrapped already (``_wrap``)."""
        if not self.clip:
            return ix, None
        return np.clip(ix, 0, self.width - 1), (ix >= 0) & (ix < self.width)

    def row(self, iy):
        """(first texel of the row, inside or None) of texel rows iy."""
        inside = None
        if self.clip:
            iy, inside = np.clip(iy, 0, self.height - 1), (iy >= 0) & (iy < self.height)
        start = iy * self.width
        start += self.offset
        return start, inside

    def add(self, total, column, row, weight):
        """total + weight (n, 1) x the texels at (column, row); zero outside the image when
        clipping.  total None: a new (n, C) array."""
        (ix, inside_x), (start, inside_y) = column, row
        index = start + ix
        values = self.items.take(index).view(self.image.texels.dtype).reshape(len(index), -1)
        values = values.astype(np.float32)
        if self.scale is not None:
            weight = weight * self.scale
        if self.clip:
            weight = weight * (inside_x & inside_y)[:, None]
        values *= weight
        if total is None:
            return values
        total += values
        return total


def _cubic_weights(t):
    """The uniform cubic B-spline's four weights at fraction t (Cycles'
    SET_CUBIC_SPLINE_WEIGHTS): (1 - t)^3 / 6, (3t^3 - 6t^2 + 4) / 6, ..., t^3 / 6."""
    t2 = t * t
    t3 = t2 * t
    return ((1 - 3 * t + 3 * t2 - t3) / 6, (3 * t3 - 6 * t2 + 4) / 6,
            (1 + 3 * t + 3 * t2 - 3 * t3) / 6, t3 / 6)


def _sample(texels: _Texels, x, y, interpolation: str, extension: str):
    """(n, C) interpolated texels at texel-space coordinates (x, y) = (u W, v H)."""
    width, height = texels.width, texels.height
    if interpolation == "Closest":
        ix, _ = _floor_fraction(x)
        iy, _ = _floor_fraction(y)
        return texels.add(None, texels.column(_wrap(ix, width, extension)),
                          texels.row(_wrap(iy, height, extension)),
                          np.ones((len(ix), 1), np.float32))
    ix, tx = _floor_fraction(x - 0.5)
    iy, ty = _floor_fraction(y - 0.5)
    tx = tx.astype(np.float32)[:, None]
    ty = ty.astype(np.float32)[:, None]
    if interpolation == "Linear":
        taps, wx, wy = (0, 1), (1 - tx, tx), (1 - ty, ty)
    else:  # Cubic, and Smart (Cubic on Cycles' CPU)
        taps, wx, wy = (-1, 0, 1, 2), _cubic_weights(tx), _cubic_weights(ty)
    columns = [texels.column(_wrap(ix + tap, width, extension)) for tap in taps]
    total = None
    for tap, row_weight in zip(taps, wy):
        row = texels.row(_wrap(iy + tap, height, extension))
        for column, column_weight in zip(columns, wx):
            total = texels.add(total, column, row, column_weight * row_weight)
    return total


# --------------------------------------------------------------------------------------------
# Lookups.

def lookup(image: ImageData, u, v, interpolation: str = "Linear", extension: str = "REPEAT",
           unassociate: bool = False, dtype=np.float32):
    """Sample ``image`` at (u, v) (arrays of n): (colour (3, n), alpha (n,)) of ``dtype``,
    scene-linear, as Cycles' ``svm_image_texture``.

    UDIM images pick each point's tile from its UV's integer parts (truncated, as the kernel
    does: u in (-1, 0) reads tile 1001) and sample it at the fractional parts; a UV in no
    tile is magenta.  unassociate: the node's Alpha output is used, so colours are divided
    by alpha where it is neither 0 nor 1 (images with associated alpha only)."""
    if interpolation not in INTERPOLATIONS:
        raise ValueError(f"image '{image.name}': interpolation must be one of "
                         f"{INTERPOLATIONS}, got {interpolation!r}")
    if extension not in EXTENSIONS:
        raise ValueError(f"image '{image.name}': extension must be one of {EXTENSIONS}, got "
                         f"{extension!r}")
    u, v = np.broadcast_arrays(np.asarray(u, dtype).reshape(-1), np.asarray(v, dtype).reshape(-1))
    n = len(u)
    missing = None
    if image.tiles:
        column, row = np.trunc(u), np.trunc(v)
        numbers = UDIM_FIRST + UDIM_COLUMNS * row + column
        known = np.array([tile.number for tile in image.tiles])
        slot = np.clip(np.searchsorted(known, numbers), 0, len(known) - 1)
        missing = ((column < 0) | (row < 0) | (column >= UDIM_COLUMNS)
                   | (known[slot] != numbers))
        u, v = u - column, v - row
        sizes = np.array([(tile.width, tile.height, tile.offset) for tile in image.tiles])
        width, height, offset = (sizes[slot, k] for k in range(3))
    else:
        width, height, offset = image.width, image.height, 0
    texels = _Texels(image, width, height, offset, clip=extension == "CLIP")
    values = _sample(texels, u * width, v * height, interpolation, extension)
    return _finish(image, values, n, unassociate, missing, dtype)


def _finish(image: ImageData, values, n: int, unassociate: bool, missing, dtype):
    """(n, C) interpolated texels -> (colour (3, n), alpha (n,)): channels expanded to RGBA,
    alpha unassociated, sRGB decoded, points in no tile made magenta."""
    channels = values.shape[1]
    colour = np.empty((3, n), dtype)
    if channels == 1:
        colour[:] = values[:, 0]
    else:
        colour[:] = values[:, :3].T
    alpha = values[:, 3].astype(dtype) if channels == 4 else np.ones(n, dtype)
    if unassociate and image.associated and channels == 4:
        partial = (alpha != 0) & (alpha != 1)
        colour[:, partial] /= alpha[partial]
    if image.srgb:
        colour[:] = srgb_to_linear(np.maximum(colour, 0), np.float32)
    if missing is not None and missing.any():
        colour[:, missing] = np.array(MISSING_RGBA[:3], dtype)[:, None]
        alpha[missing] = MISSING_RGBA[3]
    return colour, alpha


# --------------------------------------------------------------------------------------------
# Projections (Cycles' ``svm_node_tex_image`` and ``svm_node_tex_image_box``).

def sphere_uv(co):
    """(u, v) of (3, n) coordinates wrapped onto a sphere around (0.5, 0.5, 0.5), as Cycles'
    ``map_to_sphere`` of the coordinates remapped from the unit box to [-1, 1]."""
    x, y, z = (2 * c - 1 for c in co)
    length = np.sqrt(x * x + y * y + z * z)
    on_axis = (x == 0) & (y == 0)
    u = np.where(on_axis, 0.0, 0.5 - np.arctan2(x, y) / (2 * np.pi))
    with np.errstate(invalid="ignore", divide="ignore"):
        v = 1 - np.arccos(np.clip(z / length, -1, 1)) / np.pi
    zero = length == 0
    return np.where(zero, 0.0, u), np.where(zero, 0.0, v)


def tube_uv(co):
    """(u, v) of (3, n) coordinates wrapped onto a tube along Z around (0.5, 0.5), as
    Cycles' ``map_to_tube`` of the coordinates remapped to [-1, 1]."""
    x, y, z = (2 * c - 1 for c in co)
    radius = np.sqrt(x * x + y * y)
    u = (1 - np.arctan2(x, y) / np.pi) / 2
    v = (z + 1) / 2
    zero = radius == 0
    return np.where(zero, 0.0, u), np.where(zero, 0.0, v)


def box_weights(normal, blend: float):
    """(3, n) weights of the X, Y and Z projections of a Box-projected image for (3, n)
    object-space normals, as Cycles' ``svm_node_tex_image_box``: one face's image where the
    normal is near an axis, blends of two or three across ``blend`` (0: hard edges) of the
    triangle of |normal| / (|x| + |y| + |z|)."""
    n = np.abs(normal)
    total = n.sum(axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        n = n / total
    nx, ny, nz = n
    blend = float(blend)
    limit = 0.5 * (1 + blend)
    weights = np.zeros_like(n)
    undecided = np.isfinite(nx)

    def take(condition):
        nonlocal undecided
        chosen = undecided & condition
        undecided = undecided & ~chosen
        return chosen

    for axis, (a, b, c) in enumerate(((nx, ny, nz), (ny, nx, nz), (nz, nx, ny))):
        single = take((a > limit * (a + b)) & (a > limit * (a + c)))
        weights[axis, single] = 1
    if blend > 0:
        with np.errstate(invalid="ignore", divide="ignore"):
            for first, second, third in ((0, 1, 2), (1, 2, 0), (0, 2, 1)):
                pair = take(n[third] < (1 - limit) * (n[first] + n[second]))
                share = n[first][pair] / (n[first][pair] + n[second][pair])
                share = np.clip((share - 0.5 * (1 - blend)) / blend, 0, 1)
                weights[first, pair] = share
                weights[second, pair] = 1 - share
            three = take(np.ones_like(nx, bool))
            weights[:, three] = (((2 - limit) * n[:, three] + (limit - 1))
                                 / (2 * limit - 1))
    # Cycles' fallback where nothing was chosen (no blend, or a zero normal): the X image.
    weights[0, undecided] = 1
    return weights


def _box_lookup(image, co, normal, blend, interpolation, extension, unassociate, dtype):
    """Cycles' Box projection: up to three lookups (X, Y, Z faces, each mapped so that no
    face's image is mirrored) weighted by ``box_weights``."""
    weights = box_weights(normal, blend).astype(dtype)
    n = co.shape[1]
    colour, alpha = np.zeros((3, n), dtype), np.zeros(n, dtype)
    x, y, z = co
    faces = ((np.where(normal[0] < 0, 1 - y, y), z), (np.where(normal[1] > 0, 1 - x, x), z),
             (np.where(normal[2] > 0, 1 - y, y), x))
    # Cycles' Box projection samples a UDIM image's first tile only (its first slot).
    flat = first_tile(image)
    for axis, (u, v) in enumerate(faces):
        used = np.flatnonzero(weights[axis] > 0)
        if len(used) == 0:
            continue
        face_colour, face_alpha = lookup(flat, u[used], v[used], interpolation, extension,
                                         unassociate, dtype)
        colour[:, used] += weights[axis, used] * face_colour
        alpha[used] += weights[axis, used] * face_alpha
    return colour, alpha


# --------------------------------------------------------------------------------------------
# The nodes.

def _check(name: str, value, allowed, owner: str):
    if value not in allowed:
        raise ValueError(f"{owner}: {name} must be one of {allowed}, got {value_text(value)}")


@node("ShaderNodeTexImage", inputs=(("Vector", VECTOR),),
      outputs=(("Color", COLOR), ("Alpha", FLOAT)),
      options=("image", "interpolation", "projection", "projection_blend", "extension",
               "alpha_used"),
      implicit={"Vector": "uv"})
def image_texture(points, vector, *, image: ImageData, interpolation="Linear",
                  projection="FLAT", projection_blend=0.0, extension="REPEAT",
                  alpha_used=False):
    """Blender's Image Texture node.  image: the ``ImageData`` the add-on exported (a
    missing image is ``missing_image``); alpha_used: the node's Alpha output is linked
    (Cycles then un-premultiplies Color).  Box projection weighs its faces by the points'
    object-space shading normals (``ShadingPoints`` coordinate 'object_normal')."""
    _check("projection", projection, PROJECTIONS, f"image '{image.name}'")
    n = len(points)
    co = np.broadcast_to(np.asarray(vector, points.dtype), (3, n))
    if projection == "BOX":
        return _box_lookup(image, co, points.coordinate("object_normal"), projection_blend,
                           interpolation, extension, alpha_used, points.dtype)
    if projection == "SPHERE":
        u, v = sphere_uv(co)
    elif projection == "TUBE":
        u, v = tube_uv(co)
    else:
        u, v = co[0], co[1]
    return lookup(image, u, v, interpolation, extension, alpha_used, points.dtype)


def equirectangular_uv(directions):
    """(u, v) of (3, n) directions in an equirectangular (latitude-longitude) image, as
    Cycles' ``direction_to_equirectangular``: u = 0.5 - atan2(y, x) / 2 pi (+X at the
    centre, +Y a quarter from the left, -X at both edges), v = 1 - theta / pi (+Z at the
    top)."""
    x, y, z = directions
    length = np.sqrt(x * x + y * y + z * z)
    with np.errstate(invalid="ignore", divide="ignore"):
        cos_theta = np.clip(z / length, -1, 1)
    u = 0.5 - np.arctan2(y, x) / (2 * np.pi)
    v = 1 - np.arccos(cos_theta) / np.pi
    zero = length == 0
    return np.where(zero, 0.0, u), np.where(zero, 0.0, v)


def mirror_ball_uv(directions):
    """(u, v) of (3, n) unit directions in a mirror-ball image (a chrome ball photographed
    from -Y), as Cycles' ``direction_to_mirrorball``."""
    x, y, z = directions
    y = y - 1
    divisor = 2 * np.sqrt(np.maximum(-0.5 * y, 0))
    scale = np.where(divisor > 0, 1 / np.where(divisor > 0, divisor, 1), 1)
    return 0.5 * (x * scale + 1), 0.5 * (z * scale + 1)


def environment_uv(directions, projection: str = "EQUIRECTANGULAR"):
    """(u, v) of (3, n) directions for an Environment Texture's projection (normalised
    first, as Cycles' ``safe_normalize``: a zero vector stays zero)."""
    _check("projection", projection, ENVIRONMENT_PROJECTIONS, "environment texture")
    directions = np.asarray(directions)
    length = np.sqrt((directions * directions).sum(axis=0))
    with np.errstate(invalid="ignore", divide="ignore"):
        unit = np.where(length > 0, directions / length, 0)
    if projection == "MIRROR_BALL":
        return mirror_ball_uv(unit)
    return equirectangular_uv(unit)


@node("ShaderNodeTexEnvironment", inputs=(("Vector", VECTOR),), outputs=(("Color", COLOR),),
      options=("image", "interpolation", "projection"),
      implicit={"Vector": "position"})
def environment_texture(points, vector, *, image: ImageData, interpolation="Linear",
                        projection="EQUIRECTANGULAR"):
    """Blender's Environment Texture node: the image seen in the direction ``vector``
    (unlinked: the points' position, which for the world is the direction the ray travels,
    as Cycles' P of the background), wrapped with Repeat as Cycles does."""
    n = len(points)
    co = np.broadcast_to(np.asarray(vector, points.dtype), (3, n))
    u, v = environment_uv(co, projection)
    colour, _ = lookup(image, u, v, interpolation, "REPEAT", False, points.dtype)
    return (colour,)
