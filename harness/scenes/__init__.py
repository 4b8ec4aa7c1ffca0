"""What is simulated: the case files, and the scenes they describe (harness.scenes.base: the Scene protocol and its
registry), each with its parsing, truth, metrics and checks against theory: the rigid body with a fixed point
(rigid_body.py) and the sliding ladder (sliding_ladder.py)."""
from .base import Scene, kinds, register, scene, scene_of, unregister  # noqa: F401 (this package's API)
from . import rigid_body, sliding_ladder  # noqa: F401,E402 (registers the built-in scenes)
