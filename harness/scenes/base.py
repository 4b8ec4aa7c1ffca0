"""The Scene protocol and the registry of scenes (DESIGN §7): what a kind of case is, so that the plan, the one run ->
row path (harness.run.measure) and the sweep never branch on a kind.

A scene parses its TOML into a case (a frozen dataclass with name, description, tags, kind, t_end, dt, samples, path),
computes its truth, turns a run's trajectory into the row's metrics and check rows, and says which row columns it
fills. An engine models a scene through the model it declares for the scene's kind (Engine.models()).
"""
from __future__ import annotations

from typing import TYPE_CHECKING, Any, Callable, Protocol

from ...reference import plugins
from ...reference.registry import Registry

if TYPE_CHECKING:
    from ..grid import TimeGrid


class Scene(Protocol):
    """One kind of case (the TOML's top-level `kind`)."""

    kind: str                 # the TOML's `kind` and the key of Engine.models()
    title: str                # in words, for messages: "the sliding ladder"
    needs_truth: bool         # whether truth() computes anything (the sweep's progress names the phase)
    keeps_states: bool        # whether --save-trajectories can write its runs' states (quat, omega)
    work_precision: bool      # whether dt and tolerance ladders, orders and floors apply to its runs
    columns: tuple[str, ...]  # the results.csv columns its rows fill beyond the identity, status and timing ones
    # Optional: the class its models' run() returns (harness.trajectory's Trajectory, SlidingLadderTrajectory); the
    # one run -> row path checks each run's answer against it (harness.run.measure.checked). Absent: any object with
    # a Status, a message and one row of times per sample.
    # trajectory: type

    def parse(self, parser: Any, data: dict) -> Any:
        """The case of a file's TOML (parser: harness.scenes.cases' validator, whose failures name FILE: KEY: RULE)."""

    def truth(self, case: Any, grids: list["TimeGrid"], certify: bool) -> Any:
        """The case's truth on the union of the grids' sample times, or None for a scene that checks each run
        against its own equation."""

    def metrics(self, run: Any, model: Any, traj: Any, grid: "TimeGrid", truth: Any, full: bool,
                rerun: Callable[[Any], Any], keep_states: bool = False) -> dict:
        """The row's columns measured from a run (run: a RunKey) of the engine's model (model: its SceneModel for the
        scene, harness.engines.base; named, not imported, since the engines import the scenes): drifts, errors
        (against truth, when not None), and, when full, the sweep's extras (check rows under checks.ROW_KEY, the invariant series
        under "_series", with keep_states the recorded states under "_states"). rerun(case) runs the same model on
        another case (a perturbed start) on the same grid, for checks that compare two runs."""


_SCENES: dict[str, Scene] = {}
# The scenes' discovery (reference.registry): stereodyn's own modules, then the modules other distributions name under
# the entry-point group (each calls register(scene) at import), loaded when the kinds are first asked for; a plug-in
# that does not import is one warning line, and its cases' kind stays unknown.
ENTRY_POINT_GROUP = "stereodyn.scenes"
SCENES = Registry("scene plug-in", ENTRY_POINT_GROUP, (f"{__package__}.rigid_body", f"{__package__}.sliding_ladder"))


_FLAGS = ("needs_truth", "keeps_states", "work_precision")
_HOOKS = {"parse": "parse(parser, data)", "truth": "truth(case, grids, certify)",
          "metrics": "metrics(run, model, traj, grid, truth, full, rerun, keep_states)"}


def scene_problem(scene: Any) -> str | None:
    """Why an object cannot be a Scene (the protocol above), naming the field and the rule; None when it can."""
    why = plugins.name_problem("kind", getattr(scene, "kind", None))
    if why:
        return why
    if not isinstance(getattr(scene, "title", None), str):
        return "title: must be a string"
    for flag in _FLAGS:
        if not isinstance(getattr(scene, flag, None), bool):
            return f"{flag} = {plugins.shown(getattr(scene, flag, None))}: must be True or False"
    columns = getattr(scene, "columns", None)
    if not isinstance(columns, (tuple, list)) or not all(isinstance(c, str) for c in columns):
        return f"columns = {plugins.shown(columns)}: must be a tuple of column names"
    for hook, signature in _HOOKS.items():
        if not callable(getattr(scene, hook, None)):
            return f"{hook}: missing; a scene defines {signature}"
    trajectory = getattr(scene, "trajectory", None)
    if trajectory is not None and not isinstance(trajectory, type):
        return f"trajectory = {plugins.shown(trajectory)}: must be a class"
    return None


def register(scene: Scene) -> Scene:
    """Make a scene known by its kind (a case file names it with `kind = "..."`). Registering a kind again replaces
    the scene (a test's toy scene, a plug-in's newer version), but a plug-in's scene never takes a built-in's kind (it
    silently changed every built-in case). TypeError, naming the field and the rule, for what is not a Scene or claims
    a built-in's kind (a plug-in's register at import: that plug-in is left out with one warning line naming it, the
    scene it would have replaced stays)."""
    why = scene_problem(scene)
    builtin = _SCENES.get(getattr(scene, "kind", None))
    if why is None and builtin is not None and plugins.own(builtin) and not plugins.own(scene):
        why = f"kind {scene.kind!r} is a built-in scene's; a plug-in's scene takes a kind of its own"
    if why is not None:
        raise TypeError(f"scene {plugins.shown(getattr(scene, 'kind', None))} ({type(scene).__module__}."
                        f"{type(scene).__qualname__}): {why}")
    _SCENES[scene.kind] = scene
    return scene


def unregister(kind: str) -> None:
    _SCENES.pop(kind, None)


def kinds() -> tuple[str, ...]:
    SCENES.load_or_warn()
    return tuple(_SCENES)


def scene(kind: str) -> Scene:
    """The scene of a kind; KeyError naming the known kinds."""
    if kind not in _SCENES:
        SCENES.load_or_warn()
    try:
        return _SCENES[kind]
    except KeyError:
        raise KeyError(f"unknown scene kind {kind!r} (known: {', '.join(_SCENES)})") from None


def scene_of(case: Any) -> Scene:
    """The scene a case belongs to."""
    return scene(case.kind)
