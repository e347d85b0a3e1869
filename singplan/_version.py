"""singplan's version, in a module of its own so that any layer may name it without importing the
public names of :mod:`singplan` (whose type-only imports reach the entry module)."""

__version__ = "0.1.0"
