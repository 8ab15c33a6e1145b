"""Glint's procedural textures (``core.shader.textures``) against Cycles, pixel by pixel, and
their hashes against Bob Jenkins' own lookup3.

Each family's cases render in one Cycles image (``texture_support``): one sample at each
pixel's centre, each tile a plane whose material writes, into AOVs, the Vector and W it
feeds the texture and every output the texture gives.  The node function then runs on
those same float32 coordinates.

What must agree, and how closely:
* Hashes are integer arithmetic: White Noise and every Voronoi colour agree bit for bit on
  any machine.
* On a CPU with AVX2 and FMA, Blender runs Cycles' AVX2 kernel, whose fused multiply-adds
  Glint reproduces: the cases marked exact (Noise, Voronoi but Minkowski's, Gradient but
  Radial, Checker, Brick with most options, Wave's saw and triangle) must agree bit for bit.  Elsewhere Cycles' SSE kernel rounds each product
  separately, and these cases fall under the tolerance below.
* Otherwise within TOLERANCE = 1e-5 (absolute, plus the same relative): float32 holds 24
  bits (6e-8 of a value), and the longest chains here (15 fBM octaves, Magic's ten nested
  sines, Wave's phase of about 30 divided by 2 pi) turn an ulp of difference in one step
  (sinf, powf and atan2f from libm, a product fused or not) into at most about 100 ulps of
  the output: measured at most 5e-6 (Magic at scale 40).  A wrong hash, gradient, constant,
  octave weight or operation changes values by 1e-3 or more.
* Where a value jumps (a Voronoi cell's border, a brick's edge, a saw's wrap), a difference
  of an ulp in the coordinate can pick the other side; such pixels (``on_a_jump``: those
  whose value Glint changes by more than the tolerance when the coordinate moves by four
  ulps) are left out of the tolerance check, never of the bit-for-bit one.
"""

from __future__ import annotations

import dataclasses

import bpy
import numpy as np
import pytest

from texture_support import Case, Result, render_cases

from glint.addon.compat import new_material  # noqa: E402
from glint.core.shader import hash as hashes
from glint.core.shader import noise, textures, voronoi
from glint.core.shader.registry import COLOR, FLOAT, NODES, VECTOR

TOLERANCE = 1e-5


def _cpu_flags() -> set:
    try:
        with open("/proc/cpuinfo") as info:
            for line in info:
                if line.startswith("flags"):
                    return set(line.split(":", 1)[1].split())
    except OSError:
        pass
    return set()


#: Blender runs Cycles' AVX2 kernel here (Linux reports the flags; elsewhere assume not).
FUSED_KERNEL = {"avx2", "fma"} <= _cpu_flags()

NOISE, VORONOI, WAVE, MAGIC = ("ShaderNodeTexNoise", "ShaderNodeTexVoronoi",
                               "ShaderNodeTexWave", "ShaderNodeTexMagic")
GRADIENT, CHECKER, BRICK, WHITE = ("ShaderNodeTexGradient", "ShaderNodeTexChecker",
                                   "ShaderNodeTexBrick", "ShaderNodeTexWhiteNoise")
DIMENSIONS = ("1D", "2D", "3D", "4D")
FRACTAL = {"Scale": 3.0, "Detail": 3.4, "Roughness": 0.62, "Lacunarity": 2.3, "Offset": 0.3,
           "Gain": 1.2}
#: Far from the origin: past 100000 noise wraps, past a million it shifts half a cell.
FAR = dict(location=(2.1e6, -3.4e5, 1.2e6), w_offset=2.3e6, w_scale=1.0)


def noise_cases():
    cases = []
    for dimensions in DIMENSIONS:
        for noise_type in noise.NOISE_TYPES:
            cases.append(Case(NOISE, {"noise_dimensions": dimensions, "noise_type": noise_type},
                              FRACTAL))
        cases += [
            Case(NOISE, {"noise_dimensions": dimensions, "normalize": False},
                 dict(FRACTAL, Distortion=0.7)),
            Case(NOISE, {"noise_dimensions": dimensions},
                 {"Scale": 4.0, "Detail": 2.0, "Distortion": 0.7}, vector="generated"),
            Case(NOISE, {"noise_dimensions": dimensions}, {"Scale": 1.0, "Detail": 1.0}, **FAR),
        ]
    cases += [Case(NOISE, {}, {"Scale": 2.0, "Detail": 15.0, "Roughness": 0.7}),
              Case(NOISE, {"noise_type": "HYBRID_MULTIFRACTAL"},
                   {"Scale": 2.0, "Detail": 0.0, "Offset": 0.9, "Gain": 3.0})]
    return cases


def voronoi_cases():
    cases = []
    common = {"Scale": 4.0, "Exponent": 1.7, "Randomness": 0.85}
    for dimensions in DIMENSIONS:
        for feature in ("F1", "F2", "SMOOTH_F1"):
            for metric in voronoi.METRICS if dimensions != "1D" else ("EUCLIDEAN",):
                options = {"voronoi_dimensions": dimensions, "feature": feature,
                           "distance": metric}
                # glibc's powf rounds a few Minkowski distances differently from float64's.
                cases.append(Case(VORONOI, options, common, exact=metric != "MINKOWSKI"))
        for feature in ("DISTANCE_TO_EDGE", "N_SPHERE_RADIUS"):
            cases.append(Case(VORONOI, {"voronoi_dimensions": dimensions, "feature": feature},
                              common))
        for feature in ("F1", "F2", "SMOOTH_F1", "DISTANCE_TO_EDGE"):
            cases.append(Case(VORONOI, {"voronoi_dimensions": dimensions, "feature": feature,
                                        "normalize": True},
                              {"Scale": 3.0, "Detail": 2.6, "Roughness": 0.55,
                               "Lacunarity": 2.3, "Smoothness": 0.7, "Randomness": 0.9}))
        cases.append(Case(VORONOI, {"voronoi_dimensions": dimensions, "distance": "MANHATTAN"},
                          {"Scale": 3.0, "Detail": 3.0, "Roughness": 0.7, "Lacunarity": 1.7}))
    cases += [
        Case(VORONOI, {}, {"Randomness": 0.0, "Detail": 1.0}),
        Case(VORONOI, {"feature": "SMOOTH_F1"}, {"Smoothness": 0.0}),
        Case(VORONOI, {"feature": "F2", "distance": "CHEBYCHEV", "normalize": True},
             {"Randomness": 0.3, "Roughness": 0.0, "Detail": 4.0}),
        Case(VORONOI, {"feature": "DISTANCE_TO_EDGE", "normalize": True},
             {"Randomness": 0.0, "Detail": 0.5}),
        Case(VORONOI, {"distance": "MINKOWSKI", "normalize": True}, {"Exponent": 4.0},
             exact=False),
        Case(VORONOI, {"voronoi_dimensions": "2D", "feature": "SMOOTH_F1"}, {},
             vector="generated"),
        Case(VORONOI, {}, {"Scale": 1.0}, location=(3.0e9, -3.0e9, 1.0e5)),
    ]
    return cases


def other_cases():
    cases = []
    for wave_type, directions in (("BANDS", ("X", "Y", "Z", "DIAGONAL")),
                                  ("RINGS", ("X", "Y", "Z", "SPHERICAL"))):
        key = "bands_direction" if wave_type == "BANDS" else "rings_direction"
        for direction in directions:
            for profile in ("SIN", "SAW", "TRI"):
                # sinf rounds a few values differently from float64's sine.
                cases.append(Case(WAVE, {"wave_type": wave_type, key: direction,
                                         "wave_profile": profile},
                                  {"Scale": 2.0, "Phase Offset": 0.7}, exact=profile != "SIN"))
    cases += [
        Case(WAVE, {}, {"Scale": 2.0, "Distortion": 3.0, "Detail": 3.5, "Detail Scale": 1.5,
                        "Detail Roughness": 0.6}, exact=False),
        Case(WAVE, {"wave_type": "RINGS", "wave_profile": "TRI"},
             {"Scale": 1.5, "Distortion": 5.0, "Detail": 0.0, "Detail Scale": 2.0},
             vector="generated", exact=False),
    ]
    for depth in range(11):
        cases.append(Case(MAGIC, {"turbulence_depth": depth}, {"Scale": 3.0, "Distortion": 1.3},
                          exact=False))
    cases += [Case(MAGIC, {"turbulence_depth": 4}, {"Scale": 2.0, "Distortion": 0.0}),
              Case(MAGIC, {"turbulence_depth": 4}, {"Scale": 40.0, "Distortion": 2.5},
                   location=(50.0, -20.0, 3.0), exact=False)]
    for gradient_type in textures.GRADIENT_TYPES:
        for vector in ("object", "generated"):
            # atan2f rounds a few angles differently from float64's.
            cases.append(Case(GRADIENT, {"gradient_type": gradient_type}, vector=vector,
                              location=(0.2, 0.1, 0.0), scale=(0.8, 0.8, 0.8),
                              exact=gradient_type != "RADIAL",
                              name=f"Gradient {gradient_type}, {vector}"))
    cases += [
        Case(CHECKER, {}, {"Scale": 3.0, "Color1": (0.9, 0.2, 0.1), "Color2": (0.1, 0.3, 0.8)}),
        Case(CHECKER, {}, {"Scale": 7.0}, vector="generated"),
        Case(CHECKER, {}, {"Scale": 1.0}, location=(3.0e9, -1.0e5, 2.0)),
        Case(BRICK, {}, {"Scale": 3.0}),
        Case(BRICK, {}, {"Scale": 3.0, "Mortar Smooth": 0.0}, vector="generated"),
        Case(BRICK, {"offset": 0.3, "offset_frequency": 3, "squash": 1.7, "squash_frequency": 2},
             {"Scale": 4.0, "Bias": 0.3, "Mortar Size": 0.05, "Mortar Smooth": 0.6,
              "Brick Width": 0.7, "Row Height": 0.3, "Color1": (0.9, 0.3, 0.1),
              "Color2": (0.2, 0.6, 0.3), "Mortar": (0.1, 0.1, 0.4)}, exact=False),
        Case(BRICK, {"offset": 1.0, "offset_frequency": 1, "squash": 0.5, "squash_frequency": 3},
             {"Scale": 6.0, "Bias": -0.4, "Mortar Size": 0.1, "Mortar Smooth": 1.0},
             location=(-3.0, -2.0, 0.0)),
    ]
    # The Texture Mapping (sidebar): Glint builds its matrix in float64, Cycles in float32.
    for vector_type in ("POINT", "TEXTURE", "VECTOR", "NORMAL"):
        mapping = dict(vector_type=vector_type, translation=(0.3, -0.2, 0.5),
                       rotation=(0.4, -0.7, 1.1), scale=(1.5, 0.8, -1.2))
        cases.append(Case(CHECKER, {}, {"Scale": 2.0}, texture_mapping=mapping, exact=False))
        if vector_type == "NORMAL":  # a unit vector: the spherical gradient's 0.999999 - 1
            cases.append(Case(GRADIENT, {"gradient_type": "LINEAR"}, texture_mapping=mapping,
                              exact=False))
        else:
            # Only Fac: the Color's channels sample at the point plus 100 to 200, where the
            # float32 sum rounds to 1.5e-5 and so turns the mapping's last-bit differences
            # into steps of that size.
            cases.append(Case(NOISE, {}, {"Scale": 3.0}, texture_mapping=mapping, exact=False,
                              compared=("Fac",)))
    cases.append(Case(VORONOI, {}, {"Scale": 3.0}, exact=False, texture_mapping=dict(
        mapping_x="Z", mapping_y="NONE", mapping_z="X", scale=(0.0, 2.0, 1.0),
        vector_type="TEXTURE")))
    return cases


def white_noise_cases():
    cases = [Case(WHITE, {"noise_dimensions": dimensions}, location=(1.5, -2.0, 0.5),
                  scale=(3.0, 3.0, 3.0)) for dimensions in DIMENSIONS]
    return cases + [Case(WHITE, {}, vector="socket"), Case(WHITE, {}, **FAR),
                    Case(WHITE, {}, rotation=(0.0, 0.0, 0.0), name="object centres")]


FAMILIES = {"noise": noise_cases(), "voronoi": voronoi_cases(), "others": other_cases(),
            "white noise": white_noise_cases()}


@pytest.fixture(scope="module")
def rendered():
    """{family: [Result]}: each family rendered once, on first use."""
    done = {}

    def results(family):
        if family not in done:
            done[family] = render_cases(FAMILIES[family])
        return done[family]

    return results


def on_a_jump(result: Result, identifier: str, ours) -> np.ndarray:
    """Pixels where Glint's output jumps by more than the tolerance when the coordinate
    (Vector or W) moves by four ulps along an axis."""
    jumps = np.zeros(ours.shape[-1], bool)
    for axis in range(4):
        for sign in (-1, 1):
            vector, w = result.vector.copy(), result.w.copy()
            moved = vector[axis] if axis < 3 else w
            moved += sign * 4 * np.spacing(np.abs(moved))
            nudged = dataclasses.replace(result, vector=vector, w=w).glint()[identifier]
            change = np.abs(np.asarray(nudged) - ours)
            jumps |= (change > TOLERANCE * (1 + np.abs(ours))).reshape(-1, jumps.size).any(0)
    return jumps


def assert_matches_cycles(result: Result):
    label = result.case.label()
    ours = result.glint()
    assert set(ours) == set(result.outputs) and ours, label
    for identifier, theirs in result.outputs.items():
        if result.case.compared and identifier not in result.case.compared:
            continue
        mine = np.asarray(ours[identifier], np.float32)
        assert mine.shape == theirs.shape, (label, identifier)
        assert np.isfinite(theirs).all(), (label, identifier)
        if result.case.exact and FUSED_KERNEL:
            differ = mine != theirs
            assert not differ.any(), (
                f"{label} {identifier}: {differ.sum()} of {differ.size} values differ from "
                f"Cycles', by up to {np.abs(mine - theirs).max():.3g}")
            continue
        error = np.abs(mine - theirs)
        wrong = (error > TOLERANCE * (1 + np.abs(theirs))).reshape(-1, mine.shape[-1]).any(0)
        if wrong.any():
            wrong &= ~on_a_jump(result, identifier, mine)
        assert not wrong.any(), (
            f"{label} {identifier}: {wrong.sum()} of {wrong.size} pixels off by up to "
            f"{error.reshape(-1, mine.shape[-1])[:, wrong].max():.3g}")


def _ids(cases):
    return [f"{index}-{case.label()}" for index, case in enumerate(cases)]


@pytest.mark.cycles
@pytest.mark.parametrize("index", range(len(FAMILIES["noise"])), ids=_ids(FAMILIES["noise"]))
def test_noise_matches_cycles(rendered, index):
    assert_matches_cycles(rendered("noise")[index])


@pytest.mark.cycles
@pytest.mark.parametrize("index", range(len(FAMILIES["voronoi"])),
                         ids=_ids(FAMILIES["voronoi"]))
def test_voronoi_matches_cycles(rendered, index):
    assert_matches_cycles(rendered("voronoi")[index])


@pytest.mark.cycles
@pytest.mark.parametrize("index", range(len(FAMILIES["others"])), ids=_ids(FAMILIES["others"]))
def test_wave_magic_gradient_checker_and_brick_match_cycles(rendered, index):
    assert_matches_cycles(rendered("others")[index])


@pytest.mark.cycles
@pytest.mark.parametrize("index", range(len(FAMILIES["white noise"])),
                         ids=_ids(FAMILIES["white noise"]))
def test_white_noise_hashes_are_cycles_bit_for_bit(rendered, index):
    """Integer hashes of the coordinates' float32 bits: the same on every CPU."""
    result = rendered("white noise")[index]
    ours = result.glint()
    for identifier, theirs in result.outputs.items():
        np.testing.assert_array_equal(ours[identifier], theirs, err_msg=identifier)
    distinct = len(np.unique(result.outputs["Value"]))
    if result.case.vector == "socket":
        assert distinct == 1  # an unlinked Vector is the socket's value, not a coordinate
    else:
        assert distinct > result.w.size // 2


@pytest.mark.cycles
def test_the_aovs_hold_the_coordinates_of_each_pixels_centre(rendered):
    """The comparison evaluates Glint at the coordinates Cycles wrote: check that they are
    each pixel centre's, on the tilted plane z = 0.3 x - 0.2 y of every tile (object space
    [-1, 1]^2; its Generated coordinate is that box mapped to [0, 1]^3, z spanning
    [-0.5, 0.5]), to the float32 rounding of Cycles' hit points: world coordinates up to 8
    carry ulps of 1e-6, doubled by the tiles' 0.5 scale on the way back to object space."""
    named = {result.case.name: result
             for result in rendered("white noise") + rendered("others")}
    tile = named["object centres"].shape[0]
    centres = (np.arange(tile) + 0.5) / tile * 2 - 1
    x, y = np.meshgrid(centres, -centres)
    expected = np.stack([x.ravel(), y.ravel(), 0.3 * x.ravel() - 0.2 * y.ravel()])
    np.testing.assert_allclose(named["object centres"].vector, expected, atol=5e-6)
    generated = (expected + [[1.0], [1.0], [0.5]]) / [[2.0], [2.0], [1.0]]
    np.testing.assert_allclose(named["Gradient LINEAR, generated"].vector, generated, atol=5e-6)


@pytest.mark.cycles
def test_voronoi_colours_are_cycles_bit_for_bit_on_any_cpu(rendered):
    """A Voronoi F1 colour is a PCG hash of the winning cell: integer arithmetic, whatever
    kernel Cycles runs, once the same cell wins (it does away from cell borders)."""
    for result in rendered("voronoi"):
        options = result.case.options
        if options.get("feature", "F1") != "F1" or result.case.inputs.get("Detail", 0) != 0:
            continue
        ours = result.glint()["Color"]
        same = (ours == result.outputs["Color"]).all(axis=0)
        assert same.mean() > 0.99, result.case.label()


# ---- hashes against lookup3 itself -----------------------------------------------------

def _lookup3_hashlittle(key: bytes, initval: int) -> int:
    """Bob Jenkins' hashlittle (lookup3.c), written out on Python ints: the reference the
    array hashes are checked against."""
    mask = 0xFFFFFFFF

    def rot(x, k):
        return ((x << k) | (x >> (32 - k))) & mask

    a = b = c = (0xDEADBEEF + len(key) + initval) & mask
    words = [int.from_bytes(key[i:i + 4].ljust(4, b"\0"), "little")
             for i in range(0, len(key), 4)]
    tail = len(key)
    while tail > 12:
        a, b, c = (a + words[0]) & mask, (b + words[1]) & mask, (c + words[2]) & mask
        a = (a - c) & mask; a ^= rot(c, 4); c = (c + b) & mask
        b = (b - a) & mask; b ^= rot(a, 6); a = (a + c) & mask
        c = (c - b) & mask; c ^= rot(b, 8); b = (b + a) & mask
        a = (a - c) & mask; a ^= rot(c, 16); c = (c + b) & mask
        b = (b - a) & mask; b ^= rot(a, 19); a = (a + c) & mask
        c = (c - b) & mask; c ^= rot(b, 4); b = (b + a) & mask
        words, tail = words[3:], tail - 12
    if tail == 0:
        return c
    last = words + [0, 0, 0]
    # The final words, masked to the bytes the key still has.
    kept = [(last[i] & ((1 << (8 * min(4, max(0, tail - 4 * i)))) - 1)) for i in range(3)]
    a, b, c = (a + kept[0]) & mask, (b + kept[1]) & mask, (c + kept[2]) & mask
    c ^= b; c = (c - rot(b, 14)) & mask
    a ^= c; a = (a - rot(c, 11)) & mask
    b ^= a; b = (b - rot(a, 25)) & mask
    c ^= b; c = (c - rot(b, 16)) & mask
    a ^= c; a = (a - rot(c, 4)) & mask
    b ^= a; b = (b - rot(a, 14)) & mask
    c ^= b; c = (c - rot(b, 24)) & mask
    return c


def test_lookup3_reference_gives_bob_jenkins_published_values():
    # lookup3.c's driver5() prints these.
    assert _lookup3_hashlittle(b"", 0) == 0xDEADBEEF
    assert _lookup3_hashlittle(b"", 0xDEADBEEF) == 0xBD5B7DDE
    assert _lookup3_hashlittle(b"Four score and seven years ago", 0) == 0x17770551
    assert _lookup3_hashlittle(b"Four score and seven years ago", 1) == 0xCD628161


def test_uint_hashes_are_lookup3_of_their_words():
    """Cycles' hash_uint<k>(x...) is hashlittle of the k little-endian words with initval
    13, for any words (wrapping, sign bits, zero)."""
    rng = np.random.default_rng(7)
    special = np.array([[0, 1, 2 ** 31, 2 ** 32 - 1]] * 4, np.uint64)  # each in every word
    words = np.concatenate([rng.integers(0, 2 ** 32, (4, 60), dtype=np.uint64), special],
                           axis=1).astype(np.uint32)
    functions = (hashes.hash_uint, hashes.hash_uint2, hashes.hash_uint3, hashes.hash_uint4)
    for count, function in enumerate(functions, start=1):
        ours = function(*words[:count])
        assert ours.dtype == np.uint32
        for column in range(words.shape[1]):
            key = b"".join(int(words[row, column]).to_bytes(4, "little") for row in range(count))
            assert int(ours[column]) == _lookup3_hashlittle(key, 13), (count, column)


def test_float_hashes_hash_the_float32_bits():
    values = np.array([0.0, -0.0, 1.5, -3.25e7, np.float32(np.pi)], np.float32)
    np.testing.assert_array_equal(hashes.hash_float_to_float(values),
                                  hashes.hash_uint_to_float(values.view(np.uint32)))
    assert hashes.hash_float_to_float(0.0) != hashes.hash_float_to_float(-0.0)
    unit = hashes.uint_to_float_incl(np.array([0, 1, 2 ** 32 - 1], np.uint32))
    np.testing.assert_array_equal(unit, [0.0, 2.0 ** -32, 1.0])


# ---- node functions: registration, broadcasting, bad options ---------------------------

_SOCKET_TYPES = {"VALUE": FLOAT, "VECTOR": VECTOR, "RGBA": COLOR}


@pytest.mark.parametrize("kind", [NOISE, VORONOI, WAVE, MAGIC, GRADIENT, CHECKER, BRICK, WHITE])
def test_registered_sockets_and_options_are_blenders(kind):
    material = new_material("sockets")
    try:
        node = material.node_tree.nodes.new(kind)
        spec = NODES[kind]
        assert [(s.identifier, _SOCKET_TYPES[s.type]) for s in node.inputs] == list(spec.inputs)
        assert [(s.identifier, _SOCKET_TYPES[s.type]) for s in node.outputs] == list(spec.outputs)
        for option in spec.options:
            assert option in node.bl_rna.properties, option
        assert spec.implicit == ({} if kind == WHITE else {"Vector": "generated"})
    finally:
        bpy.data.materials.remove(material)


def test_enum_options_are_blenders():
    material = new_material("enums")
    try:
        nodes = material.node_tree.nodes
        items = lambda kind, name: {item.identifier for item in  # noqa: E731
                                    nodes.new(kind).bl_rna.properties[name].enum_items}
        assert items(NOISE, "noise_type") == set(noise.NOISE_TYPES)
        assert items(VORONOI, "feature") == set(voronoi.FEATURES)
        assert items(VORONOI, "distance") == set(voronoi.METRICS)
        assert items(WAVE, "wave_profile") == set(textures.WAVE_PROFILES)
        assert items(WAVE, "bands_direction") == set(textures.BANDS_DIRECTIONS)
        assert items(WAVE, "rings_direction") == set(textures.RINGS_DIRECTIONS)
        assert items(GRADIENT, "gradient_type") == set(textures.GRADIENT_TYPES)
    finally:
        bpy.data.materials.remove(material)


def _constants(spec, **values):
    """A node's inputs as constants: 0-d floats, (3, 1) vectors and colours."""
    arguments = []
    for identifier, kind in spec.inputs:
        value = values.get(identifier, 0.5 if kind == FLOAT else (0.3, -0.7, 1.9))
        arguments.append(np.asarray(value, np.float32).reshape(3, 1) if kind != FLOAT
                         else np.asarray(value, np.float32))
    return arguments


@pytest.mark.parametrize("kind,options", [
    (NOISE, {"noise_dimensions": "4D", "noise_type": "HETERO_TERRAIN"}),
    (VORONOI, {"voronoi_dimensions": "3D", "feature": "SMOOTH_F1"}),
    (WAVE, {"wave_type": "RINGS"}), (MAGIC, {"turbulence_depth": 3}),
    (GRADIENT, {"gradient_type": "RADIAL"}), (CHECKER, {}), (BRICK, {}),
    (WHITE, {"noise_dimensions": "4D"})])
def test_constant_inputs_give_one_value_that_broadcasts(kind, options):
    """A constant coordinate (a (3, 1) vector, 0-d floats) gives outputs that broadcast to
    (n,) and (3, n), equal to the same coordinate repeated per point."""
    spec = NODES[kind]
    constant = spec.function(None, *_constants(spec, Scale=2.0, Detail=2.5), **options)
    repeated = [np.repeat(a, 5, axis=-1) if a.ndim else np.full(5, a)
                for a in _constants(spec, Scale=2.0, Detail=2.5)]
    per_point = spec.function(None, *repeated, **options)
    for (identifier, kind_), one, many in zip(spec.outputs, constant, per_point):
        shape = (5,) if kind_ == FLOAT else (3, 5)
        np.testing.assert_array_equal(np.broadcast_to(one, shape), many, err_msg=identifier)


@pytest.mark.parametrize("kind,options,varying", [
    (NOISE, {"noise_type": "FBM"}, ("Detail", "Roughness", "Distortion")),
    (NOISE, {"noise_type": "HYBRID_MULTIFRACTAL"}, ("Detail", "Gain", "Offset")),
    (NOISE, {"noise_type": "RIDGED_MULTIFRACTAL", "noise_dimensions": "2D"}, ("Detail",)),
    (VORONOI, {"feature": "SMOOTH_F1", "normalize": True}, ("Detail", "Smoothness",
                                                             "Roughness")),
    (VORONOI, {"feature": "DISTANCE_TO_EDGE", "voronoi_dimensions": "2D"}, ("Detail",)),
    (WAVE, {}, ("Distortion", "Detail")),
    (MAGIC, {}, ("Distortion",)),
    (BRICK, {}, ("Mortar Smooth", "Brick Width"))])
def test_parameters_that_differ_per_point_give_each_point_its_own_value(kind, options,
                                                                        varying):
    """A linked Detail, Smoothness... is an array: each point must get what it would with
    its value as a constant (fractal octaves run per point)."""
    spec = NODES[kind]
    rng = np.random.default_rng(3)
    values = {"Detail": [0.0, 1.0, 2.5, 4.0, 0.3, 15.0], "Roughness": [0.0, 0.5, 0.8, 1.0,
                                                                         0.2, 0.6],
              "Distortion": [0.0, 0.4, 0.0, 1.5, 2.0, 0.1], "Gain": [0.5, 1.0, 2.0, 4.0, 0.1, 1.0],
              "Offset": [0.0, 0.5, 1.0, -0.3, 0.2, 0.9], "Smoothness": [0.0, 0.3, 1.0, 0.7, 0.0,
                                                                       0.1],
              "Mortar Smooth": [0.0, 0.2, 1.0, 0.5, 0.0, 0.05],
              "Brick Width": [0.5, 0.3, 0.7, 0.45, 1.0, 0.6]}
    count = 6
    vector = rng.uniform(-2, 2, (3, count)).astype(np.float32)
    base = {"Vector": vector, "W": rng.uniform(-2, 2, count).astype(np.float32), "Scale": 3.0}
    arrays = dict(base, **{name: np.array(values[name], np.float32) for name in varying})
    together = spec.function(None, *_constants_or(spec, arrays), **options)
    for point in range(count):
        alone = dict(base, Vector=vector[:, point:point + 1], W=base["W"][point],
                     **{name: values[name][point] for name in varying})
        single = spec.function(None, *_constants_or(spec, alone), **options)
        for (identifier, kind_), many, one in zip(spec.outputs, together, single):
            many = np.broadcast_to(many, ((count,) if kind_ == FLOAT else (3, count)))
            np.testing.assert_array_equal(many[..., point], np.ravel(one),
                                          err_msg=f"{identifier} at point {point}")


def _constants_or(spec, values):
    arguments = _constants(spec)
    for position, (identifier, kind) in enumerate(spec.inputs):
        if identifier in values:
            value = np.asarray(values[identifier], np.float32)
            arguments[position] = value.reshape(3, -1) if kind != FLOAT and value.ndim < 2 \
                else value
    return arguments


@pytest.mark.parametrize("kind,option,value", [
    (NOISE, "noise_type", "PERLIN"), (NOISE, "noise_dimensions", "5D"),
    (VORONOI, "feature", "F3"), (VORONOI, "distance", "EUCLID"),
    (WAVE, "wave_profile", "SQUARE"), (GRADIENT, "gradient_type", "CONE"),
    (WHITE, "noise_dimensions", "0D")])
def test_an_unknown_option_is_named_in_one_line(kind, option, value):
    spec = NODES[kind]
    with pytest.raises(ValueError) as raised:
        spec.function(None, *_constants(spec), **{option: value})
    message = str(raised.value)
    assert kind in message and option in message and repr(value) in message
    assert "\n" not in message


@pytest.mark.parametrize("kind,options,read", [
    (NOISE, {"noise_dimensions": "3D"}, "Fac"), (NOISE, {"noise_dimensions": "1D"}, "Fac"),
    (VORONOI, {"feature": "F1"}, "Distance"), (VORONOI, {"feature": "SMOOTH_F1"}, "Position"),
    (VORONOI, {"feature": "F2", "voronoi_dimensions": "2D"}, "Distance")])
def test_outputs_not_needed_are_skipped_and_the_rest_unchanged(kind, options, read):
    spec = NODES[kind]
    rng = np.random.default_rng(5)
    arguments = _constants(spec, Scale=4.0, Detail=1.5)
    arguments[0] = rng.uniform(-3, 3, (3, 400)).astype(np.float32)
    everything = dict(zip([i for i, _ in spec.outputs], spec.function(None, *arguments,
                                                                      **options)))
    some = dict(zip([i for i, _ in spec.outputs],
                    spec.function(None, *arguments, needed={read}, **options)))
    np.testing.assert_array_equal(some[read], everything[read])
    assert np.any(everything["Color"] != 0)
    assert not np.any(some["Color"])


@pytest.mark.parametrize("dimensions", [1, 2, 3, 4])
def test_unsigned_noise_is_the_normalized_single_octave(dimensions):
    """noise() (Cycles' noise_<d>d) is what the Noise node's Fac gives with Detail 0, which
    the renders above check against Cycles."""
    points = np.random.default_rng(dimensions).uniform(-50, 50, (dimensions, 500))
    points = points.astype(np.float32)
    unsigned = noise.noise(points)
    assert 0 <= unsigned.min() and unsigned.max() <= 1 and unsigned.std() > 0.05
    np.testing.assert_array_equal(unsigned, noise.noise_fbm(points, np.float32(0.0),
                                                            np.float32(0.5), np.float32(2.0),
                                                            True))
