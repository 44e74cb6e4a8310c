"""Every light-field tracer setting (``probes.TraceConfig``) reaches the runner and ``probeplace evaluate``
(issue 35: 13 of its 15 settings reached neither): the runner's ``lightfield`` group is built from the
fields (``engine`` is ``eval.trace_engine``), the evaluate command has ``--trace-<name>`` for each, and
a value given at either door is the one the evaluation's ``TraceConfig`` holds."""

from __future__ import annotations

import dataclasses

from probeplace.cli import build_parser
from probeplace.cli._evaluate import eval_config as cli_eval_config
from probeplace.experiment import ExperimentConfig, eval_config, to_config
from probeplace.probes import TraceConfig

FIELDS = [f.name for f in dataclasses.fields(TraceConfig)]


def test_every_field_is_a_runner_key_with_the_library_default():
    group = ExperimentConfig().lightfield
    assert [f.name for f in dataclasses.fields(group)] == [n for n in FIELDS if n != "engine"]
    for name in FIELDS:
        if name != "engine":
            assert getattr(group, name) == getattr(TraceConfig(), name), name
    assert eval_config(ExperimentConfig()).trace.engine == ExperimentConfig().eval.trace_engine


def test_a_runner_value_and_a_flag_reach_the_evaluation_s_trace_config():
    cfg = to_config({"lightfield": {"subdivide": 1, "edge_tol": None, "max_steps": 300}})
    trace = eval_config(cfg).trace
    assert (trace.subdivide, trace.edge_tol, trace.max_steps) == (1, None, 300)
    argv = ["evaluate", "--scene", "cornell_box", "--probes", "p.json", "--trace-subdivide", "1"]
    args = build_parser(lazy=False).parse_args([*argv, "--trace-edge-tol", "none", "--hierarchy", "flat"])
    trace = cli_eval_config(args).trace
    assert (trace.subdivide, trace.edge_tol, trace.hierarchy) == (1, None, "flat")
    untouched = {n: getattr(trace, n) for n in FIELDS if n not in ("subdivide", "edge_tol", "hierarchy")}
    assert untouched == {n: getattr(eval_config(ExperimentConfig()).trace, n) for n in untouched}
