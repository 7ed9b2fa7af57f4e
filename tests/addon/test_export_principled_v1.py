"""Exporter: Blender 3.x's Principled BSDF sockets -> the principled kind with PrincipledV1 inputs
(mcrt_addon/export/materials.py _principled_v1).  bpy 5.0 has no 3.x node, so a stand-in node with
3.4's sockets and defaults is read with the table's version set to (3, 4); Blender 3.4 itself
exports real nodes in tests/addon/test_agreement_blender34.py."""
from types import SimpleNamespace

import pytest

from engine.scene import model
from engine.materials.table import PRINCIPLED_V1, scatter_kind
from mcrt_addon.export.materials import MaterialTable

DEFAULTS_34 = {"Base Color": (0.8, 0.8, 0.8, 1.0), "Subsurface": 0.0, "Subsurface Color": (0.8, 0.8, 0.8, 1.0),
               "Metallic": 0.0, "Specular": 0.5, "Specular Tint": 0.0, "Roughness": 0.5, "Anisotropic": 0.0,
               "Anisotropic Rotation": 0.0, "Sheen": 0.0, "Sheen Tint": 0.5, "Clearcoat": 0.0,
               "Clearcoat Roughness": 0.03, "IOR": 1.45, "Transmission": 0.0, "Transmission Roughness": 0.0,
               "Emission": (0.0, 0.0, 0.0, 1.0), "Emission Strength": 1.0, "Alpha": 1.0,
               "Normal": (0.0, 0.0, 0.0), "Clearcoat Normal": (0.0, 0.0, 0.0), "Tangent": (0.0, 0.0, 0.0)}


def node_34(distribution="GGX", linked=(), **values):
    inputs = {name: SimpleNamespace(name=name, default_value=values.get(name.replace(" ", "_"), value),
                                    is_linked=name in linked)
              for name, value in DEFAULTS_34.items()}
    return SimpleNamespace(name="Principled BSDF", bl_idname="ShaderNodeBsdfPrincipled", inputs=inputs,
                           distribution=distribution)


def export_34(node):
    warnings = []
    table = MaterialTable(model, warnings, version=(3, 4))
    return table._principled_v1(SimpleNamespace(name="Mat"), node), warnings


def test_the_default_node_is_principled_v1_without_warnings():
    m, warnings = export_34(node_34())
    assert warnings == [] and scatter_kind(m) == PRINCIPLED_V1
    assert m.principled == model.PrincipledV1(clearcoat_roughness=0.03)
    assert m.roughness == 0.5 and m.ior == pytest.approx(1.45) and not m.multiscatter
    assert m.color == pytest.approx((0.8, 0.8, 0.8))


def test_the_sockets_reach_the_inputs():
    m, warnings = export_34(node_34("MULTI_GGX", Metallic=0.7, Specular=0.9, Specular_Tint=0.4, Sheen=0.6,
                                    Sheen_Tint=0.2, Clearcoat=0.8, Clearcoat_Roughness=0.2, Roughness=0.3))
    p = m.principled
    assert (p.metallic, p.specular, p.specular_tint, p.sheen, p.sheen_tint, p.clearcoat) == \
        pytest.approx((0.7, 0.9, 0.4, 0.6, 0.2, 0.8))
    assert p.clearcoat_roughness == pytest.approx(0.2) and m.multiscatter and m.roughness == pytest.approx(0.3)
    assert warnings == []


def test_what_is_not_modelled_is_named():
    m, warnings = export_34(node_34(Subsurface=0.5, Subsurface_Color=(0.0, 0.0, 0.8, 1.0), Transmission=0.2,
                                    Alpha=0.5, linked=("Clearcoat Normal",)))
    named = " | ".join(warnings)
    for text in ("'Subsurface' 0.5", "'Alpha' 0.5", "'Clearcoat Normal' is linked"):
        assert text in named, warnings
    assert "Transmission" not in named, warnings          # modelled: engine/materials/principled_v1_glass.py
    assert all(w.startswith("Material 'Mat', node 'Principled BSDF'") for w in warnings)
    assert m.color == pytest.approx((0.4, 0.4, 0.8))     # base mixed with the subsurface colour, as Cycles' fallback
    assert m.principled.transmission == pytest.approx(0.2)


@pytest.mark.parametrize("transmission, roughness", [(1.0, 0.0), (0.5, 0.3)])
def test_transmission_stays_on_principled_v1(transmission, roughness):
    """Transmission is 3.4's glass closures of the Principled (it was exported as smooth glass)."""
    m, warnings = export_34(node_34(Transmission=transmission, Roughness=roughness, Transmission_Roughness=0.2))
    assert scatter_kind(m) == PRINCIPLED_V1 and m.ior == pytest.approx(1.45) and warnings == []
    assert m.principled.transmission == pytest.approx(transmission) and m.roughness == pytest.approx(roughness)
    assert m.principled.transmission_roughness == pytest.approx(0.2)
