"""The methods a run config may name: one line per method.

The registry itself, `METHODS`, is the dict in `hola_ray.methods.config` that `RunConfig`
checks a config's `method` and sections against; this module fills it when the package is
imported. It is not a literal here because the method modules name `RunConfig` in their
signatures: `config` importing this module would close a circle (method → config →
registry → method), which the layering test refuses, type-only imports included."""

from __future__ import annotations

from hola_ray.methods import fcp, hola, mep, pbt, sp
from hola_ray.methods.base import Method
from hola_ray.methods.config import METHODS, sections

__all__ = ["METHODS", "register", "sections", "unregister"]


def register(method: Method) -> Method:
    """Make `method` a value a run config may name; its config section (if any) becomes a
    section of every run config. Returns it."""
    if method.name in METHODS and METHODS[method.name] is not method:
        raise ValueError(f"a method named {method.name!r} is already registered")
    if not method.name.isidentifier():
        raise ValueError(f"a method's name is letters, digits and _ only: {method.name!r}")
    METHODS[method.name] = method
    return method


def unregister(name: str) -> None:
    """Forget a method registered for a while (a test's toy method)."""
    METHODS.pop(name, None)


register(hola.HOLA)
register(hola.HOLA_R)
register(hola.UNIFORM)
register(sp.SP)
register(fcp.METHOD)
register(mep.METHOD)
register(pbt.METHOD)
