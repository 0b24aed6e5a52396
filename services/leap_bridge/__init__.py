"""leap-bridge: hand frames from a Leap Motion sensor, a recording or a simulated user."""
