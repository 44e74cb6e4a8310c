"""Slow, obviously correct NumPy references used as test oracles."""
