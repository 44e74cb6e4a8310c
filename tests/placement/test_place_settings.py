"""One schema for the placement's settings (issue 35): ``placement.PlaceRequest``'s fields are ``place``'s
keywords, the runner's ``placer`` keys and ``probeplace place``'s flags. The "adding a placer setting"
example of docs/architecture.md is added to a copy of the package and found at all three doors."""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import probeplace
from probeplace.cli import build_parser
from probeplace.experiment import ExperimentConfig, place_values, to_config
from probeplace.placement import PlaceRequest

DOC = Path(__file__).resolve().parents[2] / "docs" / "architecture.md"
#: Settings a door sets from its own options: the runner's refiner group and run seed, the CLI's
#: --height-band.
RUNNER_OWN, CLI_OWN = {"refiner", "seed"}, {"region"}


def _flags() -> dict[str, object]:
    """dest → default of ``probeplace place``'s options."""
    sub = build_parser(lazy=False)._subparsers._group_actions[0].choices["place"]
    return {a.dest: a.default for a in sub._actions}


def test_every_setting_reaches_the_runner_and_the_command():
    settings = PlaceRequest.settings()
    assert {"budget", "target", "n_opt_samples", "clearance", "region"} <= settings.keys()
    assert not {"config", "caster"} & settings.keys()  # library-only objects
    placer = ExperimentConfig().placer
    flags = _flags()
    for name, (_, default, help_text) in settings.items():
        assert help_text
        if name not in RUNNER_OWN:
            assert getattr(placer, name) == default, name
        if name not in CLI_OWN:
            assert flags[name] == default, name
    assert place_values(ExperimentConfig()) == {k: v[1] for k, v in settings.items()}


def test_a_runner_key_and_a_flag_reach_place_as_given():
    cfg = to_config(
        {"placer": {"n_opt_samples": 700, "clearance": 2}, "refiner": {"name": "gibbs"}, "seed": 3}
    )
    values = place_values(cfg)
    assert values["n_opt_samples"] == 700 and values["clearance"] == 2.0 and values["refiner"] == "gibbs"
    assert PlaceRequest(**values).seed == 3
    args = build_parser(lazy=False).parse_args(
        ["place", "cornell_box", "--n-opt-samples", "700", "--refiner", "none"]
    )
    assert args.n_opt_samples == 700 and args.refiner is None and args.budget == "auto"


def test_a_bad_flag_value_is_refused_naming_the_flag(capsys):
    from probeplace.cli import main

    assert main(["place", "cornell_box", "--n-opt-samples", "0"]) == 2
    assert (
        capsys.readouterr().err.strip()
        == "probeplace: error: --n-opt-samples: must be a positive integer, got 0"
    )


def test_the_documented_setting_is_one_edit(tmp_path):
    """The doc's field, pasted into a copy of ``PlaceRequest``, is a keyword of ``place`` (checked by the
    request), a ``placer`` key of the runner and a flag of ``probeplace place``, with no other edit."""
    (block,) = [
        b
        for b in re.findall(r"```python\n(.*?)```", DOC.read_text(encoding="utf-8"), re.S)
        if "PlaceRequest" in b
    ]
    field_src = "\n".join(line for line in block.splitlines() if not line.startswith("#"))
    name = re.search(r"^\s+(\w+):", field_src, re.M).group(1)
    src = Path(probeplace.__file__).parent
    copy = tmp_path / "probeplace"
    shutil.copytree(src, copy, ignore=shutil.ignore_patterns("__pycache__", "_vendor"))
    registry = copy / "placement" / "_registry.py"
    text = registry.read_text(encoding="utf-8")
    anchor = "\n    @classmethod\n    def settings("
    assert text.count(anchor) == 1
    registry.write_text(text.replace(anchor, "\n" + field_src.rstrip() + "\n" + anchor), encoding="utf-8")
    check = textwrap.dedent(
        f"""
        import probeplace
        assert probeplace.__file__.startswith({str(tmp_path)!r}), probeplace.__file__
        from probeplace.cli import build_parser
        from probeplace.experiment import ExperimentConfig, place_values, to_config
        from probeplace.placement import PlaceRequest
        assert getattr(PlaceRequest(**{{{name!r}: 0.5}}), {name!r}) == 0.5
        assert getattr(ExperimentConfig().placer, {name!r}) == 0.0
        assert place_values(to_config({{"placer": {{{name!r}: 0.25}}}}))[{name!r}] == 0.25
        args = build_parser(lazy=False).parse_args(["place", "x", "--{name.replace("_", "-")}", "0.125"])
        assert getattr(args, {name!r}) == 0.125
        print("ok")
        """
    )
    env = {"PYTHONPATH": str(tmp_path), "PATH": "/usr/bin:/bin", "JAX_PLATFORMS": "cpu"}
    done = subprocess.run([sys.executable, "-c", check], capture_output=True, text=True, env=env, timeout=300)
    assert done.stdout.strip() == "ok", done.stderr[-3000:]
