import os
import sys

from .cli import main

code = main()
sys.stdout.flush()
sys.stderr.flush()
# Leave without Blender's exit handling: nothing of the user's scene is saved on the way out
# (Blender writes quit.blend into its temporary directory when it exits).
os._exit(code if isinstance(code, int) else 1)
