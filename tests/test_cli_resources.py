"""Issue 31 from the command line: a probe count or memory budget that cannot fit in memory, an output on
a read-only folder or a full disk, and a write that fails part-way. Each is one line ``probeplace: error:
...`` naming the option or file, exit status 2, before any slow work (``no_slow_work``), nothing left on
disk."""

from __future__ import annotations

import errno
import os
import shutil
import tempfile
from pathlib import Path

import jax.numpy as jnp
import pytest

from probeplace import ProbeSet
from probeplace.cli import main
from tests.test_cli_checks import POS, probe_json, refused

BILLION = 10**9


@pytest.fixture
def limit(monkeypatch):
    """Set the memory limit ($PROBEPLACE_MAX_BYTES) to a known number of bytes."""

    def set_limit(n: int) -> int:
        monkeypatch.setenv("PROBEPLACE_MAX_BYTES", str(n))
        return n

    return set_limit


def cornell_probe_bytes() -> tuple[int, int]:
    """(radiance_res, bytes per baked probe) for the Cornell box at its default bake settings."""
    from probeplace.probes import BakeConfig, default_radiance_res, probe_bytes
    from probeplace.scene import cornell_box

    scene = cornell_box()
    res = default_radiance_res(scene)
    return res, probe_bytes(scene, BakeConfig(radiance_res=res, geometry_res=res))


def test_budget_whose_maps_cannot_fit_is_refused(tmp_path, capsys, no_slow_work, limit):
    res, per = cornell_probe_bytes()
    cap = limit(4 * BILLION)
    argv = [
        "place",
        "cornell_box",
        "--method",
        "grid",
        "--budget",
        str(BILLION),
        "--out",
        str(tmp_path / "p.json"),
    ]
    line = refused(argv, capsys, f"--budget {BILLION}", f"baking {BILLION} probes ({per} bytes each")
    assert f"at radiance_res={res}, geometry_res={res})" in line
    assert f"needs ~{BILLION * per} bytes" in line and f"over the limit of {cap} bytes" in line
    assert "--memory-budget" in line  # the fix
    assert not any(tmp_path.iterdir())


def test_budget_limit_is_exact(tmp_path, capsys, no_slow_work, limit):
    """A count whose maps need exactly the limit goes on to placement; one byte less is refused."""
    _, per = cornell_probe_bytes()
    argv = ["place", "cornell_box", "--method", "grid", "--budget", "1000", "--out", str(tmp_path / "p.json")]
    limit(1000 * per - 1)
    refused(argv, capsys, "--budget 1000", f"needs ~{1000 * per} bytes")
    limit(1000 * per)
    with pytest.raises(AssertionError, match="slow work"):  # no_slow_work: placement was reached
        main(argv)


@pytest.mark.parametrize("size", ["1TB", "1tb", "1 TiB"])
def test_memory_budget_over_the_limit_gets_the_memory_refusal(tmp_path, capsys, no_slow_work, limit, size):
    cap = limit(BILLION)
    want = 10**12 if "i" not in size else 2**40
    argv = ["place", "cornell_box", "--memory-budget", size, "--out", str(tmp_path / "p.json")]
    line = refused(argv, capsys, f"--memory-budget {size}", f"needs ~{want} bytes", f"limit of {cap} bytes")
    assert "not a size" not in line and "such as" not in line
    limit(2 * want)  # under the limit: a size, turned into a probe count, and placement is reached
    with pytest.raises(AssertionError, match="slow work"):
        main(argv)


def _read_only_folder(tmp_path: Path) -> Path:
    """A folder this process cannot create files in: a chmod-ed one, or for root (who ignores
    permissions) sysfs, which refuses new files to everyone."""
    if os.geteuid() != 0:
        ro = tmp_path / "ro"
        ro.mkdir()
        ro.chmod(0o555)
        return ro
    try:
        fd, name = tempfile.mkstemp(dir="/sys")
    except OSError:
        return Path("/sys")
    os.close(fd)
    os.unlink(name)
    pytest.skip("no read-only folder for root here")


@pytest.mark.parametrize("command", ["place", "export", "evaluate", "demo"])
def test_read_only_output_folder_is_refused(tmp_path, capsys, no_slow_work, command):
    ro = _read_only_folder(tmp_path)
    try:
        line = refused(_argv(command, tmp_path, ro / "sub" / "out"), capsys, "--out", "cannot write", str(ro))
        assert "sub/out" in line
    finally:
        if ro != Path("/sys"):
            ro.chmod(0o755)


def _argv(command: str, tmp_path: Path, out: Path) -> list[str]:
    probes = str(probe_json(tmp_path / "in.json"))
    return {
        "place": ["place", "cornell_box", "--out", f"{out}.json"],
        "export": ["export", probes, "--format", "json", "--out", f"{out}.json"],
        "evaluate": ["evaluate", "--scene", "cornell_box", "--probes", probes, "--out", str(out)],
        "demo": ["demo", "--out", str(out)],
    }[command]


def _free(monkeypatch, n: int) -> None:
    """A file system with ``n`` free bytes, as ``shutil.disk_usage`` reports it."""
    monkeypatch.setattr(shutil, "disk_usage", lambda p: shutil._ntuple_diskusage(10**12, 10**12 - n, n))


@pytest.mark.parametrize("command", ["place", "export", "evaluate", "demo"])
def test_full_disk_is_refused_before_any_work(tmp_path, capsys, no_slow_work, monkeypatch, command):
    _free(monkeypatch, 100)
    before = set(tmp_path.iterdir()) | {tmp_path / "in.json"}
    out = tmp_path / "new" / "out"
    line = refused(_argv(command, tmp_path, out), capsys, "--out", "cannot write", str(out))
    # evaluate knows its output's size (an upper bound from the image size, the runner's by default); the
    # others ask for one block
    from probeplace.cli._evaluate import runner_defaults
    from probeplace.evaluate._write import evaluation_bytes

    d = runner_defaults()
    need = evaluation_bytes(d["width"], d["height"]) if command == "evaluate" else 4096
    assert f"it needs at least {need} bytes, 100 bytes are free" in line
    assert set(tmp_path.iterdir()) <= before


def test_probe_set_larger_than_the_free_space_is_refused(tmp_path, capsys, no_slow_work, monkeypatch):
    """``place --budget N`` knows its probe set's size: at least 32 bytes a probe."""
    out = tmp_path / "p.json"
    argv = ["place", "cornell_box", "--method", "grid", "--budget", "1000", "--out", str(out)]
    _free(monkeypatch, 31_999)
    refused(argv, capsys, f"--out: cannot write {out}", "needs at least 32000 bytes, 31999 bytes are free")
    _free(monkeypatch, 32_000)
    with pytest.raises(AssertionError, match="slow work"):
        main(argv)
    assert not any(tmp_path.iterdir())


class _FullDisk:
    """A binary file whose writes fail as on a full disk: ENOSPC from ``write()``, naming no file."""

    def __init__(self, path, mode="r", *a, **k):
        self._f = open(path, mode, *a, **k)  # closed in __exit__

    def write(self, data):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self._f.close()


def _fake_place(*a, **k):
    """A placement of two probes with no coverage context (so ``place`` writes no coverage detail)."""
    from probeplace.placement import PlaceRequest, PlaceResult

    probes = ProbeSet(pos_world=jnp.asarray(POS, jnp.float32), active=jnp.ones(len(POS), bool))
    return PlaceResult(probes, "grid", PlaceRequest(), 1.0, "fake", {"total_s": 0.0})


def test_disk_full_while_writing_names_the_file_and_leaves_nothing(tmp_path, capsys, monkeypatch):
    import probeplace._core.files._io
    import probeplace.placement

    monkeypatch.setattr(probeplace._core.files._io, "open", _FullDisk, raising=False)
    ok = probe_json(tmp_path / "in.json")
    out = tmp_path / "o.json"
    refused(
        ["export", str(ok), "--format", "json", "--out", str(out)], capsys, f"No space left on device: {out}"
    )
    monkeypatch.setattr(probeplace.placement, "place", _fake_place)
    out = tmp_path / "p.json"
    refused(["place", "cornell_box", "--out", str(out)], capsys, f"No space left on device: {out}")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in.json"]  # no probe set, top view or temp file


def test_disk_full_while_drawing_the_top_view_names_it(tmp_path, capsys, monkeypatch):
    import probeplace.placement

    def full(scene, pos, path, **k):
        Path(path).write_bytes(b"\x89PNG partial")  # a writer that is not atomic leaves a part behind
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(probeplace.placement, "place", _fake_place)
    monkeypatch.setattr(probeplace.placement, "save_top_view", full)
    out = tmp_path / "p.json"
    refused(
        ["place", "cornell_box", "--out", str(out)],
        capsys,
        f"No space left on device: {out.with_suffix('.png')}",
    )
    assert not any(tmp_path.iterdir())


def test_memory_limit_variable_takes_sizes_and_refuses_nonsense(monkeypatch, tmp_path, capsys, no_slow_work):
    """$PROBEPLACE_MAX_BYTES reads sizes like the budget options (8GiB = 8·2³⁰ bytes); a value that is no
    size is one line naming the variable, not a traceback."""
    from probeplace._core import memory_limit_bytes

    monkeypatch.setenv("PROBEPLACE_MAX_BYTES", "8GiB")
    assert memory_limit_bytes() == 8 * 2**30
    monkeypatch.setenv("PROBEPLACE_MAX_BYTES", "12e9")
    assert memory_limit_bytes() == 12 * 10**9
    monkeypatch.setenv("PROBEPLACE_MAX_BYTES", "lots")
    out = tmp_path / "p.json"
    line = refused(["place", "cornell_box", "--budget", "8", "--out", str(out)], capsys)
    assert "$PROBEPLACE_MAX_BYTES='lots'" in line and "8GiB" in line, line
    assert not out.exists()
