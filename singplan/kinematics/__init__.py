"""Everything that needs only a robot and joint values: models, families, IK, configurations, dynamics."""
