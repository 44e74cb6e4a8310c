"""Checks the command line and the runner make before any slow work (issue 19, "check everything first"):
can an output be written (and is there room for it: issue 31), is an input file a NumPy archive at all,
would an image fit in memory.

Each raises :class:`~probeplace._core.ConfigError` (``ResourceError`` for memory) with a message naming
the option and the problem, in well under a second. Plain Python and NumPy, no JAX.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path

from .._errors import ConfigError
from ._memory import check_memory

# A .npz is a zip archive: every one starts with a local file header (or, empty, the end record).
_ZIP_MAGIC = (b"PK\x03\x04", b"PK\x05\x06")


def _existing_ancestor(path: Path, target: Path, what: str) -> Path:
    """The nearest existing folder at or above ``path``; refuses a file met on the way (the message
    names ``target``, the output asked for)."""
    for p in (path, *path.parents):
        if p.exists():
            if not p.is_dir():
                raise ConfigError(f"{what}: cannot create {target}: {p} is a file, not a folder")
            return p
    return Path.cwd()  # a relative path with no existing part: it lands in the working folder


def _probe_write(folder: Path, path: Path, what: str) -> None:
    """Create and remove a hidden file in ``folder``: the one test of writability that holds everywhere
    (permissions, read-only mounts, ACLs, quotas)."""
    try:
        fd, tmp = tempfile.mkstemp(prefix=".probeplace-write-test-", dir=folder)
        os.close(fd)
        os.unlink(tmp)
    except OSError as e:
        raise ConfigError(f"{what}: cannot write {path}: {e.strerror or e} ({folder})") from None


#: Free bytes below which nothing is written: a file of any size takes at least one block (4 KiB on the
#: usual file systems), so with less even a small output would fail, after the work it records.
MIN_FREE_BYTES = 4096


def _check_space(folder: Path, path: Path, what: str, size: int) -> None:
    """Refuse when the file system of ``folder`` has fewer free bytes than ``size`` (or one block)."""
    try:
        free = shutil.disk_usage(folder).free
    except OSError:  # no figure (some network mounts): the write itself will say, naming the file
        return
    need = max(int(size), MIN_FREE_BYTES)
    if free < need:
        raise ConfigError(
            f"{what}: cannot write {path}: it needs at least {need} bytes, {free} bytes are free on the "
            f"file system of {folder}; free some space or write elsewhere"
        )


def check_writable_file(path: str | os.PathLike, what: str, size: int = 0) -> Path:
    """Refuse, up front, an output file that could not be written: it is a folder, a file stands where a
    parent folder must go, its folder (or the nearest existing folder above it) is not writable, or its
    file system has less free space than ``size`` bytes (at least one block).

    Args:
        path: the file the command will write (its folder may not exist yet).
        what: the option naming it in the message, e.g. ``"--out"``.
        size: a lower bound on the bytes the file will take, where the command can tell (else 0).

    Returns:
        ``path`` as a Path. Nothing is left on disk.
    """
    path = Path(path)
    if path.is_dir():
        raise ConfigError(f"{what}: {path} is a folder, not a file")
    folder = _existing_ancestor(path.parent, path, what)
    _probe_write(folder, path, what)
    _check_space(folder, path, what, size)
    return path


def check_writable_folder(path: str | os.PathLike, what: str, size: int = 0) -> Path:
    """Refuse, up front, an output folder that could not be created or written into, or whose file
    system has less than ``size`` bytes free (see :func:`check_writable_file`). Returns ``path`` as a
    Path; nothing is left on disk."""
    path = Path(path)
    folder = _existing_ancestor(path, path, what)
    _probe_write(folder, path, what)
    _check_space(folder, path, what, size)
    return path


def check_npz_archive(path: str | os.PathLike, what: str) -> Path:
    """Refuse a file named ``.npz`` that is not a NumPy archive (a zip file) with a message saying so,
    instead of NumPy's about pickled data. A missing file is left to the reader's own message."""
    path = Path(path)
    if not path.is_file():
        return path
    try:
        with open(path, "rb") as f:
            head = f.read(4)
    except OSError as e:
        raise ConfigError(f"{what}: cannot read {path}: {e.strerror or e}") from None
    if head not in _ZIP_MAGIC:
        kind = "an empty file" if not head else f"it starts with {head!r}"
        raise ConfigError(
            f"{what}: {path} is not a probeplace .npz: not a NumPy archive (a .npz is a zip file; {kind})"
        )
    return path


def check_image_memory(
    width: int, height: int, spp: int, *, components: int, paths_per_batch: int, what: str
) -> None:
    """Refuse, up front, an image whose path-traced reference would not fit in memory: the renderer's own
    estimate (``render._render._check_renderable``: float64 mean and variance of each component per
    pixel, plus one batch of ~200-byte paths), made before a scene is loaded or a probe baked."""
    n = int(width) * int(height)
    need = n * components * 3 * 8 * 2 + min(int(paths_per_batch), n * int(spp)) * 200
    check_memory(need, f"{what} of {width}×{height} pixels × {spp} spp", "use a smaller image")
