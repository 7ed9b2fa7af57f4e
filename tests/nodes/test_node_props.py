"""mcrt_addon/export/node_props.py without Blender: special_props gives a Color Ramp's and a curve
mapping's props in the documented format, the table sampled where Cycles samples it (257 positions
i / 256 since Blender 4.0, 256 at i / 255 in 3.x; RGB Curves: R, G, B after C), None for other nodes.
(The slow Cycles tests in tests/nodes/ check the tables against Cycles' renders.)"""
from types import SimpleNamespace as NS

import numpy as np

from mcrt_addon.export import node_props


def fake_ramp():
    elements = [NS(position=0.8, color=(1.0, 1.0, 1.0, 1.0)), NS(position=0.2, color=(0.0, 0.5, 0.0, 1.0))]
    return NS(elements=elements, interpolation="EASE", color_mode="RGB", hue_interpolation="NEAR",
              evaluate=lambda x: (x, 2.0 * x, 0.0, 1.0))


class FakeMapping:
    def __init__(self, curves):
        self.curves, self.extend, self.use_clip = curves, "EXTRAPOLATED", True
        self.clip_min_x = self.clip_min_y = 0.0
        self.clip_max_x = self.clip_max_y = 1.0
        self.black_level, self.white_level = (0.0, 0.0, 0.0), (1.0, 1.0, 1.0)
        self.calls = []

    def update(self):
        self.calls.append("update")

    def initialize(self):
        self.calls.append("initialize")

    def evaluate(self, curve, x):
        return curve.scale * x


def fake_curve(x0, x1, scale):
    return NS(points=[NS(location=(x0, 0.0), handle_type="AUTO"), NS(location=(x1, 1.0), handle_type="VECTOR")],
              scale=scale)


def test_color_ramp_props_and_table():
    props = node_props.special_props(NS(bl_idname="ShaderNodeValToRGB", color_ramp=fake_ramp()))
    assert props["elements"] == [(0.2, (0.0, 0.5, 0.0, 1.0)), (0.8, (1.0, 1.0, 1.0, 1.0))]
    assert (props["interpolation"], props["color_mode"], props["hue_interpolation"]) == ("EASE", "RGB", "NEAR")
    table = np.array(props["table"])
    assert table.shape == (257, 4) and np.allclose(table[:, 0], np.arange(257) / 256.0)
    old = node_props.color_ramp_props(fake_ramp(), node_props.table_positions((3, 4)))
    assert np.allclose(np.array(old["table"])[:, 1], 2.0 * np.arange(256) / 255.0)


def test_curve_props_and_tables():
    curves = [fake_curve(0.0, 1.0, 1.0), fake_curve(-0.5, 1.0, 2.0), fake_curve(0.0, 2.0, 3.0), fake_curve(0.0, 1.0, 0.5)]
    mapping = FakeMapping(curves)
    props = node_props.special_props(NS(bl_idname="ShaderNodeRGBCurve", mapping=mapping))
    assert mapping.calls == ["update", "initialize"]
    assert (props["min_x"], props["max_x"], props["extrapolate"]) == (-0.5, 2.0, True)
    xs = -0.5 + np.arange(257) / 256.0 * 2.5
    table = np.array(props["table"])
    assert table.shape == (257, 3)
    assert np.allclose(table, np.stack([0.5 * xs, 1.0 * xs, 1.5 * xs], axis=1))      # R, G, B of C(x)
    assert props["curves"][1]["points"][0] == (-0.5, 0.0, "AUTO") and len(props["curves"]) == 4
    vec = node_props.special_props(NS(bl_idname="ShaderNodeVectorCurve", mapping=FakeMapping(curves[:3])))
    assert np.allclose(np.array(vec["table"])[:, 2], 3.0 * xs) and "black_level" not in vec
    flt = node_props.special_props(NS(bl_idname="ShaderNodeFloatCurve", mapping=FakeMapping(curves[:1])))
    assert np.allclose(flt["table"], np.arange(257) / 256.0) and (flt["min_x"], flt["max_x"]) == (0.0, 1.0)
    assert node_props.special_props(NS(bl_idname="ShaderNodeMath")) is None
