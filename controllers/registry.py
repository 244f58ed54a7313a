"""Registered controllers: name → factory(ControllerContext) → Controller.

The benchmark runs every registered controller. Built-ins are registered on import of
:mod:`controllers`; other packages (the RL agents) register theirs when imported —
:func:`load_plugins` imports the modules in :data:`PLUGIN_MODULES` that are installed.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from .base import Controller, ControllerContext

__all__ = [
    "PLUGIN_MODULES",
    "ControllerSpec",
    "available",
    "load_plugins",
    "make",
    "register",
    "spec",
    "unregister",
]

PLUGIN_MODULES = ("agents",)  # imported by load_plugins() when present


@dataclass(frozen=True)
class ControllerSpec:
    """A registered controller: its factory and a one-line description."""

    name: str
    factory: Callable[[ControllerContext], Controller]
    description: str


_REGISTRY: dict[str, ControllerSpec] = {}


def register(
    name: str,
    factory: Callable[[ControllerContext], Controller],
    description: str,
    *,
    overwrite: bool = False,
) -> None:
    """Register ``factory`` under ``name`` (ValueError if taken and not ``overwrite``)."""
    if not isinstance(name, str) or not name.isidentifier():
        raise ValueError(f"name={name!r}: must be an identifier")
    if not callable(factory):
        raise ValueError(f"factory={factory!r}: must be callable (ControllerContext → Controller)")
    if not isinstance(description, str):
        raise ValueError(f"description={description!r}: must be a string")
    if name in _REGISTRY and not overwrite:
        raise ValueError(f"name={name!r}: already registered")
    _REGISTRY[name] = ControllerSpec(name, factory, description)


def unregister(name: str) -> None:
    """Remove ``name`` (ValueError if not registered)."""
    spec(name)
    del _REGISTRY[name]


def available() -> list[str]:
    """Registered names, in registration order."""
    return list(_REGISTRY)


def spec(name: str) -> ControllerSpec:
    if name not in _REGISTRY:
        raise ValueError(f"controller={name!r}: not registered (available: {', '.join(_REGISTRY)})")
    return _REGISTRY[name]


def make(name: str, env_or_ctx: Any) -> Controller:
    """Build controller ``name`` for a PiezoTurntable env (or a ControllerContext)."""
    ctx = (
        env_or_ctx
        if isinstance(env_or_ctx, ControllerContext)
        else ControllerContext.from_env(env_or_ctx)
    )
    return spec(name).factory(ctx)


def load_plugins() -> list[str]:
    """Import the installed plugin modules (they register controllers); their names."""
    loaded = []
    for mod in PLUGIN_MODULES:
        try:
            importlib.import_module(mod)
        except ImportError:
            continue
        loaded.append(mod)
    return loaded
