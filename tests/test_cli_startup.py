"""Commands that need no JAX start without it (issue 32 item 3): ``--version``, ``--help``, ``scenes`` (the
listing), ``export`` (the NumPy-only stage, ``export --help`` too) and ``cache info`` in a fresh interpreter
end with no JAX in ``sys.modules``.

An invariant, not a timing: importing JAX is most of a cold start (1.5-4 s against ~0.3 s). The parser
adds each subcommand's options on first use (``cli._Subcommand``), so only the command run loads its stage.
"""

from __future__ import annotations

import subprocess
import sys

import pytest

from tests.export._fixture import ACTIVE, POSITIONS

BLOCKED = ("jax", "jaxlib", "equinox", "optimistix", "jaxopt")


def _jax_modules_after(argv: list[str]) -> tuple[int, list[str], str]:
    """Run ``probeplace.cli.main(argv)`` in a fresh interpreter: (status, JAX modules loaded, output)."""
    code = f"""
import sys
import probeplace.cli as cli
try:
    rc = cli.main({argv!r})
except SystemExit as e:
    rc = e.code
print("LEAKED=" + ",".join(sorted(m for m in sys.modules if m.split(".")[0] in {BLOCKED!r})))
sys.exit(rc)
"""
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    leaked = res.stdout.rsplit("LEAKED=", 1)[-1].strip()
    return res.returncode, [m for m in leaked.split(",") if m], res.stdout + res.stderr


@pytest.fixture
def probe_json(tmp_path):
    """A ProbeSet file as ``place`` writes it, made here with NumPy only (the export test's set)."""
    import json

    path = tmp_path / "set.json"
    from probeplace.export import ExportProbes, export_probes

    export_probes(ExportProbes(positions=POSITIONS, active=ACTIVE, units_m=0.5), "json", path)
    assert json.loads(path.read_text())
    return path


@pytest.mark.parametrize(
    "argv",
    [
        ["--version"],
        ["--help"],
        ["scenes"],
        ["cache", "info"],
        ["export", "--help"],
        ["-q", "cache", "info"],
        ["view", "--help"],
    ],
    ids=["version", "help", "scenes", "cache-info", "export-help", "quiet-cache-info", "view-help"],
)
def test_commands_that_need_no_jax_import_none(argv):
    rc, leaked, out = _jax_modules_after(argv)
    assert rc == 0, out
    assert not leaked, (argv, leaked)


@pytest.mark.parametrize("fmt", ["gltf", "json"])
def test_export_imports_no_jax(fmt, tmp_path, probe_json):
    out = tmp_path / f"out.{'glb' if fmt == 'gltf' else 'json'}"
    rc, leaked, text = _jax_modules_after(["export", str(probe_json), "--format", fmt, "--out", str(out)])
    assert rc == 0, text
    assert out.is_file() and out.stat().st_size > 0
    assert not leaked, leaked


def test_subcommand_options_load_on_first_use():
    """The lazy parser parses and helps as the eager one did: every subcommand has its options once filled."""
    from probeplace.cli import build_parser

    lazy = build_parser()._subparsers._group_actions[0]
    full = build_parser(lazy=False)._subparsers._group_actions[0]
    assert list(lazy.choices) == list(full.choices)
    for name, parser in full.choices.items():
        assert parser._fill is None, name
        assert {"-v", "--quiet"} <= {s for a in parser._actions for s in a.option_strings}, name
        assert lazy.choices[name].format_help() == parser.format_help(), name
    assert [a.help for a in lazy._choices_actions] == [a.help for a in full._choices_actions]
