"""Calling a function chosen by name from a registry with keyword parameters from a scene file."""

from __future__ import annotations

import inspect
from collections.abc import Callable
from typing import Any

from prefilter import PrefilterError


def check_parameters(
    registry: dict[str, Callable[..., Any]], what: str, name: str, params: dict
) -> Callable[..., Any]:
    """registry[name], after checking that it takes every key of params; an unknown name or parameter raises
    PrefilterError listing the valid ones."""
    function = registry.get(name)
    if function is None:
        raise PrefilterError(f"unknown {what} '{name}' (valid: {', '.join(registry)})")
    valid = list(inspect.signature(function).parameters)
    unknown = [key for key in params if key not in valid]
    if unknown:
        listed = ", ".join(valid) if valid else "none"
        raise PrefilterError(f"{what} '{name}' has no parameter '{unknown[0]}' (valid: {listed})")
    return function


def call_registered(registry: dict[str, Callable[..., Any]], what: str, name: str, params: dict) -> Any:
    """registry[name](**params), its name and parameters checked as check_parameters does."""
    return check_parameters(registry, what, name, params)(**params)


def call_from_table(table, registry: dict[str, Callable[..., Any]], what: str) -> Any:
    """A scene's [generator] table (a scene.Reader): `name` picks the function, the other keys are its
    parameters; errors are reported at the table's key path."""
    name = table.string("name", required=True)
    params = {k: v for k, v in table.table.items() if k != "name"}
    table.used.update(params)
    try:
        return call_registered(registry, what, name, params)
    except PrefilterError as exc:
        raise table.fail(None, str(exc)) from None
    except TypeError as exc:  # a parameter of the wrong type
        raise table.fail(None, f"bad {what} parameter ({exc})") from None
