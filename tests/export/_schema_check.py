"""A small JSON Schema checker for the keywords our schema uses (jsonschema is not a dependency).

Supports type, const, required, properties, additionalProperties: false, items, minItems, maxItems,
minimum, exclusiveMinimum. Raises AssertionError naming the path of the first violation. If the
``jsonschema`` package is installed, it is used as well.
"""

from __future__ import annotations

_TYPES = {
    "object": dict,
    "array": list,
    "string": str,
    "boolean": bool,
    "integer": int,
    "number": (int, float),
}


def _check(x, s: dict, path: str) -> None:
    if "const" in s:
        assert x == s["const"], f"{path}: {x!r} != const {s['const']!r}"
    if "type" in s:
        t = s["type"]
        ok = isinstance(x, _TYPES[t]) and not (t in ("integer", "number") and isinstance(x, bool))
        assert ok, f"{path}: expected {t}, got {type(x).__name__}"
    if isinstance(x, dict):
        for k in s.get("required", []):
            assert k in x, f"{path}: missing required {k!r}"
        props = s.get("properties", {})
        if s.get("additionalProperties") is False:
            extra = set(x) - set(props)
            assert not extra, f"{path}: unexpected properties {sorted(extra)}"
        for k, v in x.items():
            if k in props:
                _check(v, props[k], f"{path}.{k}")
    if isinstance(x, list):
        assert len(x) >= s.get("minItems", 0), f"{path}: fewer than {s['minItems']} items"
        assert len(x) <= s.get("maxItems", len(x)), f"{path}: more than {s['maxItems']} items"
        if "items" in s:
            for i, v in enumerate(x):
                _check(v, s["items"], f"{path}[{i}]")
    if isinstance(x, int | float) and not isinstance(x, bool):
        if "minimum" in s:
            assert x >= s["minimum"], f"{path}: {x} < minimum {s['minimum']}"
        if "exclusiveMinimum" in s:
            assert x > s["exclusiveMinimum"], f"{path}: {x} <= exclusiveMinimum"


def check_schema(doc, schema: dict) -> None:
    _check(doc, schema, "$")
    try:
        import jsonschema
    except ImportError:
        return
    try:
        jsonschema.validate(doc, schema)
    except jsonschema.ValidationError as e:
        raise AssertionError(str(e)) from None
