"""Package namespaces whose public names are imported on first use (PEP 562).

A package `__init__` re-exports its public API (`from fmm_ros.core.signal import
CaptureConfig`), but importing one light submodule (the settings `fmm --help` shows) must not
import the package's numerics with it. So the `__init__` maps each public name to its
submodule, and the submodule is imported when the name is first looked up.
"""

import importlib
import sys
from collections.abc import Callable, Mapping
from typing import Any


def lazy_exports(package: str, exports: Mapping[str, str]) -> Callable[[str], Any]:
    """The module `__getattr__` of package: name -> `package.<exports[name]>.name`, cached."""

    def __getattr__(name: str) -> Any:
        if name not in exports:
            raise AttributeError(f'module {package!r} has no attribute {name!r}')
        value = getattr(importlib.import_module(f'{package}.{exports[name]}'), name)
        setattr(sys.modules[package], name, value)
        return value

    return __getattr__


class LazyModule:
    """A module imported on its first attribute lookup.

    For libraries a module needs only in some of its functions: scipy.signal (it imports
    scipy.stats, scipy.optimize and scipy.interpolate) was 0.9 s of every node's 1.9 s of
    imports, for filters most nodes never run.
    """

    def __init__(self, name: str) -> None:
        self._name = name

    def __getattr__(self, attribute: str) -> Any:
        return getattr(importlib.import_module(self._name), attribute)
