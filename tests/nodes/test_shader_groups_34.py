"""Blender 3.4 (Debian's /usr/bin/blender, tests/addon/blender34.py): a Principled BSDF (3.4's v1)
inside a shader group, nested and used with two sets of inputs, exports exactly as the same nodes
ungrouped (tests/nodes/shader_groups_34.py); CONTROL: the group with an inner link changed does not."""
import json
import os
import subprocess
import sys

import pytest

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(os.path.dirname(HERE), "addon"))

pytestmark = pytest.mark.slow


def test_shader_group_exports_like_the_ungrouped_nodes_in_34(tmp_path):
    from blender34 import BLENDER34, blender_environment
    if BLENDER34 is None:
        pytest.skip("no `blender` binary (apt-get install blender)")
    out = str(tmp_path / "groups34.json")
    subprocess.run([BLENDER34, "-b", "--factory-startup", "--python-use-system-env",
                    "--python", os.path.join(HERE, "shader_groups_34.py"), "--", out],
                   env=blender_environment(), check=True, capture_output=True, timeout=300)
    with open(out) as f:
        r = json.load(f)
    assert r["version"][:2] == [3, 4]
    assert r["kinds"]["GroupRed"] == "principled"
    assert r["red"] and r["blue"], r
    assert not r["control"], r
    # the same warnings for a grouped material as for its ungrouped twin (none, or those its nodes give)
    assert r["warnings"].get("GroupRed") == r["warnings"].get("PlainRed"), r["warnings"]
    assert r["warnings"].get("NestedBlue") == r["warnings"].get("PlainBlue"), r["warnings"]
