"""The node-graph room of the Cycles agreement tests (tests/nodes/test_agreement_nodes.py): the
"node_room" scene of sample_blends/make_samples.py, written to a .blend in the running bpy."""
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(HERE)), "sample_blends"))

import make_samples as ms  # noqa: E402

SCALE = ms.NODE_ROOM_SCALE


def build(path, resolution=(64, 64)):
    """The node room at `resolution`, saved as `path` (returned)."""
    made = ms.make("node_room", os.path.dirname(path), tuple(resolution))
    if os.path.abspath(made) != os.path.abspath(path):
        os.replace(made, path)
    return path
