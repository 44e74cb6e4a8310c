"""Memory sizes as people write them (``"64MiB"``, ``"1.5 GB"``, ``"1tb"``): the budget options and
``$PROBEPLACE_MAX_BYTES`` read them alike. Plain Python (no JAX)."""

from __future__ import annotations

import re

from .._errors import ConfigError

# Decimal (SI) and binary (IEC) units. Read case-insensitively except where case is the only thing that
# tells bits from bytes (``Mb``, ``Gib``: see :func:`parse_bytes`).
_UNITS = {
    "": 1, "b": 1,
    **{p + "b": 1000 ** (i + 1) for i, p in enumerate("kmgtp")},
    **{p + "ib": 1024 ** (i + 1) for i, p in enumerate("kmgtp")},
}  # fmt: skip
_NUMBER = r"[0-9]*\.?[0-9]+(?:[eE][+-]?[0-9]+)?"


def parse_bytes(value: int | str) -> int:
    """A memory size: an int (bytes) or a string such as ``"64MiB"``, ``"1.5 GB"``, ``"1tb"``, ``"4096"``.

    Units: B, KB MB GB TB PB (powers of 1000) and KiB MiB GiB TiB PiB (powers of 1024), any case, except
    a lower-case ``b`` after an upper-case prefix (``64Mb``, ``1GiB`` written ``1Gib``): that is how bits
    are written, so it is refused rather than guessed; so is a bare prefix (``1G``: 10⁹ or 2³⁰?).
    """
    if isinstance(value, bool):
        raise ConfigError(f"memory budget must be a size in bytes such as '64MiB', got {value!r}")
    if isinstance(value, int):
        n = value
    else:
        m = re.fullmatch(rf"\s*({_NUMBER})\s*([a-zA-Z]*)\s*", str(value))
        unit = m.group(2) if m else ""
        if m is None or unit.lower() not in _UNITS:
            u = unit.upper()
            bare = m is not None and unit.lower() in set("kmgtp")
            hint = f" ({unit!r} alone is ambiguous: write {u}B or {u}iB)" if bare else ""
            raise ConfigError(
                f"memory budget must be a size in bytes such as '64MiB' or '1.5GB', got {value!r}{hint}"
            )
        if unit.endswith("b") and unit[:1].isupper():
            raise ConfigError(f"memory budget {value!r} reads as bits ({unit}); write {unit[:-1]}B for bytes")
        n = int(float(m.group(1)) * _UNITS[unit.lower()])
    if n <= 0:
        raise ConfigError(f"memory budget must be positive, got {value!r}")
    return n
