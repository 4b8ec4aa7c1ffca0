"""What is simulated: the case files, and the scenes they describe (harness.scenes.base: the Scene protocol and its
registry), each with its parsing, truth, metrics and checks against theory: the rigid body with a fixed point
(rigid_body.py) and the sliding ladder (sliding_ladder.py)."""
from importlib import import_module

from .base import SCENES, Scene, kinds, register, scene, scene_of, unregister  # noqa: F401 (this package's API)

for _module in SCENES.builtins:  # the built-in scenes register at import, the plug-ins when the kinds are first read
    import_module(_module)
