"""Write docs/errors.md from the bad-input catalogue: run every entry and record its exact message.

Run: ``.venv/bin/python -m tests.reliability.make_errors_doc`` (about a minute: a few bakes compile).
``test_bad_input.test_errors_doc_is_current`` checks that every catalogue entry is in the document.
"""

from __future__ import annotations

import logging
import re
import tempfile
from pathlib import Path

import jax

from probeplace._core import MAX_BYTES_ENV
from probeplace.scene._build import MAX_COORDINATE, MIN_EXTENT

from .catalogue import CATALOGUE, Ctx, Entry

jax.config.update("jax_enable_x64", True)  # as in the test suite (messages do not depend on it)

DOC = Path(__file__).resolve().parents[2] / "docs" / "errors.md"
STAGES = {
    "scene file": "Scene files",
    "scene data": "Scene contents",
    "memory": "Sizes that would not fit in memory",
    "probes": "Probe sets",
    "config": "Configuration values",
    "cli": "Command line and experiment runner",
}

HEAD = f"""# Errors and limits

What probeplace refuses, what it repairs, and the exact message for each. Every error is a subclass of
`probeplace._core.ProbeplaceError` (`SceneError`, `ConfigError`, `ResourceError`; all also `ValueError`
or `MemoryError`), raised by probeplace's own checks at the entry of a public function, before any JAX
work: a message names the input and the problem, never a deep JAX traceback. Repairs and detections
succeed and log a
`WARNING` on the `probeplace` logger.

This file is generated from the catalogue the tests run (`tests/reliability/catalogue.py`) by
`.venv/bin/python -m tests.reliability.make_errors_doc`; `<dir>` stands for the file's folder. The
memory limit in the messages is this machine's (see *Limits*).

## Limits

| What | Limit | Where |
|---|---|---|
| vertex coordinates | \\|x\\| ≤ {MAX_COORDINATE:g} (squared distances finite in float32) | `build_scene` |
| scene extent | ≥ {MIN_EXTENT:g} (squared distances stay normal in float32) | `scene.build_scene` |
| one derived allocation (bake batch + maps) | half the RAM, or `${MAX_BYTES_ENV}` bytes | `check_memory` |
| SDF build | 2 GiB working set (`geometry._sdf_build.MAX_BUILD_BYTES`) | `geometry.build_sdf` |
| derived radiance-map resolution | 16 … 128 (clipped, so never too large) | `probes.default_radiance_res` |
| brute-force ray caster | `BruteForceCaster.MAX_TRIANGLES` triangles | `geometry.BruteForceCaster` |

Duplicate probes and probes outside the scene bounds are accepted (with a warning) by `bake_probes`
and `make_tracer`; `save_probe_set`/`load_probe_set` accept them silently (a probe-set file has no
scene). Face winding is taken as given for shading (an inside-out model is not repaired), but not for
probe validity: the default `inside_test="reach"` flags a probe `inside` when it cannot reach the free
space of the scene's views, which never reads winding, so an inside-out model keeps its probes. The
winding-based `inside_test="backface"` (kept as an option) flags them, logged at bake time.

Unknown keys: YAML configs (the demo's here, the experiment schema's in `tests/experiment`) are refused
with a `ConfigError` naming the key; the Python config classes (`RenderConfig`, `BakeConfig`, …) are
keyword-only dataclasses, so an unknown keyword is Python's own `TypeError` naming it.
"""

TAIL = """
## Also refused (tested in the stage test suites)

`tests/scene/test_bad_input.py`: a missing `.glb`, an unsupported extension, random bytes under each
mesh extension, a truncated GLB (header and body), files without triangles (OBJ, GLB, PLY point cloud),
NaN/inf vertices (OBJ and GLB), degenerate triangles (dropped and counted: *dropped N degenerate
(zero-area) triangles of M*; all degenerate: an error), bad MTL numbers (file and line), negative
emission, a glTF 1.0 document, an unknown scene name (the search path is listed).
`tests/scene/test_sidecar_errors.py`: a scene's `<name>.probeplace.yaml` sidecar, and the same keys given
as `--sun` / `--sky` / `--camera` flags or the runner's `scene.overrides` — every bad value, unit, axis,
material, part or emitter is one line naming the file (or the flag / override layer) and the key path
(`room.probeplace.yaml: emitters.lampp: no material of that name; materials: ...`), invalid YAML names its
line, and a camera looking along its up vector is refused. `tests/probes/test_bake.py`:
bad `BakeConfig` values and NaN probe positions. `tests/placement`, `tests/export`, `tests/experiment`:
their own options, files and formats. `tests/test_cli_checks.py`, `tests/test_runner_cli.py`: every
`place` / `evaluate` / `export` option and every runner key is checked before any placement, bake or
render (a missing view, a size or sample count below 1, an image or bake too large for memory, an
output that cannot be written, an empty probe set, a text file named `.npz`), each refused in one line
`probeplace: error: ...`, exit status 2. Hydra's own errors in `experiments/run.py` — a misspelt key
(`placer.budgett=3`), a wrong type (`seed=abc`), a missing option (`scene=nosuch`) — are composed
before any run starts and printed the same way, in one line naming the key (`scene=<a file>` adds that
a file scene is given as `scene.name=<file>`); an I/O error while
writing is one line, exit 2; Ctrl-C is `probeplace: interrupted`, exit 130.
`tests/experiment/test_run_identity.py`: a finished run whose inputs changed — the scene file, its MTL or
glTF buffers (SHA-256), the resolved sidecar (sun, sky, emitters, cameras, overrides) or the code's
`RESULTS_VERSION` — is not skipped but refused before any run starts, naming the keys: *`<run folder>` is a
finished run with different inputs (scene.config.sun.elevation_deg (35.0 → 20.0)); redo it with
redo=stale (run(..., force=True)), use another name=..., or delete the folder*; a finished run that
recorded no inputs (older than `inputs.json`) is refused the same way rather than trusted.
`tests/evaluate/test_evaluate.py`: an evaluation is written all or nothing (a write that fails part-way
leaves no folder), after an up-front check of the free space its images need.
"""


def _message(entry: Entry, ctx: Ctx, tmp: Path) -> str:
    if entry.error is None:
        records: list[logging.LogRecord] = []
        handler = logging.Handler(logging.WARNING)
        handler.emit = records.append  # type: ignore[method-assign]
        logger = logging.getLogger("probeplace")
        logger.addHandler(handler)
        try:
            entry.run(ctx)
        finally:
            logger.removeHandler(handler)
        msgs = [r.getMessage() for r in records if re.search(entry.match, r.getMessage())]
        text = msgs[0] if msgs else "(no warning logged)"
    else:
        try:
            entry.run(ctx)
            text = "(no error raised)"
        except entry.error as e:
            text = str(e)
    return text.replace(str(tmp), "<dir>").replace("|", "\\|").replace("\n", " ")


def render() -> str:
    lines = [HEAD]
    pending = []
    for stage, title in STAGES.items():
        lines += [f"\n## {title}\n", "| id | input | outcome | message |", "|---|---|---|---|"]
        for e in (e for e in CATALOGUE if e.stage == stage):
            if e.xfail:
                pending.append(e)
                continue
            if e.wrong_type:
                outcome = f"`{e.error.__name__}`"
            else:
                outcome = "logged warning" if e.error is None else f"`{e.error.__name__}`"
            with tempfile.TemporaryDirectory() as d:
                msg = _message(e, Ctx(Path(d)), Path(d))
            lines.append(f"| `{e.id}` | {e.what} | {outcome} | {msg} |")
    if pending:
        lines += ["\n## Not refused yet\n", "| id | input | status |", "|---|---|---|"]
        lines += [f"| `{e.id}` | {e.what} | {e.xfail} |" for e in pending]
    lines.append(TAIL)
    return "\n".join(lines)


if __name__ == "__main__":
    DOC.write_text(render())
    print(f"wrote {DOC}")
