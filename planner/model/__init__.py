"""What users give the planner and get back: the scenario, the plan, trajectories."""
