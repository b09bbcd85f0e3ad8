"""Strict JSON of results: what every result's ``to_json`` and every JSON file the CLI writes
go through (a leaf: it imports no other part of the application)."""
from __future__ import annotations

import json

import numpy as np


def finite_json(value):
    """``value`` with every non-finite float replaced by None: what JSON can hold (RFC 8259 has
    no NaN or infinity; a NaN in a report means "not available")."""
    if isinstance(value, dict):
        return {k: finite_json(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [finite_json(v) for v in value]
    if isinstance(value, (float, np.floating)):
        return float(value) if np.isfinite(value) else None
    if isinstance(value, np.integer):
        return int(value)
    if isinstance(value, np.bool_):
        return bool(value)
    return value


def dumps(value, indent=1):
    """Strict JSON text of ``value`` (non-finite numbers as null, never ``NaN``/``Infinity``)."""
    return json.dumps(finite_json(value), indent=indent, allow_nan=False)
