"""The one compiled part of probeplace, beside pyproject.toml (which holds everything else).

Embree's packet loop (src/probeplace/geometry/_packet_loop.c) is optional: where no C compiler is found
the build goes on without it, and the Embree caster casts one ray at a time through embreex
(docs/raycast.md, "Embree's packets").
"""

from setuptools import Extension, setup

setup(
    ext_modules=[
        Extension(
            "probeplace.geometry._packet_loop",
            sources=["src/probeplace/geometry/_packet_loop.c"],
            optional=True,
        )
    ]
)
