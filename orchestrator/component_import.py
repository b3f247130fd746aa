"""Python components named in a system file: ``component = "module:Class"`` is imported from the
system file's folder first (a ``module.py`` or package beside the TOML needs no PYTHONPATH),
then from the Python path (``component = "sine"``, a name without ``:``, is one of the built-in
sources of :mod:`orchestrator.sources`); the class is built with the unit's ``[config]`` table.

A component class may name config keys that hold file paths (``relative_paths``); those are
resolved against the system file's folder, as FMU paths are."""
from __future__ import annotations

import importlib
import inspect
import sys
from pathlib import Path

from orchestrator.component import Component
from orchestrator.errors import SystemError_

# component = "sine" is short for "orchestrator.sources:Sine" (a name without ':' is no module path)
BUILTIN_SOURCES = {"constant": "Constant", "step": "Step", "ramp": "Ramp", "sine": "Sine", "table": "Table"}


def import_component(spec, name: str, config: dict, base_dir: Path | None = None) -> Component:
    """A ready component for unit *name*: *spec* is an instance, a Component subclass or a
    ``"module:Class"`` string."""
    if isinstance(spec, Component):
        return spec
    if isinstance(spec, type) and issubclass(spec, Component):
        return construct(spec, name, config, base_dir)
    if isinstance(spec, str) and spec in BUILTIN_SOURCES:
        from orchestrator import sources

        return construct(getattr(sources, BUILTIN_SOURCES[spec]), name, config, base_dir)
    if not (isinstance(spec, str) and ":" in spec):
        raise SystemError_(f"units.{name}.component = {spec!r}: expected 'module:Class' or a built-in "
                           f"source ({', '.join(BUILTIN_SOURCES)})")
    mod, cls = spec.split(":", 1)
    try:
        module = _import(mod, name, spec, Path(base_dir) if base_dir else None)
        obj = getattr(module, cls)
    except (ImportError, AttributeError) as e:
        where = f" (looked beside the system file in {base_dir}, then on the Python path)" if base_dir else ""
        raise SystemError_(f"units.{name}.component = {spec!r}: cannot import ({e}){where}") from None
    if not (isinstance(obj, type) and issubclass(obj, Component)):
        raise SystemError_(f"units.{name}.component = {spec!r}: not a Component subclass")
    return construct(obj, name, config, base_dir)


def _import(mod: str, unit: str, spec: str, base_dir: Path | None):
    top = mod.split(".")[0]
    local = None
    if base_dir is not None:
        for candidate in (base_dir / f"{top}.py", base_dir / top):
            if candidate.exists():
                local = candidate
                break
    if local is None:
        return importlib.import_module(mod)
    loaded = sys.modules.get(top)
    if loaded is not None:
        where = getattr(loaded, "__file__", None)
        if where is not None and not Path(where).resolve().is_relative_to(local.resolve()):
            # two modules of one name: Python keeps one per process, so say which is in use
            raise SystemError_(f"units.{unit}.component = {spec!r}: a module {top!r} is already "
                               f"imported from {where}, not {local}; rename one of them")
        return importlib.import_module(mod)
    sys.path.insert(0, str(base_dir))
    try:
        return importlib.import_module(mod)
    finally:
        sys.path.remove(str(base_dir))


def construct(cls: type, name: str, config: dict, base_dir: Path | None = None) -> Component:
    config = dict(config)
    for key in getattr(cls, "relative_paths", ()):
        if key in config and isinstance(config[key], str) and base_dir is not None:
            p = Path(config[key])
            config[key] = str(p if p.is_absolute() else Path(base_dir) / p)
    try:
        params = inspect.signature(cls.__init__).parameters
    except (TypeError, ValueError):
        params = {}
    takes_any = any(p.kind is inspect.Parameter.VAR_KEYWORD for p in params.values())
    unknown = [k for k in config if k not in params] if params and not takes_any else []
    if unknown:
        known = [k for k in params if k not in ("self", "name")]
        raise SystemError_(f"units.{name}.config: {cls.__name__} does not take {sorted(unknown)}; "
                           f"expected some of {known}")
    try:
        return cls(name, **config)
    except TypeError as e:
        raise SystemError_(f"units.{name}.config: {cls.__name__} does not accept {sorted(config)} ({e})") from None
