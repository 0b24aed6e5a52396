"""franka: the robot cell on a real Franka Research 3, driven through franky-control."""
