"""Inverse kinematics: closed forms (opw, ur), all-branch numeric IK (numeric), the dispatcher (solve)."""
