"""Task -> joint path -> timed joint path: path, tracking, zones, crossing methods, timing, the planner."""
