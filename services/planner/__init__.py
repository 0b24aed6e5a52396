"""planner: behaviour trees that turn an intent into robot actions, repairing preconditions."""
