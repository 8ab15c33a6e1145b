"""Color Ramp, the curves, Mix and MixRGB, Invert, Hue/Saturation/Value, Brightness/
Contrast, Gamma, RGB to BW, Blackbody and Wavelength against Cycles, per pixel
(``node_support``: inputs from the plane's Object coordinates, results through AOVs;
tolerances there: float32 arithmetic plus the inputs' own error).  The ramp's table is also
checked against Blender's own ramp evaluation, which Cycles bakes it from."""

from __future__ import annotations

import bpy
import numpy as np
import pytest

from node_support import NodeScene, by_identifier, check_outputs, evaluate, node_options

from glint.addon.compat import new_material  # noqa: E402
from glint.core.shader.colour_nodes import BLEND_MODES, RAMP_TABLE_SIZE, ramp_table  # noqa: E402

BLEND_TYPES = [item.identifier for item in
               bpy.types.ShaderNodeMix.bl_rna.properties["blend_type"].enum_items]
INTERPOLATIONS = ("EASE", "CARDINAL", "LINEAR", "B_SPLINE", "CONSTANT")
HUE_MODES = ("NEAR", "FAR", "CW", "CCW")
#: Stops of the ramps under test: uneven spacing, hues all round the circle, colours past 1.
STOPS = ((0.1, (0.9, 0.1, 0.2, 1.0)), (0.35, (0.1, 0.8, 0.3, 0.5)),
         (0.42, (0.2, 0.3, 1.2, 0.8)), (0.8, (1.0, 0.9, 0.1, 0.2)))


def set_stops(ramp, stops):
    while len(ramp.elements) > 1:
        ramp.elements.remove(ramp.elements[-1])
    ramp.elements[0].position, ramp.elements[0].color = stops[0]
    for position, colour in stops[1:]:
        ramp.elements.new(position).color = colour


def test_every_blend_mode_is_registered():
    assert set(BLEND_TYPES) == set(BLEND_MODES)


def test_ramp_table_is_blenders_ramp_at_cycles_positions():
    """The table Cycles bakes is Blender's ramp at i / 256; ours is made from the stops for
    every interpolation, colour mode and hue direction, and ramps of 1 to 5 random stops."""
    material = new_material("ramps")
    ramp_node = material.node_tree.nodes.new("ShaderNodeValToRGB")
    ramp = ramp_node.color_ramp
    rng = np.random.default_rng(7)
    positions = np.arange(RAMP_TABLE_SIZE, dtype=np.float32) / np.float32(RAMP_TABLE_SIZE - 1)
    for count in (1, 2, 3, 5, 5):
        stops = [(float(rng.uniform(0, 1)), tuple(rng.uniform(0, 1.2, 4))) for _ in range(count)]
        set_stops(ramp, stops)
        for interpolation in INTERPOLATIONS:
            for colour_mode in ("RGB", "HSV", "HSL"):
                for hue in HUE_MODES:
                    ramp.interpolation, ramp.color_mode = interpolation, colour_mode
                    ramp.hue_interpolation = hue
                    options = node_options(ramp_node)
                    table = ramp_table(options["elements"], options["interpolation"],
                                       options["color_mode"], options["hue_interpolation"])
                    blender = np.array([ramp.evaluate(p) for p in positions])
                    # Blender evaluates in float32 (and HSV through its own conversions):
                    # a few float32 steps.
                    np.testing.assert_allclose(table, blender, atol=3e-6, err_msg=(
                        f"{count} stops, {interpolation}, {colour_mode}, {hue}"))
    bpy.data.materials.remove(material)


@pytest.mark.cycles
@pytest.mark.parametrize("colour_mode", ["RGB", "HSV", "HSL"])
def test_color_ramp_matches_cycles(colour_mode):
    """Every interpolation (RGB) or hue direction (HSV, HSL: Blender blends them linearly),
    the factor running past both ends; and a constant ramp's step lands where Cycles'
    257-entry table puts it (its first table entry past the stop)."""
    scene = NodeScene((-0.1, 1.1), (0.0, 1.0))
    cases = []
    variants = INTERPOLATIONS if colour_mode == "RGB" else HUE_MODES
    for variant in variants:
        blender_node = scene.node("ShaderNodeValToRGB")
        ramp = blender_node.color_ramp
        set_stops(ramp, STOPS)
        ramp.color_mode = colour_mode
        if colour_mode == "RGB":
            ramp.interpolation = variant
        else:
            ramp.hue_interpolation = variant
        scene.link(scene.x, blender_node.inputs["Fac"])
        for output in ("Color", "Alpha"):
            cases.append((f"{colour_mode} {variant} {output}", blender_node, output,
                          lambda X, Y, n=blender_node: evaluate(n, scene.points(X, Y),
                                                                Fac=X.ravel())))
    check_outputs(scene, cases)


@pytest.mark.cycles
def test_constant_ramp_steps_at_cycles_table_entries():
    """Factors from 0.49 to 0.51 across the image: a constant ramp's stop at 0.5 switches at
    0.5 in a table of 257 entries (1 / 256 apart), at 0.50196 with 256."""
    scene = NodeScene((0.49, 0.51), (0.0, 1.0))
    blender_node = scene.node("ShaderNodeValToRGB")
    set_stops(blender_node.color_ramp, ((0.0, (0, 0, 0, 1)), (0.5, (1, 0, 0, 1)),
                                        (0.503, (0, 1, 0, 1))))
    blender_node.color_ramp.interpolation = 'CONSTANT'
    scene.link(scene.x, blender_node.inputs["Fac"])
    check_outputs(scene, [("constant", blender_node, "Color",
                           lambda X, Y: evaluate(blender_node, scene.points(X, Y),
                                                 Fac=X.ravel()))])


def shape_curve(curve, points):
    """Move the curve's two points and add the rest: ((x, y), ...)."""
    curve.points[0].location, curve.points[1].location = points[0], points[-1]
    for point in points[1:-1]:
        curve.points.new(*point)


@pytest.mark.cycles
@pytest.mark.parametrize("extend", ["EXTRAPOLATED", "HORIZONTAL"])
def test_curves_match_cycles(extend):
    """RGB Curves (each channel through the combined curve), Vector Curves and Float Curve,
    with inputs past the curves' ends (extrapolated or held) and the factor varying."""
    scene = NodeScene((-0.6, 1.6), (-0.2, 1.2))
    colour = scene.combine(scene.x, scene.y, 0.55)
    cases = []

    def colour_of(X, Y):
        x = X.ravel()
        return np.stack([x, Y.ravel(), np.full_like(x, 0.55)])

    rgb = scene.node("ShaderNodeRGBCurve")
    curves = rgb.mapping.curves
    shape_curve(curves[0], ((0.0, 0.1), (0.4, 0.7), (1.0, 0.9)))
    shape_curve(curves[1], ((0.1, 0.0), (0.6, 0.2), (0.9, 1.0)))
    shape_curve(curves[2], ((0.0, 1.0), (1.0, 0.0)))
    shape_curve(curves[3], ((0.0, 0.0), (0.3, 0.5), (1.0, 1.0)))
    curves[1].points[1].handle_type = 'VECTOR'
    rgb.mapping.extend = extend
    scene.link(colour, rgb.inputs["Color"])
    scene.link(scene.y, rgb.inputs["Fac"])
    cases.append(("RGB Curves", rgb, "Color",
                  lambda X, Y: evaluate(rgb, scene.points(X, Y), Fac=Y.ravel(),
                                        Color=colour_of(X, Y))))

    vector = scene.node("ShaderNodeVectorCurve")
    curves = vector.mapping.curves
    shape_curve(curves[0], ((-1.0, -0.5), (0.2, 0.6), (1.0, 1.0)))
    shape_curve(curves[1], ((-0.5, 1.0), (0.5, -1.0)))
    shape_curve(curves[2], ((-1.0, 0.0), (0.0, 0.8), (0.7, 0.1)))
    curves[2].points[1].handle_type = 'AUTO_CLAMPED'
    vector.mapping.extend = extend
    scene.link(colour, vector.inputs["Vector"])
    vector.inputs["Fac"].default_value = 0.8
    cases.append(("Vector Curves", vector, "Vector",
                  lambda X, Y: evaluate(vector, scene.points(X, Y), Vector=colour_of(X, Y))))

    single = scene.node("ShaderNodeFloatCurve")
    shape_curve(single.mapping.curves[0], ((0.2, 0.9), (0.5, 0.1), (0.9, 0.6)))
    single.mapping.extend = extend
    scene.link(scene.x, single.inputs["Value"])
    scene.link(scene.y, single.inputs["Factor"])
    cases.append(("Float Curve", single, "Value",
                  lambda X, Y: evaluate(single, scene.points(X, Y), Value=X.ravel(),
                                        Factor=Y.ravel())))
    check_outputs(scene, cases)


def colour_pair(scene):
    """Two colours varying over the image, channels from -0.2 to 1.3 (past both ends of
    [0, 1], where dodge, burn and the HSV modes branch), and their values at X, Y."""
    sockets = (scene.combine(scene.x, scene.y, 0.4), scene.combine(scene.y, 0.6, scene.x))

    def values(X, Y):
        x, y = X.ravel(), Y.ravel()
        return (np.stack([x, y, np.full_like(x, 0.4)]), np.stack([y, np.full_like(x, 0.6), x]))
    return sockets, values


@pytest.mark.cycles
@pytest.mark.parametrize("clamp", [False, True], ids=["unclamped", "clamped"])
def test_mix_colour_matches_cycles_for_every_blend_mode(clamp):
    """Mix (colour) with clamp factor and clamp result both off or both on, and the legacy
    MixRGB (its factor always clamped) with Clamp: the factor runs from -0.3 to 1.3."""
    scene = NodeScene((-0.2, 1.3), (-0.2, 1.3))
    (a, b), values = colour_pair(scene)
    factor = scene.node("ShaderNodeMath", operation='MULTIPLY_ADD')
    scene.link(scene.x, factor.inputs[0])
    factor.inputs[1].default_value, factor.inputs[2].default_value = -1.0, 1.0
    cases = []

    def fac(X):
        return -X.ravel() + 1.0

    for blend_type in BLEND_TYPES:
        mixed = scene.node("ShaderNodeMix", data_type='RGBA', blend_type=blend_type,
                           clamp_factor=clamp, clamp_result=clamp)
        sockets = by_identifier(mixed.inputs)
        scene.link(factor.outputs[0], sockets["Factor_Float"])
        scene.link(a, sockets["A_Color"])
        scene.link(b, sockets["B_Color"])

        def compute(X, Y, n=mixed):
            first, second = values(X, Y)
            return evaluate(n, scene.points(X, Y), Factor_Float=fac(X), A_Color=first,
                            B_Color=second)
        cases.append((f"Mix {blend_type}", mixed, "Result_Color", compute))
        legacy = scene.node("ShaderNodeMixRGB", blend_type=blend_type, use_clamp=clamp)
        scene.link(factor.outputs[0], legacy.inputs["Fac"])
        scene.link(a, legacy.inputs["Color1"])
        scene.link(b, legacy.inputs["Color2"])

        def compute_legacy(X, Y, n=legacy):
            first, second = values(X, Y)
            return evaluate(n, scene.points(X, Y), Fac=fac(X), Color1=first, Color2=second)
        cases.append((f"MixRGB {blend_type}", legacy, "Color", compute_legacy))
    check_outputs(scene, cases)


@pytest.mark.cycles
def test_mix_float_and_vector_match_cycles():
    """Float and vector mixes, uniform and per-component factors, clamped or not."""
    scene = NodeScene((-0.5, 1.5), (-0.5, 1.5))
    (a, b), values = colour_pair(scene)
    cases = []
    for clamp in (False, True):
        floats = scene.node("ShaderNodeMix", data_type='FLOAT', clamp_factor=clamp)
        sockets = by_identifier(floats.inputs)
        scene.link(scene.x, sockets["Factor_Float"])
        scene.link(scene.y, sockets["A_Float"])
        sockets["B_Float"].default_value = 2.5
        cases.append((f"float, clamp {clamp}", floats, "Result_Float",
                      lambda X, Y, n=floats: evaluate(n, scene.points(X, Y),
                                                      Factor_Float=X.ravel(),
                                                      A_Float=Y.ravel())))
        for factor_mode in ("UNIFORM", "NON_UNIFORM"):
            vectors = scene.node("ShaderNodeMix", data_type='VECTOR', factor_mode=factor_mode,
                                 clamp_factor=clamp)
            sockets = by_identifier(vectors.inputs)
            scene.link(scene.x, sockets["Factor_Float"])
            scene.link(b, sockets["Factor_Vector"])
            scene.link(a, sockets["A_Vector"])
            sockets["B_Vector"].default_value = (2.0, -1.0, 0.5)

            def compute(X, Y, n=vectors):
                first, second = values(X, Y)
                return evaluate(n, scene.points(X, Y), Factor_Float=X.ravel(),
                                Factor_Vector=second, A_Vector=first)
            cases.append((f"vector {factor_mode}, clamp {clamp}", vectors, "Result_Vector",
                          compute))
    check_outputs(scene, cases)


@pytest.mark.cycles
def test_colour_adjustments_match_cycles():
    """Invert, Hue/Saturation/Value, Brightness/Contrast, Gamma and RGB to BW over colours
    from -0.2 to 1.3, with their factors and parameters varying too."""
    scene = NodeScene((-0.2, 1.3), (-0.2, 1.3))
    (colour, _), values = colour_pair(scene)
    cases = []

    def points_and_colour(X, Y):
        return scene.points(X, Y), values(X, Y)[0]

    invert = scene.node("ShaderNodeInvert")
    scene.link(scene.y, invert.inputs["Fac"])
    scene.link(colour, invert.inputs["Color"])
    cases.append(("Invert", invert, "Color",
                  lambda X, Y: evaluate(invert, scene.points(X, Y), Fac=Y.ravel(),
                                        Color=values(X, Y)[0])))
    for hue, saturation, value, fac in ((0.3, 1.4, 0.8, 1.0), (0.75, 0.6, 1.2, 0.7)):
        hsv = scene.node("ShaderNodeHueSaturation")
        for name, number in (("Hue", hue), ("Saturation", saturation), ("Value", value),
                             ("Fac", fac)):
            hsv.inputs[name].default_value = number
        scene.link(colour, hsv.inputs["Color"])
        cases.append((f"HSV {hue}", hsv, "Color",
                      lambda X, Y, n=hsv: evaluate(n, scene.points(X, Y),
                                                   Color=values(X, Y)[0])))
    bright = scene.node("ShaderNodeBrightContrast")
    scene.link(colour, bright.inputs["Color"])
    scene.link(scene.x, bright.inputs["Bright"])
    scene.link(scene.y, bright.inputs["Contrast"])
    cases.append(("Bright/Contrast", bright, "Color",
                  lambda X, Y: evaluate(bright, scene.points(X, Y), Color=values(X, Y)[0],
                                        Bright=X.ravel(), Contrast=Y.ravel())))
    gamma = scene.node("ShaderNodeGamma")
    scene.link(colour, gamma.inputs["Color"])
    scene.link(scene.y, gamma.inputs["Gamma"])
    cases.append(("Gamma", gamma, "Color",
                  lambda X, Y: evaluate(gamma, scene.points(X, Y), Color=values(X, Y)[0],
                                        Gamma=Y.ravel())))
    grey = scene.node("ShaderNodeRGBToBW")
    scene.link(colour, grey.inputs["Color"])
    cases.append(("RGB to BW", grey, "Val",
                  lambda X, Y: evaluate(grey, scene.points(X, Y), Color=values(X, Y)[0])))
    check_outputs(scene, cases)


def light_colour_cases(scene):
    """Blackbody over 500-16000 K and Wavelength over 370-790 nm (Object x, two ranges
    mapped from it by Map Range, which is exact here: a multiply-add)."""
    cases = []
    for node_type, low, high, socket in (("ShaderNodeBlackbody", 500.0, 16000.0, "Temperature"),
                                         ("ShaderNodeWavelength", 370.0, 790.0, "Wavelength")):
        spread = scene.node("ShaderNodeMath", operation='MULTIPLY_ADD')
        scene.link(scene.x, spread.inputs[0])
        spread.inputs[1].default_value, spread.inputs[2].default_value = high - low, low
        blender_node = scene.node(node_type)
        scene.link(spread.outputs[0], blender_node.inputs[socket])
        cases.append((node_type, blender_node, "Color",
                      lambda X, Y, n=blender_node, s=socket, lo=low, hi=high:
                      evaluate(n, scene.points(X, Y), **{s: X.ravel() * (hi - lo) + lo})))
    return cases


@pytest.mark.cycles
def test_blackbody_and_wavelength_match_cycles_in_rec709():
    scene = NodeScene((0.0, 1.0), (0.0, 1.0))
    check_outputs(scene, light_colour_cases(scene))


@pytest.mark.cycles
def test_working_space_moves_blackbody_wavelength_and_luminance():
    """In a Rec.2020 file Cycles gives Blackbody, Wavelength and RGB to BW in Rec.2020: the
    readers pass that space's matrices and weights (over these inputs the Rec.709 results
    differ from them by up to 2.1, 0.37 and 0.044: far beyond the tolerance)."""
    scene = NodeScene((0.0, 1.0), (0.0, 1.0))
    bpy.ops.wm.set_working_color_space(working_space='Linear Rec.2020', convert_colors=False)
    try:
        cases = light_colour_cases(scene)
        grey = scene.node("ShaderNodeRGBToBW")
        colour = scene.combine(scene.x, scene.y, 0.4)
        scene.link(colour, grey.inputs["Color"])
        cases.append(("RGB to BW", grey, "Val",
                      lambda X, Y: evaluate(grey, scene.points(X, Y), Color=np.stack(
                          [X.ravel(), Y.ravel(), np.full(X.size, 0.4)]))))
        check_outputs(scene, cases)
    finally:
        bpy.ops.wm.set_working_color_space(working_space='Linear Rec.709',
                                           convert_colors=False)
