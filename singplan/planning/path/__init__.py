"""Path geometry, the first room of planning: a move's programmed path (LIN / CIRC pieces, weave),
followed by continuous IK (tracking), its singular zones, and the joint map (a path parameter's
joint values) the other rooms build on. Imports no other room (pyproject.toml's contracts)."""
