"""Orchestration, the last room of planning: a task's moves planned (each candidate method's joint
map, timed and checked, the fastest kept), fly-by corners and chains, the stops, collision checks,
the validators and ``singplan check``'s detection. It alone sees every other room."""
