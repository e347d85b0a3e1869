"""The closed forms of the arm families that have one (OPW, Universal Robots): compiled kernels on
parameter records and poses, with no robot object. Family recognition verifies them against the
chain's own FK (:mod:`singplan.kinematics.families`); :mod:`singplan.kinematics.ik` solves a
robot's poses with them."""
