"""Mean march steps of hi-Z, two-level and flat on the same rays (``benchmarks/tracer.py``'s
``hierarchy_steps``: shading rays from the first view, geometry-only bakes), without the rest of the
tracer benchmark. Prints one JSON object per scene and writes ``results/hierarchy_steps.json``.

    PROBEPLACE_SCENE_PATH=/work/shared/scenes .venv/bin/python experiments/hierarchy_steps.py \\
        --scenes cornell_box:4x4x4 crytek_sponza:8x4x4 --res 128 256 --rays 2000
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenes", nargs="+", default=["cornell_box:4x4x4", "crytek_sponza:8x4x4"])
    ap.add_argument("--res", nargs="+", type=int, default=[128, 256])
    ap.add_argument("--rays", type=int, default=2000)
    args = ap.parse_args(argv)
    sys.path.insert(0, str(ROOT / "benchmarks"))
    from probeplace.scene import load_scene
    from tracer import hierarchy_steps

    out = {}
    for spec in args.scenes:
        name, dims = spec.split(":")
        steps = hierarchy_steps(load_scene(name), tuple(int(x) for x in dims.split("x")), args.res, args.rays)
        out[spec] = steps
        print(json.dumps({spec: steps}), flush=True)
    path = ROOT / "results" / "hierarchy_steps.json"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
