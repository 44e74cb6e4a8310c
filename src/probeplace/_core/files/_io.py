"""Files on disk with no half-written state: atomic writes (bytes, text, JSON, a stream, or a writer
that wants a file name) and float EXR images.

Atomic: the new contents go to a fresh hidden file beside the target (same directory, so the same file
system), which ``os.replace`` then renames over the target (atomic on POSIX and Windows). A reader sees
the old file or the whole new one, never a part; when writing raises, the temporary file is removed and
the old file stays as it was. No ``fsync``: a crash of the process cannot leave a torn file, a crash of
the machine may still lose the new one. New files get the usual permissions (0o666 less the umask, as
``open(path, "w")`` gives), not ``tempfile.mkstemp``'s 0o600.

NumPy only, no JAX: the ``export`` stage writes through these.
"""

from __future__ import annotations

import contextlib
import json
import os
from collections.abc import Callable, Iterator, Mapping
from pathlib import Path
from typing import IO, Any

import numpy as np


def _new_temp_file(path: Path, suffix: str) -> Path:
    """Create an empty hidden file with a random name beside ``path`` and return its path."""
    for _ in range(100):
        tmp = path.with_name(f".{path.name}.{os.urandom(6).hex()}{suffix}")
        try:
            # O_EXCL: never reuse a name another writer holds; mode 0o666 is reduced by the umask here
            os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))
        except FileExistsError:
            continue
        return tmp
    raise FileExistsError(f"no free temporary file name beside {path}")


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike, *, suffix: str = ".tmp") -> Iterator[Path]:
    """A temporary file name to write ``path``'s new contents to (module docstring).

    When the ``with`` block ends normally the temporary file is renamed onto ``path``; when it raises,
    the temporary file is removed and ``path`` is untouched. The parent folder is created if missing.

    Args:
        path: the file to (re)write.
        suffix: end of the temporary name, for writers that pick the format from it (``".tmp.exr"``,
            ``".tmp.usda"``).

    Yields:
        The temporary path (an existing empty file).
    """
    path = Path(path)
    with naming_the_file(path):
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = _new_temp_file(path, suffix)
        try:
            yield tmp
            os.replace(tmp, path)
        finally:
            tmp.unlink(missing_ok=True)


@contextlib.contextmanager
def naming_the_file(path: str | os.PathLike) -> Iterator[None]:
    """Re-raise an OSError met while writing ``path`` with ``path`` as its file name when it names none
    or only the hidden temporary file: a full disk fails a ``write()`` call with ENOSPC, which names no
    file (issue 31: ``[Errno 28] No space left on device``, naming nothing). Same errno, same subclass."""
    try:
        yield
    except OSError as e:
        name = "" if e.filename is None else Path(e.filename).name
        if e.errno is None or not (name == "" or name.startswith(f".{Path(path).name}.")):
            raise
        raise OSError(e.errno, e.strerror or os.strerror(e.errno), str(path)) from e


def write_atomic(path: str | os.PathLike, write: Callable[[IO[bytes]], object]) -> Path:
    """Write ``path`` atomically: ``write(f)`` fills a binary file (``np.savez``, say). Returns ``path``."""
    path = Path(path)
    with atomic_path(path) as tmp, open(tmp, "wb") as f:
        write(f)
    return path


def write_bytes_atomic(path: str | os.PathLike, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically. Returns ``path``."""
    return write_atomic(path, lambda f: f.write(data))


def write_text_atomic(path: str | os.PathLike, text: str) -> Path:
    """Write ``text`` (UTF-8) to ``path`` atomically. Returns ``path``."""
    return write_bytes_atomic(path, text.encode("utf-8"))


def write_json_atomic(path: str | os.PathLike, doc: Any) -> Path:
    """Write ``doc`` to ``path`` atomically as probeplace's JSON text: indent 1, keys in the order built,
    a trailing newline. Returns ``path``.

    Raises:
        ValueError: ``doc`` holds NaN or an infinity (not JSON); ``path`` is then left as it was.
        TypeError: ``doc`` holds something JSON cannot encode.
    """
    return write_text_atomic(path, json.dumps(doc, indent=1, allow_nan=False) + "\n")


def write_exr(path: str | os.PathLike, channels: Mapping[str, np.ndarray]) -> Path:
    """Write float32 channels to one ZIP-compressed scanline EXR at ``path``, atomically.

    Args:
        path: the ``.exr`` file.
        channels: OpenEXR channel name → pixels: ``"R"`` with an (h, w) array, or a group such as
            ``"RGB"`` / ``"direct.RGB"`` with an (h, w, 3) array; converted to contiguous float32.

    Returns:
        ``path``.
    """
    import OpenEXR

    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    pixels = {k: np.ascontiguousarray(v, np.float32) for k, v in channels.items()}
    path = Path(path)
    with atomic_path(path, suffix=".tmp.exr") as tmp, OpenEXR.File(header, pixels) as f:
        f.write(str(tmp))
    return path


def read_exr(path: str | os.PathLike, *, separate_channels: bool = True) -> dict[str, np.ndarray]:
    """The channels of an EXR file as float32 arrays.

    Args:
        path: the ``.exr`` file.
        separate_channels: ``True``: one (h, w) array per channel (``"R"``, ``"G"``, ``"B"`` …);
            ``False``: OpenEXR groups them (``"RGB"`` → (h, w, 3), ``"direct.RGB"`` likewise).
    """
    import OpenEXR

    with OpenEXR.File(str(path), separate_channels=separate_channels) as f:
        return {k: np.asarray(v.pixels, np.float32) for k, v in f.channels().items()}
