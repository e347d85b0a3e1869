"""What is made from a trajectory: summary, report page, replay, controller exports (imported lazily)."""
