"""dry-robot: the robot side of the contract on the symbolic world model (no physics)."""
