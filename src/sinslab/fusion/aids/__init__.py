"""Aid plug-ins of a recorded run: the sensors and assumptions that aid the INS beside the
GNSS (:mod:`.base` holds the contract, one module per aid family).

:data:`AIDS` is the registry: one line per aid, ``"module:Class"``, in the order the aids'
states and measurements enter a run (whatever order a user lists them in). A new aid is
its module and its line here; ``sinslab navigate`` then has its config section, its
``--aid`` token and its report (docs/architecture.md, "A new sensor is one file").
"""
from __future__ import annotations

import importlib

from sinslab.fusion.aids.base import Aid

__all__ = ["AIDS", "aid_types", "aid_type", "resolve_tokens"]

#: the registry: the aids a run can be given, in the order they enter it
AIDS = (
    "sinslab.fusion.aids.rest:Zupt",
    "sinslab.fusion.aids.lever:AntennaLever",
    "sinslab.fusion.aids.vehicle:Nhc",
    "sinslab.fusion.aids.odometer:WheelOdometer",
    "sinslab.fusion.aids.magnetometer:Magnetometer",
    "sinslab.fusion.aids.barometer:BarometricAltimeter",
)

_TYPES: dict = {}


def aid_types() -> dict:
    """``{name: Aid subclass}`` of the registry, in its order (imported once)."""
    if not _TYPES:
        for entry in AIDS:
            mod, _, cls = entry.partition(":")
            t = getattr(importlib.import_module(mod), cls)
            if not (isinstance(t, type) and issubclass(t, Aid) and t.name):
                raise TypeError(f"aid registry entry {entry!r} is not a named Aid subclass")
            if t.name in _TYPES:
                raise TypeError(f"two aids named {t.name!r} in the registry")
            _TYPES[t.name] = t
    return dict(_TYPES)


def aid_type(name):
    """The aid class registered as ``name``."""
    types = aid_types()
    if name not in types:
        raise ValueError(f"unknown aid {name!r}; the aids are {', '.join(types)}")
    return types[name]


def resolve_tokens(tokens) -> dict:
    """``--aid`` tokens (names or aliases, any order, repeats allowed) -> ``{name: settings
    the alias sets}`` in registry order. Raises ValueError naming an unknown token."""
    types = aid_types()
    alias = {a: (n, kv) for n, t in types.items() for a, kv in t.aliases.items()}
    got = {}
    bad = []
    for tok in tokens:
        if tok in types:
            got.setdefault(tok, {})
        elif tok in alias:
            n, kv = alias[tok]
            got.setdefault(n, {}).update(kv)
        else:
            bad.append(tok)
    if bad:
        raise ValueError(f"unknown {', '.join(bad)}; use a comma list of {', '.join([*types, *alias])}")
    return {n: got[n] for n in types if n in got}
