"""One way to name the things a user picks by name (dm_control's `suite` style): experiments,
bench suites, the Tail's tasks, one-class methods, ReTLo model kinds.

Each entry registers itself where it is defined, with the registry's decorator; a registry that
is read before its modules are imported names them (`modules`), and imports them on first read.
A name not registered is bad input: one line naming the choices (a `UserError`).
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Iterator, Sequence
from typing import Generic, TypeVar

from macrostate_mj.core.errors import UserError

T = TypeVar("T")


class Registry(Generic[T]):
    """Entries by name, in the order they registered."""

    def __init__(self, kind: str, modules: Sequence[str] = ()) -> None:
        self.kind = kind
        self._modules = tuple(modules)
        self._entries: dict[str, T] = {}
        self._loaded = not self._modules

    def register(self, name: str) -> Callable[[T], T]:
        """A decorator that registers what it decorates under `name` and returns it as it is."""

        def add(entry: T) -> T:
            if name in self._entries and self._entries[name] is not entry:
                raise ValueError(f"two {self.kind}s named {name!r}")
            self._entries[name] = entry
            return entry

        return add

    def _load(self) -> dict[str, T]:
        if not self._loaded:
            self._loaded = True         # before importing: a module may read its own registry
            try:
                for module in self._modules:
                    importlib.import_module(module)
            except BaseException:
                self._loaded = False    # a failed import is not a registry with fewer entries
                raise
        return self._entries

    def __getitem__(self, name: str) -> T:
        entries = self._load()
        if name not in entries:
            raise UserError(f"unknown {self.kind} {name!r}; choose from {', '.join(entries)}")
        return entries[name]

    def __contains__(self, name: object) -> bool:
        return name in self._load()

    def __iter__(self) -> Iterator[str]:
        return iter(tuple(self._load()))

    def __len__(self) -> int:
        return len(self._load())

    def names(self) -> tuple[str, ...]:
        return tuple(self._load())

    def items(self) -> list[tuple[str, T]]:
        return list(self._load().items())
