"""The files of a run folder, named once: the runner (``experiment._run``) writes them, the report and the
viewer read them, the stage tour (``probeplace demo``) writes the probe files under the same names. Plain
Python (the NumPy-only ``export`` stage and the viewer's light start may read it)."""

from __future__ import annotations


class RunFiles:
    """Names inside a run folder (``results_dir/<experiment>/<run>/``)."""

    #: The run's config, as run (``config_to_yaml``).
    config = "config.yaml"
    #: Versions and machine (``_results.environment``).
    env = "env.json"
    #: What the run read: scene file hashes, the resolved sidecar, the code version (``_inputs``).
    inputs = "inputs.json"
    #: The placed probe set (``save_probe_set``); its coverage detail beside it (``coverage_detail_path``).
    probes = "probes.json"
    #: The baked light-field probes (``probes.save_probes``).
    baked = "probes_baked.npz"
    #: The placement's top view.
    top_view = "top_view.png"
    #: The run's record; the evaluation writes its own under the same name in :attr:`eval_dir`.
    metrics = "metrics.json"
    #: The evaluation's folder (``evaluate.write_evaluation``) and its image layers.
    eval_dir = "eval"
    images = "images.exr"
    #: The engine exports.
    export_dir = "export"
