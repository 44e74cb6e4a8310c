"""Exceptions with messages meant for users: they name the input and the problem."""


class ProbeplaceError(Exception):
    """Base class of every error probeplace raises on purpose."""


class SceneError(ProbeplaceError, ValueError):
    """A scene file or scene data is missing, unreadable or unusable."""


class ConfigError(ProbeplaceError, ValueError):
    """A configuration value is invalid; the message names the key."""


class ResourceError(ProbeplaceError, MemoryError):
    """A derived size (grid, image, batch) would not fit in memory; refused before allocating."""
