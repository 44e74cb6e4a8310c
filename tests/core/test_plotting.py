"""``load_pyplot``: pyplot with the file-only Agg backend (charts are written to files, STYLE §8)."""

from __future__ import annotations

import matplotlib

from probeplace._core import load_pyplot


def test_pyplot_uses_agg_and_writes_a_png(tmp_path):
    plt = load_pyplot()
    assert matplotlib.get_backend().lower() == "agg"
    fig, ax = plt.subplots(figsize=(1, 1))
    ax.plot([0, 1], [0, 1])
    fig.savefig(tmp_path / "line.png")
    plt.close(fig)
    assert (tmp_path / "line.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
