"""The path tracer's backend names (plain Python, no JAX): the command-line parsers offer them as choices
without loading the renderer."""

from __future__ import annotations

#: Who runs the path tracer: JAX (default: any device, jittable casters) or Mitsuba 3's LLVM backend (CPU).
BACKENDS = ("jax", "mitsuba")
#: What a config may name: a backend, or ``"auto"`` (:func:`._render.resolve_backend`).
BACKEND_CHOICES = ("auto", *BACKENDS)
