"""Names of a package imported on first use (PEP 562), so importing the package stays cheap."""

from __future__ import annotations

import importlib
import sys
from collections.abc import Callable, Mapping
from types import ModuleType
from typing import Any, cast

__all__ = ["lazy_exports"]


class _LazyPackage(ModuleType):
    """A package whose exported names win over its submodules of the same name.

    Importing a submodule binds it as an attribute of its package: without this class,
    ``canonid.learning.evaluate`` would become the module once anything imported
    ``canonid.learning.evaluate``, and the function before that.
    """

    _lazy_exports: Mapping[str, str] = {}

    def __setattr__(self, name: str, value: Any) -> None:
        if isinstance(value, ModuleType) and self._lazy_exports.get(name) == value.__name__:
            value = getattr(value, name)  # the import system binding the defining submodule
        super().__setattr__(name, value)


def lazy_exports(
    package: str, exports: Mapping[str, str]
) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """The module-level ``__getattr__`` and ``__dir__`` of ``package`` that import each name of
    ``exports`` (name → module defining it) the first time it is used, and keep it; ``dir()``
    lists the package's ``__all__``, ``exports``, the subpackages imported so far and the dunder
    names."""
    module = sys.modules[package]
    module.__class__ = _LazyPackage
    cast(_LazyPackage, module)._lazy_exports = dict(exports)

    def __getattr__(name: str) -> Any:
        try:
            home = exports[name]
        except KeyError:
            raise AttributeError(f"module {package!r} has no attribute {name!r}") from None
        value = getattr(importlib.import_module(home), name)
        setattr(module, name, value)
        return value

    def __dir__() -> list[str]:
        # the public names and the loaded subpackages: no helper imported (TYPE_CHECKING)
        public = {*getattr(module, "__all__", ()), *exports}
        for name, value in vars(module).items():
            if name.startswith("__") or (isinstance(value, ModuleType) and name[:1] != "_"):
                public.add(name)
        return sorted(public)

    return __getattr__, __dir__
