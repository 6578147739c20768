"""The core's block registry (``rust/src/schema/registry.rs``) as the Python side reads it:
every family of blocks, its kinds (schema key, Python class, ``kind`` tag) and which field of
which block holds which family. Kind names are listed once, in Rust; the blocks' tags, the
scenario's union checks and the TOML reader's tables follow from here.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from admit_rs import _core


@dataclass(frozen=True)
class Kind:
    """One kind of block."""

    key: str
    """Its key in ``_core.schema()`` and ``_core.defaults()``."""
    cls: str
    """The Python class's name."""
    tag: str | None
    """The ``kind`` a Python block's dict and a TOML table carry (None: untagged)."""
    core_tag: str | None
    """The ``kind`` the core's enum decodes it by (None: the family is no enum)."""
    family: str
    """The family's name (what ``_core.check_block`` validates it as)."""


def _read(registry: list[dict[str, Any]]) -> dict[str, tuple[Kind, ...]]:
    return {
        f["name"]: tuple(
            Kind(k["key"], k["class"], k["tag"], k["core_tag"], f["name"]) for k in f["kinds"]
        )
        for f in registry
    }


_REGISTRY: list[dict[str, Any]] = _core.registry()
FAMILIES: dict[str, tuple[Kind, ...]] = _read(_REGISTRY)
"""Family name -> its kinds, in the registry's order."""
BY_CLASS: dict[str, Kind] = {k.cls: k for kinds in FAMILIES.values() for k in kinds}
"""Python class name -> its kind."""
_FAMILY_OF_TYPE: dict[str, str] = {f["type_name"]: f["name"] for f in _REGISTRY}


def _field_family(prop: Mapping[str, Any]) -> tuple[str, bool] | None:
    """(family, may be None) of a property that holds a block, else None."""
    alternatives = prop.get("anyOf") or prop.get("oneOf") or [prop]
    family, nullable = None, False
    for alt in alternatives:
        ref = alt.get("$ref")
        if isinstance(ref, str):
            family = _FAMILY_OF_TYPE.get(ref.rsplit("/", 1)[-1], family)
        elif alt.get("type") == "null":
            nullable = True
    return None if family is None else (family, nullable)


def _slots(schema: Mapping[str, Any]) -> dict[str, tuple[str, bool]]:
    out: dict[str, tuple[str, bool]] = {}
    for block in schema.values():
        for name, prop in block.get("properties", {}).items():
            found = _field_family(prop)
            if found is not None:
                out[name] = found
    return out


SLOTS: dict[str, tuple[str, bool]] = _slots(_core.schema())
"""Field name -> (the family it holds, whether it may be None), for every field of every
block that holds a block (the same name holds the same family wherever it appears)."""
