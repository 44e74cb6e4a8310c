"""Issue 19, "conventions": ``--version``, ``-v``/``-q`` before or after the subcommand, help texts that
show defaults and say what ``demo`` runs, the ``scenes`` listing of a shadowed name, progress bars that
stay out of logs."""

from __future__ import annotations

import argparse
import ast
from pathlib import Path

import pytest

from probeplace._core.runtime import _progress
from probeplace.cli import build_parser, main

SRC = Path(__file__).resolve().parents[1] / "src" / "probeplace"


@pytest.fixture(autouse=True)
def _restore_progress():
    import logging

    level = logging.getLogger("probeplace").level
    yield
    _progress.set_progress(True)
    logging.getLogger("probeplace").setLevel(level)


def test_version(capsys):
    from probeplace import __version__

    with pytest.raises(SystemExit) as e:
        main(["--version"])
    assert e.value.code == 0 and capsys.readouterr().out.strip() == f"probeplace {__version__}"


@pytest.mark.parametrize("where", ["before", "after"])
@pytest.mark.parametrize("flag", ["-v", "--verbose", "-q", "--quiet"])
def test_verbosity_flags_on_every_subcommand(flag, where, capsys, monkeypatch):
    """Every subcommand takes -v/-q after its name as well as before; -q also turns progress bars off."""
    monkeypatch.setattr(_progress, "_on_terminal", lambda: True)
    sub = build_parser(lazy=False)._subparsers._group_actions[0].choices  # every option loaded
    assert {"scenes", "place", "evaluate", "export", "demo"} <= set(sub)
    for name, parser in sub.items():
        opts = {s for a in parser._actions for s in a.option_strings}
        assert {"-v", "--verbose", "-q", "--quiet"} <= opts, name
    argv = [flag, "scenes"] if where == "before" else ["scenes", flag]
    assert main(argv) == 0
    assert "cornell_box" in capsys.readouterr().out
    quiet = flag in ("-q", "--quiet")
    bar = _progress.progress_bar(total=1)
    shown = not bar.disable
    bar.close()
    assert shown is not quiet


def test_verbose_and_quiet_exclude_each_other(capsys):
    with pytest.raises(SystemExit) as e:
        main(["-v", "scenes", "-q"])
    assert e.value.code == 2 and "exclude each other" in capsys.readouterr().err


def _options(parser: argparse.ArgumentParser):
    return [a for a in parser._actions if a.option_strings and a.help != argparse.SUPPRESS]


def test_help_shows_every_default_and_says_what_demo_runs():
    parser = build_parser()
    sub = parser._subparsers._group_actions[0]
    for name, p in sub.choices.items():
        text = p.format_help()
        for a in _options(p):
            d = a.default
            if d is None or d is False or d is argparse.SUPPRESS or d == []:  # the help says what then
                continue
            assert a.help, f"{name} {a.option_strings[0]}: no help"
            shown = f"(default: {a.default})" in " ".join(text.split())
            assert shown or "default" in a.help, f"{name} {a.option_strings[0]}: default not shown"
    evaluate = " ".join(sub.choices["evaluate"].format_help().split())
    runner = ("(default: 64, the runner's eval.width)", "(default: 16, the runner's tracer.spp)")
    for default in (*runner, "(default: lightfield, the runner's eval.shading)", "(default: results/eval)"):
        assert default in evaluate
    demo = next(a.help for a in sub._choices_actions if a.dest == "demo")
    assert "stage tour" in demo and "cornell_comparison" in demo and "default experiment" not in demo


def test_scenes_says_which_of_two_same_names_wins(tmp_path, monkeypatch, capsys):
    from tests.reliability.catalogue import tet_obj

    (tmp_path / "cornell_box.obj").write_text(tet_obj())
    (tmp_path / "tetra.obj").write_text(tet_obj())
    monkeypatch.setenv("PROBEPLACE_SCENE_PATH", str(tmp_path))
    assert main(["scenes"]) == 0
    out = capsys.readouterr().out.splitlines()
    lines = [ln for ln in out if ln.startswith("cornell_box ")]
    builtin = [ln for ln in lines if " builtin " in ln]
    files = [ln for ln in lines if " file " in ln]
    assert len(builtin) == 1 and "shadowed" not in builtin[0]
    assert files and all("shadowed" in ln and "built-in" in ln for ln in files)
    tetra = [ln for ln in out if ln.startswith("tetra ")]
    assert len(tetra) == 1 and "shadowed" not in tetra[0]


def test_progress_bars_are_plain_when_stderr_is_not_a_terminal(capsys, monkeypatch):
    """Under pytest stderr is a pipe: no bar, so no carriage returns; on a terminal the bar draws."""

    def draw():
        bar = _progress.progress_bar(total=5, desc="work", mininterval=0)
        for _ in range(5):
            bar.update()
        bar.close()
        return capsys.readouterr().err

    assert "\r" not in draw()
    monkeypatch.setattr(_progress, "_on_terminal", lambda: True)
    assert "\r" in draw()  # the same call on a terminal: the check above can fail
    _progress.set_progress(False)
    assert draw() == ""


def test_progress_bars_are_built_through_the_one_helper():
    """No module but ``_core/runtime/_progress.py`` constructs a tqdm bar itself."""
    bad = []
    for path in SRC.rglob("*.py"):
        if path.name == "_progress.py":
            continue
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if (
                isinstance(node, ast.Call)
                and getattr(node.func, "id", getattr(node.func, "attr", "")) == "tqdm"
            ):
                bad.append(f"{path.relative_to(SRC)}:{node.lineno}")
    assert not bad, bad
