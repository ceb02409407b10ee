"""A scene's fingerprint: the same physics and inputs give the same short hash.

The fingerprint hashes the checked :class:`~hecker_dynamics.scene.load.Scene` (every spec,
with defaults filled in, floats by their exact value), not the file's text: a scene loaded
from a shipped name, from a parameters file in another directory or from the node's own
parameters has one fingerprint, and so does a file that only writes a default out. Only
``source`` (where the file was found) and ``threads`` (which gives the same bits any way)
are left out.
"""
from __future__ import annotations

import dataclasses
import enum
import hashlib
import json
from collections.abc import Mapping
from typing import Any

import numpy as np

from .load import Scene

__all__ = ["scene_fingerprint"]

#: Hex digits kept: 64 bits, far beyond the scenes any project compares.
FINGERPRINT_DIGITS = 16
#: Scene fields added after sessions were recorded, with their defaults: left out while at
#: them, so a scene that does not use them keeps the fingerprint its recordings hold.
_ADDED_LATER = {"map": None, "publish_contacts": False, "converged": None,
                "soft_joints": None, "pin_gap": None}


def _plain(value: Any) -> Any:
    """``value`` as JSON-ready data with floats written exactly (``float.hex``)."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {"type": type(value).__name__,
                **{f.name: _plain(getattr(value, f.name)) for f in dataclasses.fields(value)}}
    if isinstance(value, enum.Enum):
        return _plain(value.value)
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return float(value).hex()
    if isinstance(value, str) or value is None:
        return value
    if isinstance(value, bytes):  # a map's cells
        return hashlib.sha256(value).hexdigest()
    if isinstance(value, np.ndarray):
        return [_plain(x) for x in value.tolist()]
    if isinstance(value, Mapping):
        return {str(k): _plain(v) for k, v in sorted(value.items(), key=lambda kv: str(kv[0]))}
    if isinstance(value, (tuple, list)):
        return [_plain(x) for x in value]
    if hasattr(value, "__dict__"):
        return {"type": type(value).__name__,
                **{k: _plain(v) for k, v in sorted(vars(value).items())}}
    raise TypeError(f"cannot fingerprint a {type(value).__name__}")


def scene_fingerprint(scene: Scene) -> str:
    """The scene's fingerprint: hex digits of a SHA-256 over its checked specs."""
    described = _plain(dataclasses.replace(scene, source=""))
    del described["threads"]
    for name, default in _ADDED_LATER.items():
        if getattr(scene, name) == default:
            del described[name]
    text = json.dumps(described, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()[:FINGERPRINT_DIGITS]
