"""experiments/tail_causes.py's split of the glossy error by cause: against hand-built pixels whose error has
one known cause each, and the invariant that the shares add up to 1."""

from __future__ import annotations

import numpy as np
import pytest

from ._util import benchmark_module, experiment_script

MISS, HIT, UNRESOLVED, NO_RAY = 0, 1, 2, -1


def _module():
    return experiment_script("tail_causes")


def _pixels(rows):
    """Two samples a pixel from ``rows``: (status, agree, L_probe, L_ref, L_diffuse) per pixel's first sample,
    its second a ray without error (an agreeing hit read exactly)."""
    w, lp, lr, ld, st, ag = [], [], [], [], [], []
    for status, agree, p, r, d in rows:
        for s in ((status, agree, p, r, d), (HIT, True, 0.3, 0.3, 0.3)):
            w.append(np.ones(3))
            lp.append(np.full(3, s[2]))
            lr.append(np.full(3, s[3]))
            ld.append(np.full(3, s[4]))
            st.append(s[0])
            ag.append(s[1])
    return [np.array(a) for a in (w, lp, lr, ld)] + [np.array(st), np.array(ag)]


def test_each_pixel_is_charged_to_its_one_cause():
    """Six pixels, one cause each, errors 6 … 1 (largest first): each pixel's squared error goes to its
    cause alone; the tail (the worst pixel, 1/6 of the pixels) is the unresolved one."""
    rows = [
        (UNRESOLVED, False, 0.0, 6.0, 6.0),
        (HIT, False, 5.0, 0.0, 0.0),  # a wrong hit
        (HIT, True, 1.0, 5.0, 1.0),  # the probe is right about the diffuse lobe: all view dependence
        (HIT, True, 3.0, 0.0, 0.0),  # read too bright
        (HIT, True, 0.0, 2.0, 2.0),  # read too dark
        (MISS, False, 0.0, 1.0, 1.0),
    ]
    w, lp, lr, ld, st, ag = _pixels(rows)
    out = _module().tail_causes(w, lp, lr, ld, st, ag, spp=2, top_percent=100 / 6)
    sq = np.array([6.0, 5.0, 4.0, 3.0, 2.0, 1.0]) ** 2 / 4  # (error / S)², S = 2
    assert out["mse"] == pytest.approx(sq.mean())
    assert out["tail_pixels"] == 1 and out["tail_share"] == pytest.approx(sq[0] / sq.sum())
    assert out["tail"] == pytest.approx({c: float(c == "unresolved") for c in _module().CAUSES})
    names = ["unresolved", "wrong hit", "view dependence", "read too bright", "read too dark", "miss"]
    assert out["all"] == pytest.approx(dict(zip(names, sq / sq.sum())))


def test_shares_add_up_to_one_on_random_rays():
    """Random statuses, radiances and weights (parts of one pixel's error may cancel, so a share may be
    negative): the shares of the tail and of all pixels each add up to 1. A weighted sample without a
    traced ray would go to no cause: refused."""
    rng = np.random.default_rng(7)
    n, spp = 400, 4
    st = rng.choice([NO_RAY, MISS, HIT, UNRESOLVED], n)
    w = rng.uniform(0, 1, (n, 3)) * (st != NO_RAY)[:, None]  # a sample without a ray has no weight
    lp, lr, ld = (rng.exponential(1.0, (n, 3)) for _ in range(3))
    ag = rng.uniform(size=n) < 0.8  # on a hit only: the others' flag is ignored
    out = _module().tail_causes(w, lp, lr, ld, st, ag, spp=spp, top_percent=5.0)
    for part in ("tail", "all"):
        assert sum(out[part].values()) == pytest.approx(1.0, abs=1e-12)
    assert out["tail_pixels"] == 5
    w[np.flatnonzero(st == NO_RAY)[0]] = 1.0
    with pytest.raises(ValueError, match="without a traced ray"):
        _module().tail_causes(w, lp, lr, ld, st, ag, spp=spp)


@pytest.mark.parametrize(
    "argv", [["--grid", "8x4"], ["--grid", "0x4x4"], ["--top", "0"], ["--ref-spp", "-1"]]
)
def test_bad_arguments_exit_2_before_any_work(argv, capsys):
    with pytest.raises(SystemExit) as e:
        _module().main(argv)
    assert e.value.code == 2
    assert "error:" in capsys.readouterr().err


def test_a_scene_that_does_not_load_exits_2_in_one_line(monkeypatch, capsys):
    """The Sponza bench's load failing (here: a scene name on no search path, as a clone without
    ../shared/scenes meets it) is one line naming the fix, exit 2: load_scene's multi-line message is cut
    to its first line."""
    from probeplace.scene import load_scene

    convergence = benchmark_module("convergence")
    monkeypatch.setattr(convergence, "sponza_cell_bench", lambda *a: load_scene("no_such_scene_here"))
    with pytest.raises(SystemExit) as e:
        _module().main(["--grid", "8x4x4"])
    assert e.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert "Crytek Sponza not loaded (unknown scene 'no_such_scene_here'" in err
    assert err.endswith("set PROBEPLACE_SCENE_PATH")
