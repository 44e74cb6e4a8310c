"""experiments/spread_parts.py's split of a fixed placement's seed spread into the bake's and the reference's
parts: against a matrix built from known additive effects (the oracle: the population σ of each effect over
the matrix's mean), and its refusals."""

from __future__ import annotations

import numpy as np
import pytest

from ._util import experiment_script


def _module():
    return experiment_script("spread_parts")


def test_each_part_is_its_own_effect():
    """MSE(i, j) = m + a_i + b_j: the row means move by the bake's effects a alone, the column means by the
    reference's b alone, the diagonal by a_i + b_i; each spread is that effect's population σ over its
    mean (a and b each sum to zero, so every mean is m)."""
    m = 2.0
    a = np.array([0.3, -0.1, -0.2, 0.0])
    b = np.array([0.0, 0.05, -0.15, 0.1])
    out = _module().spread_parts(m + a[:, None] + b[None, :])
    assert out["bake"]["cv"] == pytest.approx(a.std() / m)
    assert out["reference"]["cv"] == pytest.approx(b.std() / m)
    assert out["fixed_rays"]["cv"] == pytest.approx((a + b).std() / m)
    lo, hi = out["bake"]["ci95"]
    assert lo < out["bake"]["cv"] < hi


def test_a_reference_without_noise_has_no_spread():
    """Only the bake moves: the reference's part is exactly 0 and the diagonal's is the bake's."""
    a = np.array([0.2, -0.2, 0.1])
    out = _module().spread_parts(1.0 + a[:, None] + np.zeros((1, 3)))
    assert out["reference"]["cv"] == 0.0
    assert out["fixed_rays"]["cv"] == pytest.approx(out["bake"]["cv"])


@pytest.mark.parametrize("shape", [(3, 2), (1, 1), (4,)])
def test_a_matrix_that_is_not_square_is_refused(shape):
    with pytest.raises(ValueError, match="n × n matrix"):
        _module().spread_parts(np.ones(shape))


@pytest.mark.parametrize(
    "argv",
    [
        ["--seeds", "1"],
        ["--grid", "8x4"],
        ["--bake-spp", "0"],
        ["--glossy-ref-spp", "1"],
        ["--glossy-spp", "0"],
    ],
)
def test_bad_arguments_exit_2_before_any_work(argv, capsys):
    with pytest.raises(SystemExit) as e:
        _module().main(argv)
    assert e.value.code == 2
    assert "error:" in capsys.readouterr().err
