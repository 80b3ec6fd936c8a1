"""Extension points: β/γ strategies, controllers and CLI commands found by entry point.

``meanfield`` never imports the packages built on it (``analysis``, ``verification``).
They extend it the way pytest plugins extend pytest: by declaring entry points in their
distribution's metadata, which ``meanfield`` discovers at run time.  The groups:

``meanfield.beta_gamma``
    ``name = "module:factory"`` with ``factory(scenario) -> BetaGammaStrategy``;
    selectable as ``controller.beta_gamma = name`` in a scenario.
``meanfield.controllers``
    ``name = "module:factory"`` with ``factory(loop) -> controller``, where ``loop`` is
    the :class:`~meanfield.simulate.ClosedLoop` being built and ``controller`` has the
    methods ``robot_inputs(rho, field, t, dt) -> ControlState`` and ``reset()`` of
    :class:`~meanfield.control.BacksteppingController`; selectable as
    ``controller.kind = name``.
``meanfield.commands``
    ``name = "module:register"`` with ``register(subparsers) -> handler``: adds the
    sub-command's parser and returns ``handler(args) -> int`` (the exit status).

This toolkit's own entry points are declared in ``pyproject.toml``.
"""

from __future__ import annotations

from importlib.metadata import EntryPoint, entry_points
from typing import Any

from meanfield.errors import ParameterError

__all__ = ["GROUPS", "available", "load"]

GROUPS = {
    "beta_gamma": "meanfield.beta_gamma",
    "controller": "meanfield.controllers",
    "command": "meanfield.commands",
}
"""Plugin kinds and their entry-point groups."""


def _entry_points(kind: str) -> dict[str, EntryPoint]:
    if kind not in GROUPS:
        raise ParameterError("kind", kind, " or ".join(map(repr, GROUPS)))
    return {ep.name: ep for ep in entry_points(group=GROUPS[kind])}


def available(kind: str) -> tuple[str, ...]:
    """Names of the installed plugins of one kind (``"beta_gamma"``, ``"controller"``, ``"command"``)."""
    return tuple(sorted(_entry_points(kind)))


def load(kind: str, name: str) -> Any:
    """The object a plugin's entry point names (a factory or a registration function).

    Raises
    ------
    ParameterError
        If no installed plugin of that kind has this name.
    """
    eps = _entry_points(kind)
    if name not in eps:
        names = ", ".join(sorted(eps)) or "none installed"
        raise ParameterError(kind, name, f"an installed {kind} plugin ({names})")
    return eps[name].load()
