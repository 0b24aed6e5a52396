"""Offline tools of the mujoco-sim service: benchmarks."""
