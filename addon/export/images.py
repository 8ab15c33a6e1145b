"""Blender images -> ``core.shader.images.ImageData``, read once per image per export.

``ImageExporter`` keeps one ImageData per (image, frame): every material and world using an
image shares it, and so do the render's worker processes (its texels reach them once,
through shared memory).  What it holds is what Cycles samples (Blender 5.0: Cycles reads
file images itself through OpenImageIO, and packed, generated and movie images through
Blender's buffers, ``intern/cycles/blender/image.cpp``):

* byte images in the sRGB colour space keep their bytes, 1 byte a channel, decoded after
  interpolation as Cycles does; Non-Color and scene-linear byte images keep their bytes too.
  A 256-entry table decoding bytes before interpolation would match Cycles for Closest
  only: Linear and Cubic blend the encoded values there;
* byte images in any other colour space are converted to scene-linear half floats, as
  Cycles converts them (its OCIO processor, reproduced through Blender's: ``ColourSpaces``),
  with its half floats' quirks (rounding toward zero; a zero half reads as 2^-15);
* float images are Blender's float buffer (already converted to scene-linear on load),
  float32, except where Cycles reads the file itself and treats it otherwise (an sRGB float
  image stays encoded; a Straight-alpha EXR keeps its stored colours: ``_file_values``);
* alpha is associated (colours premultiplied) as Cycles associates it: bytes with Cycles'
  integer product (c a) / 255, rounded down; not for Non-Color, Channel Packed or None
  (None: alpha 1).  The alpha channel is dropped when every texel is opaque, and the colour
  channels of a float image with one channel stay one (grey);
* non-finite float texels are zeroed, all four channels, as Cycles' loader intends (its loop
  reaches only every fourth pixel, so there a NaN texel other than those poisons the
  samples that read it), with one warning naming the image;
* an image Blender cannot read (missing file, unreadable data, a viewer image) is Cycles'
  magenta stand-in, with one warning naming the image, its path and the material.

Sequences and movies are read at the frame the node's image user shows at the scene's
frame (offset, start, duration, cyclic: Blender's ``BKE_image_user_frame_get``), UDIM
images tile by tile, every tile (Cycles loads a file UDIM's tiles only where some vertex's
UV falls, and shows a face's other tiles magenta).

Known differences from Cycles: a half-float EXR is held as float32 (Cycles reads its zero
texels as 2^-15 = 3e-5); a PNG file marked Premultiplied whose colours exceed their alpha
(not valid premultiplied data) reads slightly differently, as Blender's buffer clamps them.

Memory (``python -m bench.images``): reading goes through ``Image.pixels`` (float32, 16
bytes a pixel) beside Blender's own buffer (4 bytes a pixel for bytes) while the texels are
made a block at a time; Blender's buffer is freed afterwards if the export loaded it, as
Cycles does.  Measured for opaque 8-bit RGBA PNGs: 8k x 8k peaks at 1.5 GiB during the
export and keeps 192 MiB of texels (3 bytes a pixel); 16k x 16k peaks at 5.8 GiB and keeps
768 MiB.  A float RGBA image keeps 16 bytes a pixel, one in another colour space 8.
"""

from __future__ import annotations

import os
import re
import tempfile
from typing import Callable, Optional

import bpy
import numpy as np

from ...core.colour import linear_to_srgb, srgb_to_linear
from ...core.shader.images import ImageData, Tile, missing_image

#: Texels converted at a time (bounds the temporaries of a conversion to a few tens of MB).
BLOCK_TEXELS = 1 << 20
#: Blender converts an hdr-video encoded colour space (Rec.2100-PQ, Rec.2100-HLG) with 1.0 at
#: 203 nits (ITU-R BT.2408's reference white) when it loads a float image, where Cycles'
#: OCIO processor puts 1.0 at the config's 100 nits: Cycles' values are 2.03 times
#: Blender's (measured 2.029-2.030 over every texel of a test image, test_shader_images).
HDR_VIDEO_CYCLES_SCALE = 203.0 / 100.0
#: Image sources Cycles reads through Blender's buffers rather than from the file
#: (``image_is_builtin``; packed images too).
BUILTIN_SOURCES = ("GENERATED", "MOVIE")
#: File formats OpenImageIO reads as premultiplied whatever the image's alpha mode says.
EXR_FORMATS = ("OPEN_EXR", "OPEN_EXR_MULTILAYER")


class ImageReadError(Exception):
    """Blender holds no pixels for the image (missing or unreadable file)."""


def frame_number(image_user, frame: int) -> int:
    """The frame of an animated image (sequence or movie) its user shows at scene frame
    ``frame``: Blender's ``BKE_image_user_frame_get`` (frame start, duration, offset,
    cyclic), which Cycles uses."""
    length = image_user.frame_duration
    if length == 0:
        return 0
    number = frame - image_user.frame_start + 1
    if image_user.use_cyclic:
        number %= length
        if number == 0:
            number = length
    number = min(max(number, 0), length)
    if image_user.use_cyclic:
        number %= length
        if number == 0:
            number = length
    return number + image_user.frame_offset


def cycles_reads_file(image) -> bool:
    """Whether Cycles reads this image's file itself (OpenImageIO) instead of Blender's
    buffer: not packed, not generated, not a movie, no generated UDIM tile."""
    if image.packed_file is not None or len(image.packed_files):
        return False
    if image.source in BUILTIN_SOURCES:
        return False
    if image.source == 'TILED' and any(tile.is_generated_tile for tile in image.tiles):
        return False
    return True


# --------------------------------------------------------------------------------------------
# Colour spaces.

def _ocio_config_path() -> Optional[str]:
    path = os.environ.get("OCIO") or os.path.join(bpy.utils.system_resource('DATAFILES'),
                                                  "colormanagement", "config.ocio")
    return path if os.path.isfile(path) else None


def hdr_video_colour_spaces(path: Optional[str]) -> frozenset:
    """Names (and aliases) of the colour spaces an OCIO config marks ``encoding:
    hdr-video``."""
    if path is None:
        return frozenset()
    names, current, aliases = set(), None, []
    with open(path, encoding="utf-8") as config:
        for line in config:
            text = line.strip()
            if text.startswith("- !<"):
                current, aliases = None, []
            elif text.startswith("name:") and current is None:
                current = text[5:].strip().strip('"')
            elif text.startswith("aliases:"):
                aliases = [alias.strip().strip('"')
                           for alias in text[8:].strip().strip("[]").split(",") if alias]
            elif current and re.fullmatch(r"encoding:\s*hdr-video", text):
                names.add(current)
                names.update(aliases)
    return frozenset(names)


class ColourSpaces:
    """Cycles' handling of Blender's colour spaces: ``kind`` sorts them as Cycles does
    (``ColorSpaceManager::detect_known_colorspace``) and ``to_scene_linear`` converts
    colours with the colour space's OCIO transform.

    Both use Blender's own conversion: a float image Blender loads in a colour space is
    converted to scene-linear with the OCIO config's transform, which is the processor
    Cycles applies.  A probe image (float, packed as EXR in memory, never written to disk)
    holds the colours; its colour space is set, Blender reloads and converts it, and its
    pixels are read back; the probe is removed.  Results are kept for the session: the
    config does not change while Blender runs."""

    _kinds: dict = {}
    _hdr_video: Optional[frozenset] = None

    @staticmethod
    def convert_in_blender(name: str, rgb: np.ndarray) -> np.ndarray:
        """(n, 3) float32 colours in colour space ``name`` -> (n, 3) float32 scene-linear,
        as Blender converts a float image on load."""
        count = len(rgb)
        if count == 0:
            return np.zeros((0, 3), np.float32)
        width = min(count, 4096)
        height = -(-count // width)
        rgba = np.ones((height * width, 4), np.float32)   # alpha 1: no (un)premultiplying
        rgba[:count, :3] = rgb
        probe = bpy.data.images.new("glint colour probe", width, height, alpha=True,
                                    float_buffer=True)
        try:
            probe.colorspace_settings.name = "Linear Rec.709"
            probe.pixels.foreach_set(rgba.ravel())
            probe.pack()
            probe.colorspace_settings.name = name
            probe.pixels.foreach_get(rgba.ravel())
        finally:
            bpy.data.images.remove(probe)
        return rgba[:count, :3]

    @classmethod
    def kind(cls, name: str, is_data: bool) -> str:
        """'data' (no conversion, no alpha association), 'linear' (scene-linear already),
        'srgb' (the sRGB curve: Cycles keeps byte images encoded) or 'other', by Cycles'
        test: 256 levels of each primary and of grey through the transform, no crosstalk
        and equal channels, then the identity or the sRGB curve within its tolerances."""
        if is_data:
            return "data"
        if name not in cls._kinds:
            levels = np.arange(256, dtype=np.float32) / 255
            probe = np.zeros((4, 256, 3), np.float32)
            for channel in range(3):
                probe[channel, :, channel] = levels
            probe[3] = levels[:, None]
            out = cls.convert_in_blender(name, probe.reshape(-1, 3)).reshape(4, 256, 3)
            crosstalk = max(np.abs(np.delete(out[channel], channel, axis=1)).max()
                            for channel in range(3))
            grey = out[3]
            separable = (crosstalk <= 1e-5
                         and all(np.allclose(out[c, :, c], grey[:, c], rtol=1e-5, atol=1e-6)
                                 for c in range(3))
                         and np.allclose(grey[:, 0], grey[:, 1], rtol=1e-5, atol=1e-6)
                         and np.allclose(grey[:, 1], grey[:, 2], rtol=1e-5, atol=1e-6))
            mean = grey.mean(axis=1)
            if separable and np.allclose(mean, levels, rtol=1e-5, atol=1e-6):
                cls._kinds[name] = "linear"
            elif separable and np.allclose(mean, srgb_to_linear(levels), rtol=1e-4, atol=1e-6):
                cls._kinds[name] = "srgb"
            else:
                cls._kinds[name] = "other"
        return cls._kinds[name]

    @classmethod
    def cycles_scale(cls, name: str) -> float:
        """What Cycles' conversion of colour space ``name`` is, as a multiple of Blender's
        (HDR_VIDEO_CYCLES_SCALE for hdr-video encodings, else 1)."""
        if cls._hdr_video is None:
            cls._hdr_video = hdr_video_colour_spaces(_ocio_config_path())
        return HDR_VIDEO_CYCLES_SCALE if name in cls._hdr_video else 1.0

    @classmethod
    def to_scene_linear(cls, name: str, rgb: np.ndarray) -> np.ndarray:
        """(n, 3) colours in colour space ``name`` -> (n, 3) scene-linear float32, as
        Cycles converts them."""
        return cls.convert_in_blender(name, rgb) * np.float32(cls.cycles_scale(name))


# --------------------------------------------------------------------------------------------
# Pixels -> texels.

def _blocks(count: int):
    for start in range(0, count, BLOCK_TEXELS):
        yield slice(start, min(start + BLOCK_TEXELS, count))


def _read_pixels(image) -> np.ndarray:
    """(N, C) float32 copy of ``Image.pixels`` (row 0 at the bottom), C = image.channels.
    Raises ImageReadError when Blender holds no pixels."""
    try:
        width, height = image.size
        channels = image.channels
        count = width * height * channels
        if count == 0 or len(image.pixels) != count:
            raise ImageReadError(image.name)
        pixels = np.empty(count, np.float32)
        image.pixels.foreach_get(pixels)
    except (RuntimeError, ValueError, TypeError, ReferenceError):
        raise ImageReadError(image.name) from None
    return pixels.reshape(width * height, channels), width, height


def _byte_texels(pixels, kind: str, associate: bool, reads_file: bool, premultiplied: bool,
                 colour_space: str):
    """Texels of a byte image from its pixels (bytes / 255, straight alpha: Blender's byte
    buffer): uint8 for data, linear and sRGB colour spaces, float16 scene-linear for others
    (Cycles' half float conversion)."""
    count = len(pixels)
    opaque = bool(np.all(pixels[:, 3] == 1))
    channels = 3 if opaque else 4
    texels = np.empty((count, channels), np.uint8)
    for block in _blocks(count):
        # Whole contiguous rows scaled and rounded, then the channels kept: 2.2x faster
        # than rounding the strided channels (measured on 16M texels).
        scaled = pixels[block] * np.float32(255)
        np.rint(scaled, out=scaled)
        np.copyto(texels[block], scaled[:, :channels], casting="unsafe")
    if kind == "other":
        return _converted_bytes(texels, associate, colour_space, reads_file), False
    if associate and not opaque:
        alpha = texels[:, 3]
        for block in _blocks(count):
            colour = texels[block, :3].astype(np.uint16)
            a = alpha[block, None].astype(np.uint16)
            if reads_file and premultiplied:
                # Cycles reads a file marked Premultiplied as it is stored (premultiplied)
                # and multiplies by alpha again; Blender's buffer holds it divided by alpha:
                # undo that first.
                colour = (colour * a + 127) // 255
            texels[block, :3] = colour * a // 255
    return texels, kind == "srgb"


def _rgb_keys(texels):
    """(n,) uint32 R << 16 | G << 8 | B of (n, >= 3) uint8 texels."""
    keys = texels[:, 0].astype(np.uint32) << 16
    keys |= texels[:, 1].astype(np.uint32) << 8
    keys |= texels[:, 2]
    return keys


def cycles_half(values) -> np.ndarray:
    """float16 of float32 values as Cycles' ``float_to_half_image`` makes them on the CPU:
    rounded toward zero (not to nearest), below 2^-14 flushed to zero, beyond the largest
    half clamped to it."""
    values = np.asarray(values, np.float32)
    halves = values.astype(np.float16)
    over = np.abs(halves.astype(np.float32)) > np.abs(values)
    halves[over] = np.nextafter(halves[over], np.float16(0))
    halves[np.abs(values) < 2.0 ** -14] = 0
    return halves


def cycles_half_read(halves) -> np.ndarray:
    """float32 of float16 values as Cycles' ``half_to_float_image`` reads them on the CPU:
    exact for normal halves, but a zero reads as 2^-15 (its bias trick skips the zero
    case): what a black half texel shows in Cycles, and what alpha 0 divides by."""
    bits = np.asarray(halves, np.float16).view(np.uint16).astype(np.uint32)
    out = ((bits & 0x8000) << 16) | (((bits & 0x7C00) + 0x1C000) << 13) | ((bits & 0x03FF) << 13)
    return out.view(np.float32)


def _converted_bytes(texels, associate: bool, colour_space: str, reads_file: bool):
    """(N, 3 or 4) float16 scene-linear texels of (N, 3 or 4) uint8 ones (RGB: opaque) in
    ``colour_space``, as Cycles makes them (``ColorSpaceManager::to_scene_linear``): the
    bytes become half floats (rounded by OpenImageIO for a file, by ``cycles_half`` in
    Cycles' loader of Blender's buffer), colours are multiplied by alpha (associated), read
    back (``cycles_half_read``) and through OCIO with alpha divided out and back in where
    it is not 0 or 1 (so alpha 0, read as 2^-15, gives the conversion of white times
    2^-15), stored as ``cycles_half``, and read by the kernel as ``cycles_half_read``: the
    texels hold what that reading returns.

    Each distinct input is converted once: a byte image has few distinct colours."""
    count = len(texels)
    opaque = texels.shape[1] == 3
    out = np.empty((count, 3 if opaque else 4), np.float16)

    def to_half(bytes_):
        values = bytes_.astype(np.float32) / 255
        return values.astype(np.float16) if reads_file else cycles_half(values)

    def stored(linear):   # what the kernel reads back from Cycles' half texels
        return cycles_half_read(cycles_half(linear)).astype(np.float16)

    alpha = np.full(count, 255, np.uint8) if opaque else texels[:, 3]
    whole = alpha == 255
    # Opaque texels go through OCIO as they are: a 2^24-entry table of which colours occur
    # keeps this linear in the texels.
    keys = _rgb_keys(texels)
    present = np.zeros(1 << 24, bool)
    present[keys[whole]] = True
    unique = np.flatnonzero(present).astype(np.uint32)
    rgb = np.stack([(unique >> 16) & 255, (unique >> 8) & 255, unique & 255], axis=1)
    table = stored(ColourSpaces.to_scene_linear(colour_space, cycles_half_read(to_half(rgb))))
    slot = np.cumsum(present, dtype=np.int32) - 1
    out[whole, :3] = table[slot[keys[whole]]]
    if not whole.all():
        index = np.flatnonzero(~whole)
        a = cycles_half_read(to_half(alpha[index, None]))
        if not associate:
            colour = to_half(texels[index, :3])
        elif reads_file:   # OpenImageIO's halves multiplied in Cycles' half
            colour = cycles_half(cycles_half_read(to_half(texels[index, :3])) * a)
        else:              # Cycles' loader multiplies the bytes' floats, then makes halves
            colour = cycles_half(texels[index, :3].astype(np.float32) / 255
                                 * (alpha[index, None].astype(np.float32) / 255))
        inputs = cycles_half_read(colour) * (np.float32(1) / a)
        distinct, inverse = np.unique(inputs, axis=0, return_inverse=True)
        linear = ColourSpaces.to_scene_linear(colour_space, distinct)
        out[index, :3] = stored(linear[inverse.reshape(-1)] * a)
    if not opaque:
        out[:, 3] = cycles_half_read(to_half(alpha)).astype(np.float16)
    return out


def _file_values(pixels, kind: str, straight_file: bool, colour_space: str) -> bool:
    """Turn Blender's float buffer (premultiplied, scene-linear) into what Cycles holds for
    a float image it reads from the file itself, in place; returns whether the values stay
    sRGB-encoded.  Cycles keeps an sRGB float image encoded (decoded after interpolation:
    the texel is the encoded straight colour times alpha), converts hdr-video colour spaces
    at 100 nits (HDR_VIDEO_CYCLES_SCALE), and takes an EXR marked Straight as stored, where
    Blender premultiplies it (straight_file: the texel is the straight colour)."""
    channels = pixels.shape[1]
    has_alpha = channels == 4
    srgb = kind == "srgb"
    scale = np.float32(ColourSpaces.cycles_scale(colour_space))
    if not (srgb or straight_file or scale != 1):
        return False
    for block in _blocks(len(pixels)):
        colour = pixels[block, :min(channels, 3)]
        if has_alpha:
            a = pixels[block, 3:4]
            partial = (a > 0) & (a != 1)
            straight = np.divide(colour, a, out=colour.copy(), where=partial)
        else:
            straight = colour
        if scale != 1:
            straight = straight * scale
        if srgb:
            straight = linear_to_srgb(straight).astype(np.float32)
        colour[...] = straight if straight_file or not has_alpha else np.where(
            partial, straight * a, straight)
    return srgb


def _clean(texels) -> int:
    """Zero every texel holding a NaN or infinity (all its channels); the count zeroed."""
    bad = 0
    for block in _blocks(len(texels)):
        rows = ~np.isfinite(texels[block]).all(axis=1)
        found = int(rows.sum())
        if found:
            texels[block][rows] = 0
            bad += found
    return bad


def image_texels(image, pixels, reads_file: bool):
    """(texels, srgb, associated, non-finite texels zeroed) of a bpy Image from its
    ``_read_pixels`` (consumed)."""
    settings = image.colorspace_settings
    kind = ColourSpaces.kind(settings.name, settings.is_data)
    mode = image.alpha_mode
    associate = kind != "data" and mode not in ("CHANNEL_PACKED", "NONE")
    if not image.is_float:
        texels, srgb = _byte_texels(pixels, kind, associate, reads_file, mode == "PREMUL",
                                    settings.name)
        return texels, srgb, associate, 0
    srgb = False
    if reads_file:
        straight_file = mode == "STRAIGHT" and image.file_format in EXR_FORMATS
        srgb = _file_values(pixels, kind, straight_file, settings.name)
    bad = _clean(pixels)
    if pixels.shape[1] == 4 and np.all(pixels[:, 3] == 1):
        pixels = np.ascontiguousarray(pixels[:, :3])
    return pixels, srgb, associate, bad


# --------------------------------------------------------------------------------------------
# The exporter.

class ImageExporter:
    """Reads images into ImageData once per (image, frame) for one export.

    frame: the scene frame (animated images' frame: ``frame_number``);
    note: takes a warning for the user (``ExportContext.note``)."""

    def __init__(self, frame: int, note: Callable[[str], None]):
        self.frame = frame
        self.note = note
        self.cache: dict = {}

    def image(self, image, image_user, owner: str) -> ImageData:
        """The ImageData of a bpy Image (or None) as an image node whose image user is
        ``image_user`` shows it; owner names the material or world using it (warnings)."""
        if image is None:
            self.note(f"{owner}: an image node has no image; it renders magenta, as in "
                      f"Cycles")
            return missing_image("(no image)")
        animated = image.source in ("SEQUENCE", "MOVIE")
        frame = frame_number(image_user, self.frame) if animated and image_user else 0
        key = (image.name_full, frame)
        if key not in self.cache:
            self.cache[key] = self._export(image, image_user, frame, owner)
        return self.cache[key]

    def _export(self, image, image_user, frame: int, owner: str) -> ImageData:
        loaded = image.has_data
        try:
            if image.source == 'VIEWER':
                raise ImageReadError(image.name)
            if image.source == 'TILED':
                data = self._tiled(image, owner)
            else:
                if image.source in ("SEQUENCE", "MOVIE"):
                    self._show_frame(image, image_user, frame)
                pixels, width, height = _read_pixels(image)
                texels, srgb, associated, bad = image_texels(
                    image, pixels, cycles_reads_file(image))
                del pixels
                self._warn_non_finite(image, bad, owner)
                data = ImageData(image.name, texels, width, height, srgb, associated,
                                 image.alpha_mode)
        except ImageReadError:
            path = self._path(image, image_user)
            self.note(f"{owner}: image '{image.name}' ({path}) cannot be read; it renders "
                      f"magenta, as in Cycles")
            return missing_image(image.name)
        finally:
            if not loaded and image.source != 'GENERATED':
                image.buffers_free()
        return data

    def _warn_non_finite(self, image, bad: int, owner: str) -> None:
        if bad:
            self.note(f"{owner}: image '{image.name}' has {bad} pixels with NaN or infinite "
                      f"values; they render black")

    @staticmethod
    def _path(image, image_user) -> str:
        if image.packed_file is not None:
            return "packed"
        if image.source == 'GENERATED':
            return "generated"
        try:
            path = image.filepath_from_user(image_user=image_user) if image_user else \
                bpy.path.abspath(image.filepath, library=image.library)
        except (RuntimeError, TypeError):
            path = image.filepath
        return f"path '{path}'" if path else "no path"

    @staticmethod
    def _show_frame(image, image_user, frame: int) -> None:
        """Make ``frame`` the frame ``Image.pixels`` reads (Blender reads an animated
        image's last acquired frame): a temporary image texture acquires it."""
        texture = bpy.data.textures.new("glint frame probe", 'IMAGE')
        try:
            texture.image = image
            user = texture.image_user
            user.frame_duration, user.frame_start = 1, 1
            user.frame_offset, user.use_cyclic = 0, False
            user.frame_current = frame
            texture.evaluate((0.5, 0.5, 0.0))
        finally:
            bpy.data.textures.remove(texture)

    def _tiled(self, image, owner: str) -> ImageData:
        """A UDIM image, each tile read as an image of its own (``Image.pixels`` reads only
        the first tile): a file tile from its file, a packed one from its packed bytes, a
        generated one as Blender generates it.  A tile that cannot be read is Cycles'
        magenta stand-in, with a warning naming it."""
        reads_file = cycles_reads_file(image)
        tiles, parts, settings, unread = [], [], None, []
        offset = 0
        for tile in sorted(image.tiles, key=lambda t: t.number):
            try:
                with _tile_image(image, tile) as single:
                    pixels, width, height = _read_pixels(single)
                    texels, srgb, associated, bad = image_texels(single, pixels, reads_file)
                self._warn_non_finite(image, bad, owner)
                settings = settings or (srgb, associated)
            except ImageReadError:
                unread.append(tile.number)
                texels, width, height = None, 1, 1
            tiles.append(Tile(tile.number, width, height, offset))
            parts.append(texels)
            offset += width * height
        if unread:
            self.note(f"{owner}: image '{image.name}' ({self._path(image, None)}): UDIM "
                      f"tiles {unread} cannot be read; they render magenta, as in Cycles")
        if settings is None:
            raise ImageReadError(image.name)
        read = [part for part in parts if part is not None]
        channels = max(part.shape[1] for part in read)
        dtype = np.result_type(*(part.dtype for part in read))
        one = 255 if dtype == np.uint8 else 1
        texels = np.zeros((offset, max(channels, 3)), dtype)
        for tile, part in zip(tiles, parts):
            rows = slice(tile.offset, tile.offset + tile.width * tile.height)
            if part is None:
                texels[rows, :3] = (one, 0, one)     # magenta, whatever the encoding
            else:
                texels[rows, :part.shape[1]] = part
                if part.shape[1] == 1:
                    texels[rows, 1:3] = part
            if channels == 4 and (part is None or part.shape[1] < 4):
                texels[rows, 3] = one
        first = tiles[0]
        return ImageData(image.name, texels, first.width, first.height, settings[0],
                         settings[1], image.alpha_mode, tuple(tiles))


def tile_path(image, number: int) -> str:
    """The absolute file path of UDIM tile ``number`` of a tiled image: its path's <UDIM>
    token as the four-digit number, or <UVTILE> as u<column>_v<row> (counted from 1)."""
    path = bpy.path.abspath(image.filepath, library=image.library)
    column, row = (number - 1001) % 10 + 1, (number - 1001) // 10 + 1
    return path.replace("<UDIM>", f"{number:04d}").replace("<UVTILE>", f"u{column}_v{row}")


class _tile_image:
    """Context manager: a temporary bpy Image holding one UDIM tile, with the image's
    colour space and alpha mode; removed on exit (with any temporary file)."""

    def __init__(self, image, tile):
        self.image, self.tile = image, tile
        self.single = self.temporary = None

    def __enter__(self):
        image, tile = self.image, self.tile
        if tile.is_generated_tile:
            single = bpy.data.images.new(
                "glint tile", tile.generated_width, tile.generated_height, alpha=True,
                float_buffer=tile.use_generated_float)
            single.generated_type = tile.generated_type
            single.generated_color = tile.generated_color
        else:
            packed = [item for item in image.packed_files if item.tile_number == tile.number]
            if packed:
                suffix = os.path.splitext(packed[0].filepath)[1] or ".png"
                handle, self.temporary = tempfile.mkstemp(suffix=suffix)
                with os.fdopen(handle, "wb") as file:
                    file.write(packed[0].packed_file.data)
                path = self.temporary
            else:
                path = tile_path(image, tile.number)
            try:
                single = bpy.data.images.load(path, check_existing=False)
            except RuntimeError:
                self.__exit__(None, None, None)
                raise ImageReadError(image.name) from None
        self.single = single
        single.colorspace_settings.name = image.colorspace_settings.name
        single.alpha_mode = image.alpha_mode
        return single

    def __exit__(self, *exc):
        if self.single is not None:
            bpy.data.images.remove(self.single)
            self.single = None
        if self.temporary is not None:
            os.unlink(self.temporary)
            self.temporary = None
        return False
