"""Timing, a room of planning: a joint map timed within the limits at the controller period
(TOPP-RA's profile, compiled; the checker's ratios; the jerk-limited time laws; the duration bound
auto ranks candidates by). Imports the path room only; never a crossing method (pyproject.toml's
contracts)."""
