"""Redraw every chart of an experiment from its saved files and write report.md.

    python experiments/report.py results/cornell_comparison      # -> results/cornell_comparison/report/

Only finished runs (folders with a DONE marker) are read; see probeplace.experiment._report. Several
runs of a method at one probe count (seeds, scene offsets) are drawn at their geometric mean with a
95 % t-interval as error bars on log-scale count and memory axes; the tables compare methods at exactly
equal probe counts and at equal bytes of probe data (a method placing the same probes as another is
marked "(= other)"); top_views/<run>.png shows each probe set from the top and the side. report.html
is the same report in one self-contained page, with a 3D view of each method's placement and its
evaluation images side by side (probeplace.experiment._report_html).
"""

from __future__ import annotations

import argparse
import sys

from probeplace._core import ProbeplaceError
from probeplace.experiment import make_report


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("results", help="an experiment folder: results/<experiment>")
    args = p.parse_args(argv)
    try:
        path = make_report(args.results)
    except ProbeplaceError as e:
        print(f"report: error: {e}", file=sys.stderr)
        return 2
    print(path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
