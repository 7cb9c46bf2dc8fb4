"""Shared checks of a plain number from a user (a seed, a count, a positive number), so that
every layer words them alike: each refuses with a `UserError` naming the parameter (the CLI
maps it onto its flag), before any work. Older checks written inline elsewhere say the same."""

from __future__ import annotations

import math

import numpy as np

from macrostate_mj.core.errors import UserError


def _whole(value: object) -> bool:
    return isinstance(value, int | np.integer) and not isinstance(value, bool)


def _real(value: object) -> bool:
    return (isinstance(value, int | float | np.integer | np.floating)
            and not isinstance(value, bool) and math.isfinite(value))


def check_seed(value: object, name: str = "seed", also: str = "") -> None:
    """A seed for numpy's generators: a whole number >= 0 (`also`: what else was allowed)."""
    if not (_whole(value) and value >= 0):
        raise UserError(f"{name} must be {also}a whole number >= 0 (a seed), got {value!r}"[:160],
                        name)


def check_count(value: object, name: str, least: int = 1) -> None:
    """A count: a whole number >= `least`."""
    if not (_whole(value) and value >= least):
        raise UserError(f"{name} must be a whole number of at least {least}, got {value!r}"[:160],
                        name)


def check_positive(value: object, name: str, zero: bool = False) -> None:
    """A finite number above 0 (or >= 0 with `zero`)."""
    if not (_real(value) and (value >= 0 if zero else value > 0)):
        raise UserError(f"{name} must be a finite number {'>= 0' if zero else 'above 0'}, "
                        f"got {value!r}"[:160], name)
