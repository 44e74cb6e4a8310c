"""``--sun``, ``--sky`` and ``--camera`` on ``probeplace place`` / ``evaluate``: checked before any work,
and what they give reaches the loaded scene (the sidecar's one-off overrides)."""

from __future__ import annotations

import numpy as np
import pytest

from probeplace.cli import build_parser, main
from probeplace.cli._scene_options import scene_overrides_from_args
from probeplace.scene import load_scene


@pytest.mark.parametrize(
    ("flag", "value", "words"),
    [
        ("--sun", "az=120", "elevation"),
        ("--sky", "0.1,0.2", "--sky"),
        ("--camera", "name=a,pos=0,0,0,look_at=0,0,0", "look_at"),
    ],
)
def test_a_bad_light_or_camera_flag_fails_at_once(flag, value, words, tmp_path, capsys):
    """Exit 2 with one line naming the problem, before the probe file is even read: it does not exist,
    and that would be a different error."""
    rc = main(["evaluate", "--scene", "cornell_box", "--probes", str(tmp_path / "none.json"), flag, value])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and words in err[0]


def test_flags_override_the_scene():
    args = build_parser().parse_args(
        [
            "place",
            "cornell_box",
            "--sun",
            "az=90,el=45,irradiance=2",
            "--sky",
            "0.1,0.2,0.3",
            "--camera",
            "name=door,pos=0.5,0.5,2,look_at=0.5,0.5,0,fov=50",
            "--camera",
            "name=top,pos=0.5,2,0.5,look_at=0.5,0,0.5,up=0,0,1",
        ]
    )
    scene = load_scene(args.scene, overrides=scene_overrides_from_args(args))
    names = [v.name for v in scene.views]
    assert {"door", "top"} <= set(names)
    assert scene.sun is not None
    # elevation 45°: the direction toward the sun rises at 45° above the horizontal plane (y up)
    d = np.asarray(scene.sun.direction, np.float64)
    assert d[1] / np.linalg.norm(d) == pytest.approx(np.sin(np.radians(45)), abs=1e-5)
    np.testing.assert_allclose(np.asarray(scene.sky_radiance), [0.1, 0.2, 0.3], rtol=1e-6)
