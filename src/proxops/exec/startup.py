"""Start-up cost of a process (CLI, pool worker) that the work does not need.

numba's first compile-or-cache-load imports ``scipy.linalg`` (its BLAS check), and
``scipy.linalg`` imports scipy's array-API shim, which reads every public attribute of numpy --
importing ``numpy.f2py`` (a Fortran wrapper generator whose import compiles hundreds of regular
expressions) and ``numpy.testing``: about 90 ms of a 1 s ``proxops run`` (measured with
``python -X importtime``), for modules no run uses.
"""

from __future__ import annotations

import importlib.util
import os
import sys

_UNUSED_NUMPY_SUBMODULES = ("numpy.f2py", "numpy.testing")


def skip_pydantic_plugin_scan() -> None:
    """``PYDANTIC_DISABLE_PLUGINS=__all__`` unless the user set it: pydantic's first model class
    otherwise reads the entry points of every installed distribution for pydantic plugins
    (``pydantic.plugin._loader.get_plugins``: 10-13 % of pydantic's own import, measured under load)
    for plugins proxops never uses. The console script only (library users keep their plugins);
    the campaign's worker processes inherit it. ``PYDANTIC_DISABLE_PLUGINS=`` (empty) keeps them."""
    os.environ.setdefault("PYDANTIC_DISABLE_PLUGINS", "__all__")


def defer_unused_numpy_submodules() -> None:
    """Register ``numpy.f2py`` and ``numpy.testing`` as lazily executed modules
    (:class:`importlib.util.LazyLoader`): reading the attribute gives the module object, its code
    runs on the first access to anything in it, so every real use works unchanged. No effect on a
    submodule already imported."""
    import numpy

    for name in _UNUSED_NUMPY_SUBMODULES:
        if name in sys.modules:
            continue
        spec = importlib.util.find_spec(name)
        if spec is None or spec.loader is None:
            continue
        loader = importlib.util.LazyLoader(spec.loader)
        spec.loader = loader
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        loader.exec_module(module)
        setattr(numpy, name.rsplit(".", 1)[1], module)  # numpy's __getattr__ would import it eagerly


def defer_when_numpy_is_imported() -> None:
    """:func:`defer_unused_numpy_submodules` now if numpy is imported, else right after numpy's own
    import (a one-shot import hook): ``proxops --help`` and the other commands that do not compute
    never import numpy, those that do get the deferral before numba's first kernel load."""
    if "numpy" in sys.modules:
        defer_unused_numpy_submodules()
    elif not any(isinstance(f, _AfterNumpy) for f in sys.meta_path):
        sys.meta_path.insert(0, _AfterNumpy())


class _AfterNumpy:
    """Meta path finder that only wraps numpy's loader (then removes itself)."""

    def find_spec(self, name, path=None, target=None):
        if name != "numpy":
            return None
        sys.meta_path.remove(self)
        spec = importlib.util.find_spec(name)
        if spec is not None and spec.loader is not None and hasattr(spec.loader, "exec_module"):
            run = spec.loader.exec_module

            def exec_module(module, run=run):
                run(module)
                defer_unused_numpy_submodules()

            spec.loader.exec_module = exec_module
        return spec
