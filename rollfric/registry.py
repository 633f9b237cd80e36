"""Registries: the names the CLI offers, each bound to the object that implements it.

A :class:`Registry` maps a name (``"subpixel"``, ``"lsq"``, ...) to ``"module:attribute"``
(or ``"module"`` for a module), like an entry point: the names are known without importing
anything (the CLI builds its ``choices`` from them and stays light), the implementation is
imported on first use (:meth:`Registry.load`). An unknown name is bad input
(:class:`rollfric.errors.InputError`, naming the known ones).

rollfric's registries are here (the simulation engines' is ``ENGINES`` in the suite's engines
module). To add a locator or a fit method: write it (a :class:`rollfric.locate.Locator` or a
:class:`rollfric.fit.estimate.FitMethod`) and add one line below; the CLI offers it and
``tests/test_architecture.py`` checks that it loads and has the interface.
"""

from __future__ import annotations

import dataclasses
import importlib
import types
from collections.abc import Iterator, Mapping

from rollfric.errors import InputError


@dataclasses.dataclass(frozen=True)
class Registry(Mapping):
    """Names of one kind (``kind``: "locator", "fit method", ...) -> ``"module:attribute"``.

    A read-only mapping in declaration order (the first name is the default).
    """

    kind: str
    targets: Mapping[str, str]

    def __post_init__(self) -> None:
        object.__setattr__(self, "targets", types.MappingProxyType(dict(self.targets)))

    def __getitem__(self, name: str) -> str:
        return self.targets[name]

    def __contains__(self, name: object) -> bool:
        # a TOML value of another type (a list, a table) is simply not a registered name
        return isinstance(name, str) and name in self.targets

    def __iter__(self) -> Iterator[str]:
        return iter(self.targets)

    def __len__(self) -> int:
        return len(self.targets)

    def names(self) -> tuple[str, ...]:
        """The registered names, in declaration order."""
        return tuple(self.targets)

    def check(self, name: str) -> str:
        """A registered name, checked.

        Parameters
        ----------
        name : str

        Returns
        -------
        str
            ``name``.

        Raises
        ------
        InputError
            An unregistered name (the message lists the known ones).
        """
        if name not in self.targets:
            raise InputError(f"unknown {self.kind} {name!r} (known: {', '.join(self.targets)})")
        return name

    def load(self, name: str):
        """The object registered as ``name``, its module imported on first use.

        Parameters
        ----------
        name : str

        Returns
        -------
        object
            The registered function, class or module.

        Raises
        ------
        InputError
            An unregistered name.
        """
        module, _, attr = self.targets[self.check(name)].partition(":")
        obj = importlib.import_module(module)
        return getattr(obj, attr) if attr else obj


#: Ball locators (:class:`rollfric.locate.Locator`), the default first.
LOCATORS = Registry("locator", {
    "subpixel": "rollfric.locate.subpixel:subpixel_locator",
    "thesis-large": "rollfric.locate.thesis:thesis_large_locator",
    "thesis-small": "rollfric.locate.thesis:thesis_small_locator",
})

#: Fit methods (:class:`rollfric.fit.estimate.FitMethod`), the default first.
FIT_METHODS = Registry("fit method", {
    "lsq": "rollfric.fit.lsq:fit_lsq",
    "paper1_eps": "rollfric.fit.thesis:paper1_eps_method",
    "paper2_grid": "rollfric.fit.thesis:paper2_grid_method",
})
