"""One way to name the things a user picks by name (dm_control's `suite` style): experiments,
their results records and sources, bench suites, the Tail's tasks and collection policies, SRS
picks, one-class methods, ReTLo model kinds.

Each entry registers itself where it is defined, with the registry's decorator. A registry
whose entries live in other modules finds them by one rule: it names the packages to scan
(`packages`), and on first read imports every module of theirs whose name does not start with
`_` (`scan`; with `deep`, of their subpackages too), so adding an entry is adding a module.
Where a package also holds modules that are not entries (heavy or optional ones), the registry
names its modules instead (`modules`).
A name not registered is bad input: one line naming the choices (a `UserError`).
"""

from __future__ import annotations

import contextlib
import importlib
import pkgutil
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import Generic, TypeVar

from macrostate_mj.core.errors import UserError

T = TypeVar("T")


def scan(package: str, deep: bool = False) -> list[str]:
    """The full names of `package`'s modules not starting with `_`, sorted, none of them
    imported (only the package itself): the one discovery rule, which a listing that must not
    import the modules (the CLI's experiment names) reads too. `deep`: the modules of its
    subpackages too (an experiment's `tables.py` beside its `__init__.py`)."""
    return _modules(package, importlib.import_module(package).__path__, deep)


def _modules(prefix: str, path: Sequence[str], deep: bool) -> list[str]:
    found = []
    for info in pkgutil.iter_modules(path):
        if info.name.startswith("_"):
            continue
        found.append(f"{prefix}.{info.name}")
        if deep and info.ispkg:
            found += _modules(f"{prefix}.{info.name}", [str(Path(p) / info.name) for p in path],
                              deep)
    return sorted(found)


class Registry(Generic[T]):
    """Entries by name: by `rank` where entries give one (a registry whose order is shown and
    whose modules may be imported in any order), else in the order they registered."""

    def __init__(self, kind: str, modules: Sequence[str] = (),
                 packages: Sequence[str] = (), deep: bool = False) -> None:
        self.kind = kind
        self._deep = deep
        self._modules = tuple(modules)
        self._packages = tuple(packages)
        self._entries: dict[str, T] = {}
        self._ranks: dict[str, float] = {}
        self._loaded = not (self._modules or self._packages)

    def register(self, name: str, rank: float = 0) -> Callable[[T], T]:
        """A decorator that registers what it decorates under `name` and returns it as it is;
        entries read in `rank` order, equal ranks in the order they registered."""

        def add(entry: T) -> T:
            if name in self._entries and self._entries[name] is not entry:
                raise ValueError(f"two {self.kind}s named {name!r}")
            self._entries[name] = entry
            self._ranks[name] = rank
            return entry

        return add

    def module_names(self) -> tuple[str, ...]:
        """Every module this registry imports on first read, none of them imported here."""
        return (*self._modules, *(m for p in self._packages for m in scan(p, self._deep)))

    @contextlib.contextmanager
    def scanning(self, package: str) -> Iterator[None]:
        """This registry with `package` scanned too, inside the block only (its entries are
        forgotten after it): how a test adds a toy entry in a temporary package and leaves
        nothing to the tests after it."""
        kept = dict(self._load())
        self._packages += (package,)
        self._loaded = False
        try:
            yield
        finally:
            self._packages = self._packages[:-1]
            self._entries, self._loaded = kept, True
            self._ranks = {name: self._ranks[name] for name in kept}

    def _load(self) -> dict[str, T]:
        if not self._loaded:
            self._loaded = True         # before importing: a module may read its own registry
            try:
                for module in self.module_names():
                    importlib.import_module(module)
            except BaseException:
                self._loaded = False    # a failed import is not a registry with fewer entries
                raise
        return self._entries

    def _ordered(self) -> list[str]:
        entries = self._load()
        return sorted(entries, key=self._ranks.__getitem__)    # stable: ties as registered

    def __getitem__(self, name: str) -> T:
        entries = self._load()
        if name not in entries:
            raise UserError(f"unknown {self.kind} {name!r}; choose from "
                            f"{', '.join(self._ordered())}")
        return entries[name]

    def __contains__(self, name: object) -> bool:
        return name in self._load()

    def __iter__(self) -> Iterator[str]:
        return iter(self._ordered())

    def __len__(self) -> int:
        return len(self._load())

    def names(self) -> tuple[str, ...]:
        return tuple(self._ordered())

    def items(self) -> list[tuple[str, T]]:
        entries = self._load()
        return [(name, entries[name]) for name in self._ordered()]
