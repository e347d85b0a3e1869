"""Crossing, a room of planning: what a method sees and returns, the built-in methods and the
registry of their names. Imports the path room only; never the timing (pyproject.toml's contracts)."""
