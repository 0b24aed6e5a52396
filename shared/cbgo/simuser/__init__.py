"""Simulated users: scenarios of gesture episodes performed with the kinematic hand.

Shared (not inside the leap-bridge) because training and benchmarks of the gesture services
generate their data with the same simulated people the leap-bridge streams.
"""
