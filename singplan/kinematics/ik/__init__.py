"""Inverse kinematics of a robot: all-branch numeric IK (numeric), whole-turn variants (turns), the
dispatcher over the closed forms of :mod:`singplan.kinematics.closedform` and the numeric IK (solve)."""
