"""`stereodyn export`: the engine model of a case, to open in the engines' own tools.

Each engine lists the formats it writes (About.export_formats) and writes them (SceneModel.export): the built-ins give
mjcf (the MuJoCo adapter's scene, with an integrator and a timestep in its <option>) and urdf (the Pinocchio adapter's
body, its ball joint as a three-joint gimbal).
"""
from __future__ import annotations

from .scenes import scene_of
from .scenes.cases import Case


class ExportError(ValueError):
    """The case cannot be exported in that format (its adapter cannot model it, or its SDK is missing): exit 2."""


def formats() -> dict[str, str]:
    """format -> the name of the engine that writes it, over every registered engine that loads."""
    from .engines import EngineError, engine_names, get_engine

    found: dict[str, str] = {}
    for name in engine_names():
        try:
            found.update((fmt, name) for fmt in get_engine(name).about.export_formats if fmt not in found)
        except EngineError:
            continue
    return found


def export(case: Case, fmt: str, integrator: str | None = None, dt: float | None = None) -> str:
    """The model text. integrator and dt (default: the engine's choice and the case's first dt) apply to formats
    whose model holds a stepper (MJCF's <option>)."""
    from .engines import UnavailableEngine, get_engine

    writers = formats()
    if fmt not in writers:
        from .engines import engine_names

        unavailable = [n for n in engine_names() if isinstance(get_engine(n), UnavailableEngine)]
        hint = f" (unavailable engines: {', '.join(get_engine(n).reason for n in unavailable)})" if unavailable else ""
        raise ExportError(f"--format: unknown format {fmt!r}; valid: {', '.join(writers)}{hint}")
    engine = get_engine(writers[fmt])
    model = engine.models().get(scene_of(case).kind)  # the engine's model of the case's scene writes it
    if model is None:
        raise ExportError(f"{case.name}: {engine.unmodelled(scene_of(case))}")
    try:
        return model.export(case, fmt, integrator, dt)
    except (KeyError, ValueError) as exc:
        raise ExportError(str(exc).strip("'\"")) from None
