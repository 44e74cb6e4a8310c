"""ProbeSet JSON files: lossless float32 round trip, clear errors for broken files."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
import pytest

from probeplace._core import ProbeplaceError, ProbeSet, load_probe_set, save_probe_set


def test_round_trip_keeps_float32_positions_exactly(tmp_path, getkey):
    import jax

    pos = jax.random.normal(getkey(), (7, 3), jnp.float32)
    ps = ProbeSet(pos_world=pos, active=jnp.arange(7) % 3 != 0, method="test")
    save_probe_set(tmp_path / "p.json", ps, units_m=0.001, metadata={"seed": 3})
    back, meta = load_probe_set(tmp_path / "p.json")
    np.testing.assert_array_equal(np.asarray(back.pos_world), np.asarray(pos))
    np.testing.assert_array_equal(np.asarray(back.active), np.asarray(ps.active))
    assert back.method == "test" and meta["units_m"] == 0.001 and meta["metadata"] == {"seed": 3}


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("{not json", "not valid JSON"),
        ('{"format": "other"}', "not a probe set file"),
        ('{"format": "probeplace.ProbeSet/1", "positions": [[1, 2]]}', "bad positions"),
        ('{"format": "probeplace.ProbeSet/1", "positions": [[1, 2, 3]], "active": [true, false]}', "active"),
    ],
)
def test_broken_files_are_clear_errors(tmp_path, text, match):
    (tmp_path / "p.json").write_text(text)
    with pytest.raises(ProbeplaceError, match=match):
        load_probe_set(tmp_path / "p.json")


def test_nan_positions_are_refused(tmp_path):
    ps = ProbeSet(pos_world=jnp.asarray([[np.nan, 0, 0]], jnp.float32), active=jnp.ones(1, bool))
    with pytest.raises(ProbeplaceError, match="NaN"):
        save_probe_set(tmp_path / "p.json", ps)
    assert not (tmp_path / "p.json").exists()
