"""``probeplace view`` as a command: bad input is one line and status 2 before anything slow (no scene, no
JAX, no server); a running viewer prints its address and stops on Ctrl-C with status 0."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import pytest

from . import _fixture as fx


def _view(*argv: str, **kw) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "probeplace", "view", *argv], capture_output=True, text=True, timeout=60, **kw
    )


@pytest.mark.parametrize(
    ("make", "extra", "says"),
    [
        (lambda d: d / "nowhere", (), r"nowhere: no such file or folder; give a run folder"),
        (lambda d: d, (), r"not a finished run \(no probes.json\); give a run folder"),
        (lambda d: _write(d / "p.json", "{oops"), (), r"p.json: not valid JSON .*damaged"),
        (lambda d: fx.write_probes_json(d / "p.json"), (), r"records no scene; give it with --scene"),
        (
            lambda d: fx.write_probes_json(d / "p.json"),
            ("--scene", "no_such_scene"),
            r"--scene: scene 'no_such_scene' is neither built-in nor on the scene search path",
        ),
        (lambda d: d / "x", ("--port", "70000"), r"--port must be in 0..65535"),
    ],
    ids=["missing-path", "not-a-run", "corrupt-probes", "no-scene", "unknown-scene", "bad-port"],
)
def test_bad_input_is_one_line_and_status_2(tmp_path, make, extra, says):
    import re

    t0 = time.monotonic()
    res = _view(str(make(tmp_path)), *extra)
    lines = res.stderr.strip().splitlines()
    assert res.returncode == 2, res.stderr
    assert len(lines) == 1 and lines[0].startswith("probeplace: error: "), res.stderr
    assert re.search(says, lines[0]), lines[0]
    # refused before the scene is loaded (JAX's import alone takes seconds); 20 s leaves room for a
    # loaded 2-core machine
    assert time.monotonic() - t0 < 20


def _write(path, text):
    path.write_text(text)
    return path


def test_serves_until_ctrl_c_then_exits_0(tmp_path):
    run = fx.write_run(tmp_path / "run")
    proc = subprocess.Popen(
        [sys.executable, "-m", "probeplace", "view", str(run), "--port", "0"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, "PYTHONUNBUFFERED": "1"},
    )
    try:
        first = proc.stdout.readline()  # the scene loads first: JAX's import, the Cornell box
        assert first.startswith("probeplace view: http://localhost:"), first + proc.stderr.read()
        port = first.split("http://localhost:")[1].split()[0]
        assert f"ssh -L {port}:localhost:{port}" in proc.stdout.readline()
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=30)
    finally:
        proc.kill()
    assert proc.returncode == 0, err
    assert "Traceback" not in err, err
    assert out.strip().endswith("probeplace view: stopped"), out
