"""A scene file's dropped-triangle warning once per file in a process: the runner loads a scene for its
early checks (``check_scenes``) and again for the run (``load_experiment_scene``), issue 31 item 6."""

from __future__ import annotations

import logging

from probeplace.experiment import check_scenes, load_experiment_scene, to_config

TET = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n"


def _records(caplog, what: str) -> list[str]:
    return [r.getMessage() for r in caplog.records if r.levelno >= logging.WARNING and what in r.getMessage()]


def test_duplicate_triangles_are_reported_once_per_file(tmp_path, caplog):
    path = tmp_path / "dup.obj"
    path.write_text(TET + "f 1 3 2\n")  # the first triangle again, same winding
    cfg = to_config(
        {
            "name": "dup",
            "scene": {"name": str(path)},
            "placer": {"method": "grid", "budget": 8},
            "bake": {"enabled": False},
            "eval": {"enabled": False},
        }
    )
    with caplog.at_level(logging.DEBUG, logger="probeplace.scene._build"):
        check_scenes([cfg])  # the runner's early check ...
        scene = load_experiment_scene(cfg.scene, with_translation=True)[0]  # ... and the run's own load
        load_experiment_scene(cfg.scene)  # the report's top views load it once more
    assert scene.n_triangles == 4
    assert _records(caplog, "duplicate triangles") == [f"{path}: dropped 1 duplicate triangles of 5"]
    later = [r for r in caplog.records if r.levelno == logging.DEBUG and "duplicate" in r.getMessage()]
    assert len(later) == 2  # the later loads still say it, at debug level
    caplog.clear()
    path.write_text(TET + "f 1 3 2\nf 2 1 3\n")  # an edited file is a new file: warned again
    with caplog.at_level(logging.WARNING, logger="probeplace.scene._build"):
        load_experiment_scene(cfg.scene)
    assert _records(caplog, "duplicate triangles") == [f"{path}: dropped 2 duplicate triangles of 6"]
